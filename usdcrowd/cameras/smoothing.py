"""Camera track smoothing of seed 002, section 7.2: a 20-frame moving average, 3 passes, on position and orientation.

Toric coordinates are local to the two heads, so a camera that follows them
inherits every jitter of their motion; the paper smooths the final tracks
with a sliding average of 20 frames repeated 3 times (close to a Gaussian of
sigma about 10 frames). Orientation is averaged as yaw, pitch and roll,
unwrapped over time first so that a turn through +-180 degrees is not
averaged into a spin the other way.
"""

from __future__ import annotations

import numpy as np

WINDOW = 20
PASSES = 3


def moving_average(x: np.ndarray, window: int) -> np.ndarray:
    """Centred moving average along axis 0; the ends are padded by reflection (no pull toward zero)."""
    if window <= 1 or len(x) < 2:
        return x
    half = window // 2
    pad = np.pad(x, [(half, window - 1 - half)] + [(0, 0)] * (x.ndim - 1),
                 mode="reflect" if len(x) > half + 1 else "edge")
    kernel = np.ones(window) / window
    return np.apply_along_axis(lambda c: np.convolve(c, kernel, mode="valid"), 0, pad)


def _yaw_pitch_roll(rot: np.ndarray) -> np.ndarray:
    """(t, 3) yaw, pitch, roll of camera-to-world rotations (row vectors: right, up, back)."""
    back = rot[:, 2]
    forward = -back
    yaw = np.arctan2(forward[:, 1], forward[:, 0])
    pitch = np.arcsin(np.clip(forward[:, 2], -1.0, 1.0))
    # Roll: the camera's right axis against the level right axis for this yaw.
    level_right = np.stack([np.sin(yaw), -np.cos(yaw), np.zeros_like(yaw)], -1)
    level_up = np.cross(level_right, forward)
    right = rot[:, 0]
    roll = np.arctan2(np.einsum("ij,ij->i", right, level_up), np.einsum("ij,ij->i", right, level_right))
    return np.stack([yaw, pitch, roll], -1)


def rotation_from_ypr(ypr: np.ndarray) -> np.ndarray:
    """Inverse of :func:`_yaw_pitch_roll`: (t, 3, 3) rows right, up, back."""
    yaw, pitch, roll = ypr.T
    forward = np.stack([np.cos(pitch) * np.cos(yaw), np.cos(pitch) * np.sin(yaw), np.sin(pitch)], -1)
    level_right = np.stack([np.sin(yaw), -np.cos(yaw), np.zeros_like(yaw)], -1)
    level_up = np.cross(level_right, forward)
    right = np.cos(roll)[:, None] * level_right + np.sin(roll)[:, None] * level_up
    up = np.cross(right, forward)
    return np.stack([right, up, -forward], 1)


def smooth_track(cam_to_world: np.ndarray, window: int = WINDOW, passes: int = PASSES) -> np.ndarray:
    """Smoothed copy of a camera track.

    Parameters
    ----------
    cam_to_world : (t, 4, 4) float
        Row-vector camera-to-world matrices (rows right, up, back, eye).
    window : int
        Frames averaged (20 in the paper).
    passes : int
        Times the average is applied (3 in the paper).

    Returns
    -------
    (t, 4, 4) float64
        Rigid transforms again (orthonormal rotations).
    """
    m = np.array(cam_to_world, dtype=np.float64)
    eye = m[:, 3, :3]
    ypr = _yaw_pitch_roll(m[:, :3, :3])
    ypr = np.unwrap(ypr, axis=0)            # a turn through +-pi stays a turn
    for _ in range(passes):
        eye = moving_average(eye, window)
        ypr = moving_average(ypr, window)
    out = np.zeros_like(m)
    out[:, :3, :3] = rotation_from_ypr(ypr)
    out[:, 3, :3] = eye
    out[:, 3, 3] = 1.0
    return out
