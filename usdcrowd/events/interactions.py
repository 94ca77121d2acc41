"""One-to-one interactions: two characters face each other without moving.

Per frame, the still characters are put in a kd-tree and only the pairs
closer than ``interaction_distance`` are tested (``query_pairs``), never all
pairs. Pairs are then followed over frames with vectorised state arrays (no
Python loop over pairs per frame); samples are kept only for running pairs.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from itertools import islice

import numpy as np
from scipy.spatial import cKDTree

from .params import EventParams


def find_interaction_pairs(xy: np.ndarray, heading: np.ndarray, speed: np.ndarray,
                           eligible: np.ndarray, params: EventParams | None = None) -> np.ndarray:
    """Pairs of characters facing each other at near-zero speed in one frame.

    Parameters
    ----------
    xy : (n, 2) float
        Planar positions, metres.
    heading : (n,) float
        Facing yaw, radians (0 faces +X).
    speed : (n,) float
        Planar speed, m/s.
    eligible : (n,) bool
        Characters that may take part (visible, alive).
    params : EventParams, optional

    Returns
    -------
    (k, 2) int64
        Agent rows ``(a, b)`` with ``a < b``, sorted.
    """
    p = params or EventParams()
    idx = np.flatnonzero(eligible & (speed <= p.interaction_speed))
    if len(idx) < 2:
        return np.zeros((0, 2), np.int64)
    pts = np.asarray(xy, np.float64)[idx]
    pairs = cKDTree(pts).query_pairs(p.interaction_distance, output_type="ndarray")
    if len(pairs) == 0:
        return np.zeros((0, 2), np.int64)
    i, j = pairs[:, 0], pairs[:, 1]
    d = pts[j] - pts[i]
    dist = np.hypot(d[:, 0], d[:, 1])
    dhat = d / np.maximum(dist, 1e-12)[:, None]
    h = np.asarray(heading, np.float64)[idx]
    hi = np.stack([np.cos(h[i]), np.sin(h[i])], axis=1)
    hj = np.stack([np.cos(h[j]), np.sin(h[j])], axis=1)
    cos_tol = np.cos(np.radians(p.interaction_facing))
    # Each one's heading must point at the other: i along +d, j along -d.
    facing = ((np.einsum("ij,ij->i", hi, dhat) >= cos_tol)
              & (np.einsum("ij,ij->i", hj, -dhat) >= cos_tol) & (dist > 1e-6))
    a, b = idx[i[facing]], idx[j[facing]]
    out = np.stack([np.minimum(a, b), np.maximum(a, b)], axis=1)
    return out[np.lexsort((out[:, 1], out[:, 0]))]


@dataclass
class InteractionRecord:
    """A finished interaction, before it is numbered.

    Attributes
    ----------
    a, b : int
        Agent rows, ``a < b``.
    times : (m,) float64
        Time codes, every frame from the first to the last frame the test held.
    center : (m, 3) float64
        Midpoint of the two, metres.
    radius : (m,) float64
        Half their distance plus the margin, metres.
    """

    a: int
    b: int
    times: np.ndarray
    center: np.ndarray
    radius: np.ndarray


class InteractionTracker:
    """Follows facing pairs over frames; each pair runs at most one interaction at a time.

    Parameters
    ----------
    n_agents : int
    fps : float
    params : EventParams
    """

    def __init__(self, n_agents: int, fps: float, params: EventParams):
        self.n = int(n_agents)
        self.p = params
        self.gap = EventParams.frames(params.interaction_gap, fps)
        self.min_frames = max(EventParams.frames(params.interaction_min_duration, fps), 1)
        # Running pairs, sorted by key a * n + b: first and last frame the test held.
        self.key = np.zeros(0, np.int64)
        self.start = np.zeros(0, np.int64)
        self.last = np.zeros(0, np.int64)
        # Samples of the running pairs, one block per frame since the oldest start.
        self.blocks: deque = deque()  # (frame, time, keys (r,), center (r, 3), radius (r,))
        self.stored = 0  # entries in blocks
        self.done: list[InteractionRecord] = []

    def step(self, frame: int, time: float, position: np.ndarray, heading: np.ndarray,
             speed: np.ndarray, eligible: np.ndarray) -> None:
        """Advance one frame.

        Parameters
        ----------
        frame : int
            Frame index since the first fed frame.
        time : float
            Its time code.
        position : (n, 3) float
        heading, speed : (n,) float
        eligible : (n,) bool
        """
        pairs = find_interaction_pairs(position[:, :2], heading, speed, eligible, self.p)
        cand = pairs[:, 0] * self.n + pairs[:, 1]
        if len(self.key):
            pos = np.minimum(np.searchsorted(self.key, cand), len(self.key) - 1)
            found = self.key[pos] == cand
            self.last[pos[found]] = frame
            cand = cand[~found]
        if len(cand):
            key = np.concatenate([self.key, cand])
            order = np.argsort(key, kind="stable")
            self.key = key[order]
            self.start = np.concatenate([self.start, np.full(len(cand), frame)])[order]
            self.last = np.concatenate([self.last, np.full(len(cand), frame)])[order]
        ended = frame - self.last > self.gap
        if ended.any():
            self._close(ended)
        if len(self.key):
            a, b = self.key // self.n, self.key % self.n
            pa, pb = position[a].astype(np.float64), position[b].astype(np.float64)
            center = 0.5 * (pa + pb)
            dist = np.hypot(pb[:, 0] - pa[:, 0], pb[:, 1] - pa[:, 1])
            self.blocks.append((frame, float(time), self.key.copy(), center, 0.5 * dist + self.p.interaction_margin))
            self.stored += len(self.key)
            oldest = int(self.start.min())
        else:
            oldest = frame + 1
        while self.blocks and self.blocks[0][0] < oldest:
            self.stored -= len(self.blocks.popleft()[2])
        # Blocks keep the samples of pairs that ended until their frame is
        # dropped; compact when those outweigh the running pairs' own samples.
        needed = int(np.sum(frame - self.start + 1))
        if self.stored > 2 * needed + 4096:
            self._compact()

    def _compact(self) -> None:
        """Drop the samples of pairs no longer running from every block."""
        blocks = deque()
        self.stored = 0
        for f, t, keys, c, r in self.blocks:
            keep = np.isin(keys, self.key, assume_unique=True)
            blocks.append((f, t, keys[keep], c[keep], r[keep]))
            self.stored += int(keep.sum())
        self.blocks = blocks

    def _close(self, which: np.ndarray) -> None:
        """End the pairs ``which`` (bool mask); keep those that lasted long enough."""
        for k, s, e in zip(self.key[which], self.start[which], self.last[which]):
            if e - s + 1 >= self.min_frames:
                self.done.append(self._record(int(k), int(s), int(e)))
        keep = ~which
        self.key, self.start, self.last = self.key[keep], self.start[keep], self.last[keep]

    def _record(self, key: int, start: int, end: int) -> InteractionRecord:
        """Gather the samples of pair ``key`` on frames ``start .. end``."""
        times, centers, radii = [], [], []
        # Blocks are consecutive frames (one per frame while any pair runs), so
        # the pair's frames are a slice: no walk from the oldest running start.
        first = self.blocks[0][0] if self.blocks else start
        for f, t, keys, c, r in islice(self.blocks, max(0, start - first), max(0, end - first + 1)):
            i = int(np.searchsorted(keys, key))
            times.append(t)
            centers.append(c[i])
            radii.append(r[i])
        return InteractionRecord(key // self.n, key % self.n, np.asarray(times, np.float64),
                                 np.asarray(centers, np.float64).reshape(-1, 3), np.asarray(radii, np.float64))

    def finish(self) -> list[InteractionRecord]:
        """End every running pair; the kept interactions in the order they ended."""
        if len(self.key):
            self._close(np.ones(len(self.key), bool))
        self.blocks.clear()
        self.stored = 0
        return self.done
