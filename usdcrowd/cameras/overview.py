"""The overview behavior: one camera that keeps the whole crowd in frame.

It keeps the crowd's centroid in view from a fixed bearing, at a distance
that fits the crowd's spread into the field of view, smoothed over a second
so it does not jitter with individual agents. It is the shot's
``Cameras/CrowdCam`` beside the camera agents.
"""

from __future__ import annotations

import numpy as np

from ..core import model
from ..core.view import look_at

NAME = "CrowdCam"
# A 35 mm full-frame 16:9 crop with a 28 mm lens.
FOCAL_LENGTH = 28.0
H_APERTURE = 36.0
V_APERTURE = 20.25
ELEVATION_DEG = 35.0


def crowd_summary(positions, visible: np.ndarray, block: int = 256,
                  fill: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """(t, 3) centroid and (t,) largest distance from it of the visible crowd per frame (everyone if nobody is).

    ``positions`` is a (t, n, 3) array or a :class:`usdcrowd.core.framestore.FrameStore`,
    read ``block`` frames at a time. NaN positions are people not in the scene (a replay); a frame
    with nobody takes the nearest frame's values (:func:`filled`), or stays NaN without ``fill`` (a
    chunk of a shot: fill once the whole shot is known).
    """
    vis = np.asarray(visible, bool)
    vis = vis if vis.any() else np.ones_like(vis)
    from ..core.framestore import frame_blocks

    centres, spreads = [], []
    for frames in frame_blocks(positions, size=block):
        pos = frames[:, vis].astype(np.float64)
        here = np.isfinite(pos[..., 0])             # NaN: not in the scene at that frame (a replay)
        if here.all():
            c = pos.mean(axis=1)
            centres.append(c)
            spreads.append(np.linalg.norm(pos - c[:, None], axis=2).max(axis=1))
            continue
        count = here.sum(axis=1)
        c = np.where(here[..., None], pos, 0.0).sum(axis=1) / np.maximum(count, 1)[:, None]
        d = np.where(here, np.linalg.norm(np.nan_to_num(pos) - c[:, None], axis=2), 0.0)
        centres.append(np.where(count[:, None] > 0, c, np.nan))
        spreads.append(np.where(count > 0, d.max(axis=1, initial=0.0), np.nan))
    if not centres:
        return np.zeros((0, 3)), np.zeros(0)
    centres, spreads = np.concatenate(centres), np.concatenate(spreads)
    return (filled(centres), filled(spreads)) if fill else (centres, spreads)


def filled(values: np.ndarray) -> np.ndarray:
    """``values`` (t, ...) with NaN frames (nobody in the scene) given the nearest frame's values."""
    bad = ~np.isfinite(values.reshape(len(values), -1)).all(axis=1)
    if not bad.any() or bad.all():
        return np.nan_to_num(values) if bad.all() else values
    good = np.flatnonzero(~bad)
    nearest = good[np.clip(np.searchsorted(good, np.arange(len(values))), 0, len(good) - 1)]
    before = good[np.clip(np.searchsorted(good, np.arange(len(values))) - 1, 0, len(good) - 1)]
    pick = np.where(np.abs(before - np.arange(len(values))) < np.abs(nearest - np.arange(len(values))), before,
                    nearest)
    return values[pick]


def overview_track(centre: np.ndarray, spread: np.ndarray, times: np.ndarray, fps: float,
                   path: str) -> model.CameraTrack:
    """A camera framing the whole crowd.

    Parameters
    ----------
    centre : (t, 3) float
        Centroid of the visible agents, canonical metres.
    spread : (t,) float
        Largest distance of a visible agent from the centroid, metres.
    times : (t,) float
        Time codes.
    fps : float
    path : str
        Prim path of the camera.
    """
    # Half a metre around the outermost agent, and at least a 3 m wide view.
    spread = np.maximum(np.asarray(spread, dtype=np.float64) + 0.5, 1.5)
    centre = np.asarray(centre, dtype=np.float64)
    k = max(1, int(fps))
    kernel = np.ones(k) / k
    pad = lambda a: np.pad(a, [(k // 2, k - 1 - k // 2)] + [(0, 0)] * (a.ndim - 1), mode="edge")
    centre = np.stack([np.convolve(pad(centre[:, j]), kernel, mode="valid") for j in range(3)], 1)
    spread = np.convolve(pad(spread), kernel, mode="valid")
    half_fov = np.arctan(0.5 * V_APERTURE / FOCAL_LENGTH)
    distance = spread / np.tan(half_fov)
    bearing = np.array([0.0, -np.cos(np.radians(ELEVATION_DEG)), np.sin(np.radians(ELEVATION_DEG))])
    target = centre + np.array([0.0, 0.0, 1.0])
    eye = target + distance[:, None] * bearing
    return model.CameraTrack(path, np.asarray(times, dtype=np.float64), look_at(eye, target),
                             np.full(len(times), FOCAL_LENGTH), H_APERTURE, V_APERTURE, 0.1, 1000.0)
