"""How well tracking cameras frame their events, frame by frame.

Seed 000 counts a camera's work by the activity metric (:mod:`.metrics`):
people near it, in its frustum. A viewer asks more of a camera that says it
tracks an event: are the event's people on screen, not hidden by a wall or
by others, and large enough to see; and how long after taking the event
does the camera get there? Per tracking frame this measures the share of
the event's (rendered) people visible (:mod:`.sightlines`) and their median
height on screen, whether the picture shows only scenery or ground (none of
them in frame unhidden by scenery: "walled"; a passer-by in front of them
does not count), and per take the time to frame it (at least half its
people visible).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core import model
from .sightlines import Prisms, lens_tangents, views

# A take is framed from the first frame at least this share of its people is visible.
FRAMED_SHARE = 0.5
# Seconds a camera is given to reach an event it has just taken.
SETTLE_SECONDS = 2.0


@dataclass
class TrackingQuality:
    """One camera agent's tracking, measured.

    Attributes
    ----------
    camera : str
    times : (t,) float64
    event : list[str]
        Per frame, the event tracked ("" while scouting).
    share : (t,) float64
        Share of the tracked event's people visible (NaN while scouting or when none takes part).
    size : (t,) float64
        Their median height on screen, share of the frame's height (0 when none is visible).
    since : (t,) float64
        Seconds since the camera took the event it tracks (NaN while scouting).
    takes : list of (str, float, float)
        (event, time code taken, seconds to frame it or NaN if it never was).
    walled : (t,) bool
        None of the tracked event's people is in the picture unhidden by scenery: the picture shows
        only scenery or ground (a passer-by in front of them does not count; False while scouting).
    """

    camera: str
    times: np.ndarray
    event: list
    share: np.ndarray
    size: np.ndarray
    since: np.ndarray
    takes: list
    walled: np.ndarray

    @property
    def settled(self) -> np.ndarray:
        """(t,) bool: tracking, with someone taking part, at least SETTLE_SECONDS after taking the event."""
        return np.nan_to_num(self.since, nan=-1.0) >= SETTLE_SECONDS - 1e-9

    def summary(self) -> dict:
        """Frames tracking, settled frames, the share of those framed and blank, median size, times to frame."""
        s = self.settled & ~np.isnan(self.share)
        share = self.share[s]
        return {"tracking_frames": int((~np.isnan(self.since)).sum()),
                **_shares(share, self.walled[s], [t for _, _, t in self.takes]),
                "median_size": float(np.median(self.size[s][share > 0])) if (share > 0).any() else float("nan")}


def _shares(share: np.ndarray, walled: np.ndarray, seconds_to_frame: list) -> dict:
    """Settled frames, the shares framed, blank and walled (``walled`` (f,) of the same frames), the mean
    share visible ((f,) shares of settled frames),
    and the takes, those never framed and the median seconds to frame one (NaN where there is nothing)."""
    ttf = np.array(seconds_to_frame, dtype=np.float64)
    some = len(share) > 0
    return {"settled_frames": int(len(share)),
            "framed": float(np.mean(share >= FRAMED_SHARE)) if some else float("nan"),
            "blank": float(np.mean(share == 0)) if some else float("nan"),
            "walled": float(np.mean(walled)) if some else float("nan"),
            "mean_share": float(np.mean(share)) if some else float("nan"),
            "takes": int(len(ttf)), "never_framed": int(np.isnan(ttf).sum()),
            "median_seconds_to_frame": float(np.nanmedian(ttf)) if np.isfinite(ttf).any() else float("nan")}


def tracking_quality(tracks: list[model.CameraTrack], positions, events: model.EventTable, visible: np.ndarray,
                     obstacles: model.Obstacles, fps: float,
                     overhead: model.Obstacles | None = None,
                     heights: np.ndarray | None = None) -> list[TrackingQuality]:
    """Measure every camera agent of ``tracks`` (those with a per-frame state) over the shot.

    Parameters
    ----------
    tracks : list[CameraTrack]
        Sampled at the shot's frames; cameras without ``tracked`` are skipped.
    positions : (t, n, 3) float array-like
        Ground positions per frame (a FrameStore works).
    events : EventTable
    visible : (n,) bool
    obstacles : Obstacles
    fps : float
    overhead : Obstacles, optional
        Raised scenery that hides people from cameras above it.
    heights : (n,) float, optional
        Body heights, metres (the points sight lines end at scale with them).
    """
    agents = [tr for tr in tracks if tr.tracked is not None]
    if not agents:
        return []
    times = np.asarray(agents[0].times, dtype=np.float64)
    visible = np.asarray(visible, bool)
    rows = np.flatnonzero(visible)
    col = np.full(len(visible), -1)
    col[rows] = np.arange(len(rows))
    by_path = {e.path: e for e in events}
    prisms = Prisms.of(obstacles, overhead=overhead)
    c, t = len(agents), len(times)
    share = np.full((c, t), np.nan)
    walled = np.zeros((c, t), bool)
    size = np.zeros((c, t))
    near = np.array([tr.near for tr in agents])
    far = np.array([tr.far for tr in agents])
    for i in range(t):
        if not any(tr.tracked[i] for tr in agents):
            continue
        mats = np.stack([tr.cam_to_world[i] for tr in agents])
        tx, ty = lens_tangents(agents, i)
        v = views(mats, tx, ty, near, far, np.asarray(positions[i], dtype=np.float64), people=rows, prisms=prisms,
                  occluders=visible, heights=heights)
        for k, tr in enumerate(agents):
            e = by_path.get(tr.tracked[i])
            if e is None:
                continue
            idx = col[e.members_at(times[i])]
            idx = idx[idx >= 0]
            if len(idx) == 0:
                continue
            seen = v.visible[k, idx]
            share[k, i] = seen.mean()
            walled[k, i] = not (v.in_frame[k, idx] & ~v.hidden_by_scenery[k, idx]).any()
            size[k, i] = float(np.median(v.height[k, idx][seen])) if seen.any() else 0.0
    out = []
    for k, tr in enumerate(agents):
        since = np.full(t, np.nan)
        takes = []
        start = None
        for i in range(t):
            if not tr.tracked[i]:
                start = None
                continue
            if start is None or tr.tracked[i] != tr.tracked[i - 1]:
                start = i
                takes.append([tr.tracked[i], float(times[i]), float("nan")])
            since[i] = (times[i] - times[start]) / fps
            if np.isnan(takes[-1][2]) and share[k, i] >= FRAMED_SHARE:
                takes[-1][2] = float(since[i])
        out.append(TrackingQuality(tr.path, times, list(tr.tracked), share[k], size[k], since,
                                   [tuple(x) for x in takes], walled[k]))
    return out


def pooled(qualities: list[TrackingQuality]) -> dict:
    """Every camera's settled tracking frames and takes together: the shares framed and blank, the mean
    share visible, and the median seconds to frame a take (NaN where nothing was tracked)."""
    kept = [q.settled & ~np.isnan(q.share) for q in qualities]
    share = np.concatenate([q.share[s] for q, s in zip(qualities, kept)]) if qualities else np.zeros(0)
    walled = np.concatenate([q.walled[s] for q, s in zip(qualities, kept)]) if qualities else np.zeros(0, bool)
    return {"cameras": len(qualities), **_shares(share, walled, [t for q in qualities for _, _, t in q.takes])}
