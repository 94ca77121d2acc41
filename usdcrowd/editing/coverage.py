"""How well each camera shows each event at each frame.

An event is well shown by a camera when its people are on screen, not
hidden (by scenery or by other people: :mod:`usdcrowd.cameras.sightlines`),
and large enough to read. Per (camera, event, frame) this gives the share of
the members taking part that the camera shows, and how tall they are on
screen; the director weighs the two by the event's importance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..cameras.sightlines import Prisms, lens_tangents, views
from ..core import model
from .params import EditParams


@dataclass
class Coverage:
    """Every camera's view of every event over a shot.

    Attributes
    ----------
    times : (t,) float64
    share : (c, e, t) float32
        Members taking part (rendered ones) visible in the camera, as a share (0 when none takes part).
    size : (c, e, t) float32
        Median on-screen height of those visible, share of the frame's height (0 when none is).
    shown : (c, t) float32
        People of any kind the camera shows legibly, summed (legibility in 0..1 each).
    eye : (c, t, 3) float64
        Camera positions, metres.
    centre : (e, t, 3) float64
        Event centres (from the event's samples; NaN outside it).
    line : (e, t, 2) float64
        Unit line of action seen from above (zeros: none): the two people of
        a two-person event, or the direction a group walks.
    """

    times: np.ndarray
    share: np.ndarray
    size: np.ndarray
    shown: np.ndarray
    eye: np.ndarray
    centre: np.ndarray
    line: np.ndarray

    def framing(self, params: EditParams) -> np.ndarray:
        """(c, e, t) float32: sqrt(share visible) x legibility of their size.

        The square root: a closer shot of part of a group reads better than
        all of it too small to see (a quarter of the people, legible, is
        worth half the group; all of it at half the legible height, too).
        """
        return np.sqrt(self.share) * np.clip(self.size / params.legible_height, 0.0, 1.0)


def coverage(tracks: list[model.CameraTrack], positions, events: model.EventTable, visible: np.ndarray,
             obstacles: model.Obstacles, params: EditParams, fps: float, progress=None,
             overhead: model.Obstacles | None = None, heights: np.ndarray | None = None) -> Coverage:
    """Measure every camera's view of every event at every frame.

    Parameters
    ----------
    tracks : list[CameraTrack]
        Sampled at the shot's frames (``tracks[0].times``).
    positions : (t, n, 3) float array-like
        Ground positions per frame, metres (a :class:`~usdcrowd.core.framestore.FrameStore` works).
    events : EventTable
    visible : (n,) bool
        Rendered agents (invisible leaders are neither shown nor hide anyone).
    obstacles : Obstacles
    params : EditParams
    fps : float
    progress : callable(int), optional
        Called with the number of frames done since the last call.
    overhead : Obstacles, optional
        Raised scenery that hides people from cameras above it.
    heights : (n,) float, optional
        Body heights, metres (the points sight lines end at scale with them).
    """
    times = np.asarray(tracks[0].times, dtype=np.float64)
    c, e, t = len(tracks), len(events), len(times)
    visible = np.asarray(visible, bool)
    vis_rows = np.flatnonzero(visible)
    col = np.full(len(visible), -1)
    col[vis_rows] = np.arange(len(vis_rows))
    prisms = Prisms.of(obstacles, overhead=overhead)
    share = np.zeros((c, e, t), np.float32)
    size = np.zeros((c, e, t), np.float32)
    shown = np.zeros((c, t), np.float32)
    near = np.array([tr.near for tr in tracks])
    far = np.array([tr.far for tr in tracks])
    eye = np.stack([tr.cam_to_world[:, 3, :3] for tr in tracks]) if c else np.zeros((0, t, 3))
    centre, line = _event_geometry(events, times, positions, fps, params)
    for i in range(t):
        running = events.active_at(times[i])
        ground = np.asarray(positions[i], dtype=np.float64)
        mats = np.stack([tr.cam_to_world[i] for tr in tracks])
        tx, ty = lens_tangents(tracks, i)
        v = views(mats, tx, ty, near, far, ground, people=vis_rows, prisms=prisms, occluders=visible,
                  heights=heights)
        legible = np.where(v.visible, np.clip(v.height / params.legible_height, 0.0, 1.0), 0.0)
        shown[:, i] = legible.sum(axis=1)
        for k in running:
            rows = events[k].members_at(times[i])
            idx = col[rows]
            idx = idx[idx >= 0]
            if len(idx) == 0:
                continue
            seen = v.visible[:, idx]
            share[:, k, i] = seen.mean(axis=1)
            h = np.where(seen, v.height[:, idx], np.nan)
            with np.errstate(all="ignore"):
                med = np.nanmedian(np.where(seen.any(axis=1, keepdims=True), h, 0.0), axis=1)
            size[:, k, i] = np.nan_to_num(med)
        if progress is not None:
            progress(1)
    return Coverage(times, share, size, shown, eye, centre, line)


def _event_geometry(events: model.EventTable, times: np.ndarray, positions, fps: float, params: EditParams):
    """(e, t, 3) centres and (e, t, 2) lines of action (see :class:`Coverage`)."""
    e, t = len(events), len(times)
    centre = np.full((e, t, 3), np.nan)
    line = np.zeros((e, t, 2))
    half = max(1, int(round(0.5 * fps)))
    for k, ev in enumerate(events):
        frames, samples = ev.on_frames(times)
        if len(frames) == 0:
            continue
        centre[k, frames] = ev.center[samples]
        pairs = ev.active[samples].sum(axis=1) == 2
        # A pair: the line through the two (who is first does not matter for a side).
        for f, s in zip(frames[pairs], samples[pairs]):
            a, b = ev.members[ev.active[s]]
            pa, pb = np.asarray(positions[f][[a, b]], dtype=np.float64)[:, :2]
            d = pb - pa
            n = np.linalg.norm(d)
            if n > 1e-6:
                line[k, f] = d / n
        # A group: where its centre goes, over a second about each frame.
        c = ev.center[:, :2]
        if len(c) > 1:
            lo = np.clip(np.arange(len(c)) - half, 0, len(c) - 1)
            hi = np.clip(np.arange(len(c)) + half, 0, len(c) - 1)
            vel = (c[hi] - c[lo]) / np.maximum(hi - lo, 1)[:, None] * fps
            speed = np.linalg.norm(vel, axis=1)
            moving = (speed[samples] >= params.min_line_speed) & ~pairs
            s = samples[moving]
            line[k, frames[moving]] = vel[s] / speed[s, None]
    return centre, line
