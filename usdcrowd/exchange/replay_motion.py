"""Recorded tracks turned into a crowd's frames: what ``usdcrowd replay`` animates.

The tracks (:class:`~usdcrowd.exchange.recorded_tracks.Tracks`) are sampled at
the shot's frame rate (:class:`TrackSampler`): linearly between the rows a
person has (a gap longer than ``max_gap_s`` is a person leaving and coming
back), absent before the first row and after the last. Positions are the
file's where a frame falls on a row, so a replayed shot reproduces the file
point for point. The frames are made a window at a time
(:class:`ReplayMotion`), so memory follows the window, not the recording.

The rest is derived as the simulation derives it for its own walkers:
velocity from the positions (a centred difference over about a fifth of a
second, which smooths the corners that linear interpolation of sparse rows
leaves), heading from the velocity (held while standing), the walk cycle
advanced by the distance walked (:func:`usdcrowd.character.animation.advance_phase`,
so the stride keeps pace with the ground covered), and the gaze on where the
person will be a second later.

Pure numpy: nothing here knows USD.
"""

from __future__ import annotations

import numpy as np

from ..core import model
from .recorded_tracks import Tracks

# Half-width of the centred difference the velocity is taken over.
VELOCITY_HALF_WINDOW_S = 0.2
# Slower than this, a person stands: the heading is held, not turned by jitter.
STANDING_SPEED = 0.2
# People look at where they will be this much later...
GAZE_AHEAD_S = 1.0
# ...when that is at least this far; nearer, they look straight ahead.
GAZE_MIN_DISTANCE = 0.5
# Eye height of the canonical 1.75 m body, as a share of its height.
EYE_SHARE = 1.63 / 1.75


class TrackSampler:
    """Every person's ground position at the shot's frames, a window of frames at a time.

    Parameters
    ----------
    tracks : Tracks
    fps : float
        Frames per second of the shot; frame 0 is the file's first frame.
    max_gap_s : float
        Longest stretch without rows that is interpolated across.

    Attributes
    ----------
    n_frames : int
    first, last : (n,) int
        Each person's first and last frame.
    first_xy, last_xy : (n, 2) float
        Where they are at those frames.
    first_heading : (n,) float
        The way they first walk (toward their first position GAZE_MIN_DISTANCE
        from the start), radians; for someone who never moves that far, the
        way the file says they face, else 0.
    """

    def __init__(self, tracks: Tracks, fps: float, max_gap_s: float = 2.0):
        self.fps = float(fps)
        self.n = len(tracks)
        self._s, self._xy = tracks.seconds, tracks.xy
        facing = tracks.facing if tracks.facing is not None else np.full(len(tracks.frame), np.nan)
        self._facing = facing if np.isfinite(facing).any() else None
        self._rows = tracks.row_bounds
        # Whether each person's every row says which way they face (persons are 0..n-1, each with rows).
        self._facing_everywhere = (np.logical_and.reduceat(np.isfinite(facing), self._rows[:-1]) if len(facing)
                                   else np.zeros(self.n, bool))
        start, end = self._rows[:-1], self._rows[1:] - 1
        self.n_frames = int(np.floor(self._s.max() * fps + 1e-6)) + 1
        self.first = np.ceil(self._s[start] * fps - 1e-6).astype(np.int64)
        self.last = np.floor(self._s[end] * fps + 1e-6).astype(np.int64)
        self.first_xy, self.last_xy = self._xy[start], self._xy[end]
        self.first_heading = self._first_headings()
        # Rows in one ascending key (person, then time) to find anyone's last row before a time at once.
        self._span = float(self._s.max()) + 1.0
        self._key = tracks.person + self._s / self._span
        gap = np.flatnonzero((np.diff(self._s) > max_gap_s) & (tracks.person[1:] == tracks.person[:-1]))
        self._gaps = tracks.person[gap], self._s[gap], self._s[gap + 1]

    def _first_headings(self) -> np.ndarray:
        out = np.zeros(self.n)
        for i in range(self.n):
            xy = self._xy[self._rows[i]:self._rows[i + 1]]
            away = np.flatnonzero(np.linalg.norm(xy - xy[0], axis=1) >= GAZE_MIN_DISTANCE)
            if len(away):
                d = xy[away[0]] - xy[0]
                out[i] = np.arctan2(d[1], d[0])
            elif self._facing is not None and np.isfinite(self._facing[self._rows[i]]):
                out[i] = self._facing[self._rows[i]]
        return out

    def _bracketing(self, i: int, k: np.ndarray) -> slice:
        """Person ``i``'s rows from the last at or before frame ``k[0]`` to the first at or after ``k[-1]``:
        all that interpolating at those frames needs (a window's cost then does not grow with the track)."""
        start, end = self._rows[i], self._rows[i + 1]
        s = self._s[start:end]
        lo = max(int(np.searchsorted(s, k[0] / self.fps, side="right")) - 1, 0)
        hi = min(int(np.searchsorted(s, k[-1] / self.fps, side="left")) + 1, end - start)
        return slice(start + lo, start + hi)

    def facing(self, a: int, b: int) -> np.ndarray | None:
        """(b - a, n) the way each person faces at frames ``a`` to ``b - 1`` as the file says (between
        rows, turned the short way), radians; NaN where it does not say; None for a file without facings."""
        if self._facing is None:
            return None
        out = np.full((b - a, self.n), np.nan)
        for i in np.flatnonzero((self.first < b) & (self.last >= a)):
            k = np.arange(max(a, self.first[i]), min(b, self.last[i] + 1))
            # Where some rows say no facing, the nearest that do may lie outside the window: the whole track.
            rows = self._bracketing(i, k) if self._facing_everywhere[i] else slice(self._rows[i], self._rows[i + 1])
            si, fi = self._s[rows], self._facing[rows]
            ok = np.isfinite(fi)
            if not ok.any():
                continue
            at = np.clip(k / self.fps, si[0], si[-1])
            out[k - a, i] = np.arctan2(np.interp(at, si[ok], np.sin(fi[ok])), np.interp(at, si[ok], np.cos(fi[ok])))
        return out

    def window(self, a: int, b: int) -> np.ndarray:
        """(b - a, n, 2) positions at frames ``a`` to ``b - 1``, metres; NaN where a person is absent."""
        xy = np.full((b - a, self.n, 2), np.nan)
        for i in np.flatnonzero((self.first < b) & (self.last >= a)):
            k = np.arange(max(a, self.first[i]), min(b, self.last[i] + 1))
            rows = self._bracketing(i, k)
            si, pi = self._s[rows], self._xy[rows]
            at = np.clip(k / self.fps, si[0], si[-1])
            xy[k - a, i, 0], xy[k - a, i, 1] = np.interp(at, si, pi[:, 0]), np.interp(at, si, pi[:, 1])
        person, s0, s1 = self._gaps
        on = (s0 < b / self.fps) & (s1 > a / self.fps)
        k = np.arange(a, b) / self.fps
        for i, g0, g1 in zip(person[on], s0[on], s1[on]):
            xy[(k > g0 + 1e-9) & (k < g1 - 1e-9), i] = np.nan
        return xy

    def resting(self, a: int) -> np.ndarray:
        """(n, 2) where someone absent at frame ``a`` stands: where they were last seen, or where they will
        come in."""
        row = np.searchsorted(self._key, np.arange(self.n) + (a / self.fps) / self._span, side="right") - 1
        seen = row >= self._rows[:-1]
        return np.where(seen[:, None], self._xy[np.maximum(row, 0)], self.first_xy)


def _held(values: np.ndarray, present: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """``values`` (t, n, ...) with every absent frame given the last present one before it, or ``fallback``
    (n, ...) before a person's first present frame."""
    t = len(values)
    before = np.maximum.accumulate(np.where(present, np.arange(t)[:, None], -1), axis=0)
    extra = (1,) * (values.ndim - 2)
    out = np.take_along_axis(values, np.maximum(before, 0).reshape(before.shape + extra), axis=0)
    return np.where((before >= 0).reshape(before.shape + extra), out, fallback[None])


class ReplayMotion:
    """The crowd's frames for a :class:`TrackSampler`, window by window.

    Parameters
    ----------
    sampler : TrackSampler
    first_code : float
        Time code of frame 0.
    height : (n,) float
        Body heights, metres (the gaze is at eye height).
    ground : callable((m,) x, (m,) y) -> (m,) z, optional
        Ground height; flat at 0 if None.
    """

    def __init__(self, sampler: TrackSampler, first_code: float, height: np.ndarray, ground=None):
        self.sampler = sampler
        self.first_code = float(first_code)
        self.height = np.asarray(height, np.float64)
        self.ground = ground
        fps = sampler.fps
        self._half = max(1, int(round(VELOCITY_HALF_WINDOW_S * fps)))
        self._ahead = int(round(GAZE_AHEAD_S * fps))
        self._heading = sampler.first_heading.copy()      # held while standing, from one window to the next
        self._anim_prev = None

    def chunks(self, size: int):
        """Consecutive :class:`CrowdFrames` of at most ``size`` frames over the whole recording."""
        for a in range(0, self.sampler.n_frames, size):
            yield self.frames(a, min(a + size, self.sampler.n_frames))

    def frames(self, a: int, b: int) -> model.CrowdFrames:
        """Frames ``a`` to ``b - 1`` (call in order: headings and the walk cycle carry over), with
        ``present``; an absent person stands, idle, where they come in or left (hidden by the shot's
        visibility)."""
        from ..character.animation import classify

        pad = max(self._half, self._ahead)
        lo, hi = max(0, a - pad), min(self.sampler.n_frames, b + pad)
        xy = self.sampler.window(lo, hi)
        present = np.isfinite(xy[..., 0])
        pos2 = _held(np.nan_to_num(xy), present, self.sampler.resting(lo))
        position = self._on_ground(pos2)
        look = _gaze(position, present, self._ahead, self.height)
        keep = slice(a - lo, b - lo)
        velocity = np.where(present[keep, :, None], self._velocity(pos2, present)[keep], 0.0)
        speed = np.hypot(velocity[..., 0], velocity[..., 1])
        heading = self._headings(velocity, speed >= STANDING_SPEED, self.sampler.facing(a, b))
        cls = classify(velocity, heading)
        phase = self._phase(speed, cls)
        t, n = b - a, self.sampler.n
        return model.CrowdFrames(
            times=self.first_code + np.arange(a, b, dtype=np.float64), position=position[keep].astype(np.float32),
            heading=heading.astype(np.float32), velocity=velocity.astype(np.float32),
            behavior=np.full((t, n), model.BEHAVIORS.index("walk"), np.int8), anim_class=cls.astype(np.int8),
            anim_phase=phase, health=np.zeros((t, n), np.int8), look_at=look[keep].astype(np.float32),
            path_method=np.zeros(n, np.int8), present=present[keep])

    def _on_ground(self, pos2: np.ndarray) -> np.ndarray:
        t, n = pos2.shape[:2]
        z = np.zeros((t, n)) if self.ground is None else self.ground(pos2[..., 0].ravel(),
                                                                     pos2[..., 1].ravel()).reshape(t, n)
        return np.concatenate([pos2, z[..., None]], axis=2)

    def _velocity(self, pos2: np.ndarray, present: np.ndarray) -> np.ndarray:
        """(t, n, 2) centred differences over ``_half`` frames each side, within each stretch of frames a
        person is present (one-sided where a stretch begins or ends, and at the window's ends, which are
        the recording's: windows are padded); zero for a stretch of one frame."""
        t = len(pos2)
        k = np.arange(t)[:, None]
        cols = np.arange(pos2.shape[1])
        stretch = np.cumsum(present & ~np.vstack([np.zeros((1, len(cols)), bool), present[:-1]]), axis=0)
        ahead = np.minimum(k + self._half, t - 1) + np.zeros_like(stretch)
        behind = np.maximum(k - self._half, 0) + np.zeros_like(stretch)

        def outside(rows):
            return ~present[rows, cols] | (stretch[rows, cols] != stretch)

        for _ in range(self._half):                    # step back inside the stretch (at most _half frames)
            ahead = np.where(outside(ahead), ahead - 1, ahead)
            behind = np.where(outside(behind), behind + 1, behind)
        ahead, behind = np.maximum(ahead, k), np.minimum(behind, k)
        span = (ahead - behind)[..., None] / self.sampler.fps
        return np.where(span > 0, (pos2[ahead, cols] - pos2[behind, cols]) / np.maximum(span, 1e-9), 0.0)

    def _headings(self, velocity: np.ndarray, walking: np.ndarray, facing: np.ndarray | None) -> np.ndarray:
        """(t, n) the way of walking; standing, the way the file says they face, else the last one."""
        raw = np.arctan2(velocity[..., 1], velocity[..., 0])
        known = walking
        if facing is not None:
            told = ~walking & np.isfinite(facing)
            raw, known = np.where(told, facing, raw), walking | told
        idx = np.maximum.accumulate(np.where(known, np.arange(len(raw))[:, None], -1), axis=0)
        held = np.take_along_axis(raw, np.maximum(idx, 0), axis=0)
        heading = np.where(idx >= 0, held, self._heading[None])
        self._heading = heading[-1].copy()
        return heading

    def _phase(self, speed: np.ndarray, cls: np.ndarray) -> np.ndarray:
        """The walk cycle advanced by the distance walked, continued from the previous window."""
        from ..character.animation import advance_phase

        dt = 1.0 / self.sampler.fps
        if self._anim_prev is None:
            phase = advance_phase(speed, cls, dt)
        else:
            ps, pc, pp = self._anim_prev
            phase = advance_phase(np.concatenate([ps[None], speed]), np.concatenate([pc[None], cls]), dt, pp)[1:]
        self._anim_prev = (speed[-1], cls[-1], phase[-1])
        return phase.astype(np.float32)


def _gaze(position: np.ndarray, present: np.ndarray, ahead: int, height: np.ndarray) -> np.ndarray:
    """(t, n, 3) where each person will be ``ahead`` frames later (their last frame, near the end), at eye
    height; NaN while that is nearer than ``GAZE_MIN_DISTANCE`` or they are absent."""
    t = len(position)
    k = np.arange(t)[:, None]
    last = np.where(present, k, -1).max(axis=0)
    later = np.minimum(k + ahead, np.maximum(last, 0)[None, :])
    target = np.take_along_axis(position, np.broadcast_to(later, present.shape)[..., None], axis=0).copy()
    far = np.linalg.norm(target[..., :2] - position[..., :2], axis=2) >= GAZE_MIN_DISTANCE
    target[..., 2] += EYE_SHARE * height[None, :]
    return np.where((far & present)[..., None], target, np.nan)
