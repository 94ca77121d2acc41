"""Recorded tracks turned into a crowd's frames: what ``usdcrowd replay`` animates.

The tracks (:class:`~usdcrowd.exchange.recorded_tracks.Tracks`) are sampled at
the shot's frame rate: linearly between the rows a person has (a gap longer
than ``max_gap_s`` is a person leaving and coming back), absent before the
first row and after the last. Positions are the file's where a frame falls on
a row, so a replayed shot reproduces the file point for point.

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


def sample_tracks(tracks: Tracks, fps: float, max_gap_s: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """Every person's ground position at each frame of the shot.

    Parameters
    ----------
    tracks : Tracks
    fps : float
        Frames per second of the shot; frame 0 is the file's first frame.
    max_gap_s : float
        Longest stretch without rows that is interpolated across.

    Returns
    -------
    seconds : (t,) float64
        Time of each shot frame after the file's first frame.
    xy : (t, n, 2) float64
        Positions, metres; NaN where the person is absent.
    """
    s = tracks.seconds
    n_frames = int(np.floor(s.max() * fps + 1e-6)) + 1
    seconds = np.arange(n_frames) / fps
    xy = np.full((n_frames, len(tracks), 2), np.nan)
    bounds = np.searchsorted(tracks.person, np.arange(len(tracks) + 1))
    for i in range(len(tracks)):
        rows = slice(bounds[i], bounds[i + 1])
        si, pi = s[rows], tracks.xy[rows]
        k = np.arange(int(np.ceil(si[0] * fps - 1e-6)), int(np.floor(si[-1] * fps + 1e-6)) + 1)
        if len(k) == 0:
            continue
        at = np.clip(k / fps, si[0], si[-1])
        xy[k, i, 0], xy[k, i, 1] = np.interp(at, si, pi[:, 0]), np.interp(at, si, pi[:, 1])
        for g in np.flatnonzero(np.diff(si) > max_gap_s):
            inside = (at > si[g] + 1e-9) & (at < si[g + 1] - 1e-9)
            xy[k[inside], i] = np.nan
    return seconds, xy


def _held(values: np.ndarray, present: np.ndarray) -> np.ndarray:
    """``values`` (t, n, ...) with every absent frame given the nearest present one before it (or after it,
    before a person's first frame); a person never present keeps zeros."""
    t = len(values)
    idx = np.where(present, np.arange(t)[:, None], -1)
    before = np.maximum.accumulate(idx, axis=0)
    after = np.where(present, np.arange(t)[:, None], t)
    after = np.minimum.accumulate(after[::-1], axis=0)[::-1]
    pick = np.where(before >= 0, before, np.where(after < t, after, 0))
    out = np.take_along_axis(values, pick.reshape(pick.shape + (1,) * (values.ndim - 2)), axis=0)
    return np.where(present.any(axis=0).reshape((1, -1) + (1,) * (values.ndim - 2)), out, 0)


def crowd_frames(xy: np.ndarray, fps: float, first_code: float, height: np.ndarray,
                 ground=None) -> model.CrowdFrames:
    """The crowd's frames for positions sampled by :func:`sample_tracks`.

    Parameters
    ----------
    xy : (t, n, 2) float
        Positions, NaN where absent.
    fps : float
    first_code : float
        Time code of frame 0.
    height : (n,) float
        Body heights, metres (the gaze is at eye height).
    ground : callable((m,) x, (m,) y) -> (m,) z, optional
        Ground height; flat at 0 if None.

    Returns
    -------
    CrowdFrames
        With ``present``; an absent person stands, idle, where they enter or
        leave (hidden there by the shot's visibility).
    """
    from ..character.animation import advance_phase, classify

    t, n = xy.shape[:2]
    present = np.isfinite(xy[..., 0])
    pos2 = _held(np.nan_to_num(xy), present)
    h = max(1, int(round(VELOCITY_HALF_WINDOW_S * fps)))
    ahead, behind = np.minimum(np.arange(t) + h, t - 1), np.maximum(np.arange(t) - h, 0)
    span = np.maximum(ahead - behind, 1)[:, None, None] / fps
    velocity = np.where(present[..., None], (pos2[ahead] - pos2[behind]) / span, 0.0)
    speed = np.hypot(velocity[..., 0], velocity[..., 1])
    walking = speed >= STANDING_SPEED
    heading = _held(np.arctan2(velocity[..., 1], velocity[..., 0]), walking)
    cls = classify(velocity, heading)
    phase = advance_phase(speed, cls, 1.0 / fps)
    z = np.zeros((t, n)) if ground is None else ground(pos2[..., 0].ravel(), pos2[..., 1].ravel()).reshape(t, n)
    position = np.concatenate([pos2, z[..., None]], axis=2)
    look = _gaze(position, present, fps, np.asarray(height, np.float64))
    return model.CrowdFrames(
        times=first_code + np.arange(t, dtype=np.float64), position=position.astype(np.float32),
        heading=heading.astype(np.float32), velocity=velocity.astype(np.float32),
        behavior=np.full((t, n), model.BEHAVIORS.index("walk"), np.int8), anim_class=cls.astype(np.int8),
        anim_phase=phase, health=np.zeros((t, n), np.int8), look_at=look.astype(np.float32),
        path_method=np.zeros(n, np.int8), present=present)


def _gaze(position: np.ndarray, present: np.ndarray, fps: float, height: np.ndarray) -> np.ndarray:
    """(t, n, 3) where each person will be ``GAZE_AHEAD_S`` later (their last frame, near the end), at eye
    height; NaN while that is nearer than ``GAZE_MIN_DISTANCE`` or they are absent."""
    t = len(position)
    k = np.arange(t)[:, None]
    last = np.where(present, k, -1).max(axis=0)
    later = np.minimum(k + int(round(GAZE_AHEAD_S * fps)), np.maximum(last, 0)[None, :])
    target = np.take_along_axis(position, np.broadcast_to(later, present.shape)[..., None], axis=0).copy()
    far = np.linalg.norm(target[..., :2] - position[..., :2], axis=2) >= GAZE_MIN_DISTANCE
    target[..., 2] += EYE_SHARE * height[None, :]
    return np.where((far & present)[..., None], target, np.nan)


def chunks(frames: model.CrowdFrames, size: int):
    """``frames`` as consecutive chunks of at most ``size`` frames."""
    for a in range(0, len(frames.times), size):
        yield frames.frames(slice(a, a + size))
