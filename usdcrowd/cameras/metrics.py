"""Seed 000's evaluation: how much of what happens the cameras see.

- Activity metric (Algorithm 7): each camera scores every character it
  sees, ``1 / distance``, into an active score (characters taking part in an
  event) or an idle score. Summed over a group of cameras, per frame.
- Viewed ratio (section 5.4): active characters seen by at least one camera
  of the group against active characters seen by none.

"Seen" is geometric: the character's chest inside the camera's frustum,
within ``max_distance``, and at least ``min_pixels`` tall in a frame of
``image_width`` pixels (a person a few pixels high is not filmed, only in
the picture). The paper does not say occlusion was counted; here it is when
the scenery is given (``usdcrowd metrics`` does): someone hidden from a
camera by scenery or by others (:mod:`.sightlines`) is not seen by it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..core import model
from .frustum import half_tangents, points_in_frustum
# The chest (where "seen" is tested) and a person's height (the legibility test below), metres.
from .sightlines import CHEST_HEIGHT, PERSON_HEIGHT, Prisms, seen_points


@dataclass
class CoverageSeries:
    """Per-frame scores of a group of cameras.

    Attributes
    ----------
    times : (t,) float64
    score_active, score_idle : (t,) float64
        Algorithm 7's sums of 1 / distance (1/m).
    n_active : (t,) int64
        Active characters in the shot.
    n_active_viewed : (t,) int64
        Of them, seen by at least one camera.
    """

    times: np.ndarray
    score_active: np.ndarray
    score_idle: np.ndarray
    n_active: np.ndarray
    n_active_viewed: np.ndarray

    @property
    def active_share(self) -> np.ndarray:
        """(t,) active score / (active + idle score); NaN where nothing is seen."""
        total = self.score_active + self.score_idle
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(total > 0, self.score_active / total, np.nan)

    @property
    def active_idle_ratio(self) -> np.ndarray:
        """(t,) active score / idle score (the paper's Figures 12 and 13); NaN where the idle score is 0."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.score_idle > 0, self.score_active / self.score_idle, np.nan)

    @property
    def viewed_ratio(self) -> np.ndarray:
        """(t,) active viewed / active not viewed (Figures 14 and 15); NaN where none is active, inf where all are seen."""
        not_viewed = self.n_active - self.n_active_viewed
        with np.errstate(invalid="ignore", divide="ignore"):
            r = self.n_active_viewed / not_viewed.astype(np.float64)
        return np.where(self.n_active > 0, r, np.nan)

    @property
    def viewed_share(self) -> np.ndarray:
        """(t,) active viewed / active; NaN where none is active."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.n_active > 0, self.n_active_viewed / np.maximum(self.n_active, 1), np.nan)

    def summary(self) -> dict:
        """Means over the frames where they are defined."""
        ratio = self.viewed_ratio
        finite = np.isfinite(ratio)
        return {"mean_active_share": _mean(self.active_share),
                "mean_active_idle_ratio": _mean(self.active_idle_ratio),
                "mean_viewed_share": _mean(self.viewed_share),
                "median_viewed_ratio": float(np.median(ratio[~np.isnan(ratio)])) if (~np.isnan(ratio)).any()
                else float("nan"),
                "frames_all_active_viewed": int(np.sum(np.isinf(ratio))),
                "mean_viewed_ratio_finite": float(np.mean(ratio[finite])) if finite.any() else float("nan")}


def active_mask(events: model.EventTable, times: np.ndarray, n_agents: int) -> np.ndarray:
    """(t, n) bool: agents taking part in some event at each frame."""
    times = np.asarray(times, dtype=np.float64)
    out = np.zeros((len(times), n_agents), dtype=bool)
    for e in events:
        for frame, sample in zip(*e.on_frames(times)):
            out[frame, e.members[e.active[sample]]] = True
    return out


def coverage(tracks: list[model.CameraTrack], positions: np.ndarray, active: np.ndarray,
             visible: np.ndarray | None = None, max_distance: float = 100.0, min_pixels: float = 24.0,
             image_width: int = 640, obstacles: model.Obstacles | None = None,
             overhead: model.Obstacles | None = None) -> CoverageSeries:
    """Algorithm 7 and the viewed ratio for a group of cameras.

    Parameters
    ----------
    tracks : list[CameraTrack]
        The group, sampled at the same frames as ``positions``.
    positions : (t, n, 3) float
        Characters' ground positions, metres.
    active : (t, n) bool
        From :func:`active_mask`.
    visible : (n,) bool, optional
        Characters that are rendered (invisible leaders are never seen).
    max_distance : float
        Metres; characters further away count as not seen.
    min_pixels : float
        A character is seen only if at least this many pixels tall in an
        image ``image_width`` wide (0: no limit).
    image_width : int
        Pixels across the horizontal aperture.
    obstacles : Obstacles, optional
        With them, occlusion counts: a person hidden from a camera by
        scenery or by other people (:mod:`.sightlines`) is not seen by it.
    overhead : Obstacles, optional
        Raised scenery (awnings), with ``obstacles``.
    """
    t, n = positions.shape[:2]
    vis = np.ones(n, bool) if visible is None else np.asarray(visible, bool)
    if not tracks:
        zero = np.zeros(t)
        return CoverageSeries(np.arange(t, dtype=np.float64), zero, zero.copy(),
                              active[:, vis].sum(axis=1), np.zeros(t, np.int64))
    mats = np.stack([tr.cam_to_world for tr in tracks], 1)          # (t, c, 4, 4)
    tan_x = np.array([half_tangents(tr.focal_length[0], tr.horizontal_aperture, tr.vertical_aperture)[0]
                      for tr in tracks])
    tan_y = np.array([half_tangents(tr.focal_length[0], tr.horizontal_aperture, tr.vertical_aperture)[1]
                      for tr in tracks])
    near = np.array([tr.near for tr in tracks])
    # Focal length in pixels: a person PERSON_HEIGHT tall at depth z is f_px * h / z pixels tall.
    f_px = image_width * 0.5 / tan_x
    s_act = np.zeros(t)
    s_idle = np.zeros(t)
    n_act = active[:, vis].sum(axis=1)
    n_seen = np.zeros(t, dtype=np.int64)
    rows = np.flatnonzero(vis)
    prisms = Prisms.of(obstacles, overhead=overhead) if obstacles is not None else None
    for k in range(t):
        chest = np.asarray(positions[k, rows], dtype=np.float64) + [0.0, 0.0, CHEST_HEIGHT]
        tree = cKDTree(chest)
        eye = mats[k, :, 3, :3]
        lists = tree.query_ball_point(eye, r=max_distance)
        cam = np.repeat(np.arange(len(tracks)), [len(x) for x in lists])
        if len(cam) == 0:
            continue
        who = np.concatenate([np.asarray(x, dtype=np.int64) for x in lists])
        inside, dist = points_in_frustum(chest[who], eye[cam], -mats[k, cam, 2, :3], mats[k, cam, 0, :3],
                                         mats[k, cam, 1, :3], tan_x[cam], tan_y[cam], near[cam], max_distance)
        depth = np.einsum("ij,ij->i", chest[who] - eye[cam], -mats[k, cam, 2, :3])
        inside &= f_px[cam] * PERSON_HEIGHT >= min_pixels * np.maximum(depth, 1e-9)
        cam, who, dist = cam[inside], who[inside], dist[inside]
        if obstacles is not None and len(cam):
            unhidden = _unhidden(mats[k], tan_x, tan_y, near, cam, who, np.asarray(positions[k], dtype=np.float64),
                                 rows, prisms)
            cam, who, dist = cam[unhidden], who[unhidden], dist[unhidden]
        act = active[k, rows[who]]
        w = 1.0 / np.maximum(dist, 1e-3)
        s_act[k] = w[act].sum()
        s_idle[k] = w[~act].sum()
        n_seen[k] = len(np.unique(who[act]))
    return CoverageSeries(np.asarray(tracks[0].times, dtype=np.float64), s_act, s_idle, n_act, n_seen)


def _unhidden(mats, tan_x, tan_y, near, cam, who, ground, rows, prisms) -> np.ndarray:
    """(m,) bool: person ``rows[who]`` has a clear sight line from camera ``cam`` (scenery and people).

    Who may hide a person seen by a camera is someone else that camera sees in
    its frustum (anyone hiding them stands in front of them, in view).
    """
    order = np.argsort(cam, kind="stable")
    first = np.searchsorted(cam[order], np.arange(len(mats)))
    last = np.searchsorted(cam[order], np.arange(len(mats)), side="right")
    pair_idx, occ = [], []
    for c in np.unique(cam):
        mine = order[first[c]:last[c]]
        pair_idx.append(np.repeat(mine, len(mine)))
        occ.append(np.tile(rows[who[mine]], len(mine)))
    eye = mats[cam, 3, :3]
    right, up, back = mats[cam, 0, :3], mats[cam, 1, :3], mats[cam, 2, :3]
    return seen_points(eye, (right, up, -back), tan_x[cam], tan_y[cam], near[cam], np.full(len(cam), np.inf),
                       ground, rows[who], (np.concatenate(pair_idx), np.concatenate(occ)), prisms)


def _mean(values: np.ndarray) -> float:
    """Mean over the defined (non-NaN) entries; NaN, quietly, when none is (a shot without events)."""
    defined = ~np.isnan(values)
    return float(np.mean(values[defined])) if defined.any() else float("nan")
