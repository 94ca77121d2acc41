"""Steering torques on camera orientations (seed 000, section 4.4).

A torque here is an angular acceleration in the world frame: the desired
rotational velocity minus the current one (the ``q_dot_d q_dot_c^-1`` of
Algorithms 5 and 6, written with rotation vectors), in rad/s.
"""

from __future__ import annotations

import numpy as np

from .frustum import frustums_intersect_2d
from .orientation import axes

_UP = np.array([0.0, 0.0, 1.0])


def aiming(q: np.ndarray, q_desired: np.ndarray, omega: np.ndarray, max_rate: np.ndarray,
           threshold: np.ndarray) -> np.ndarray:
    """Algorithm 5: turn toward ``q_desired`` at full rate, slowing inside ``threshold`` (arrival).

    The turn is a pan about the world's up axis and a tilt about the camera's
    right axis, as a camera head moves, not the shortest rotation between the
    two orientations: for a target behind a camera looking steeply down, the
    shortest rotation runs through the nadir, which the pitch limit forbids,
    and the camera would crawl along that limit instead of panning round.

    Parameters
    ----------
    q, q_desired : (c, 4) float
        Current and desired orientations (roll-free).
    omega : (c, 3) float
        Current rotational velocity, rad/s.
    max_rate, threshold : (c,) float
        alpha max (rad/s) and alpha t (rad).

    Returns
    -------
    (c, 3) float64
        T_aim.
    """
    fwd, right, _ = axes(q)
    goal = axes(q_desired)[0]
    pan = np.arctan2(goal[:, 1], goal[:, 0]) - np.arctan2(fwd[:, 1], fwd[:, 0])
    pan = (pan + np.pi) % (2.0 * np.pi) - np.pi
    tilt = np.arcsin(np.clip(goal[:, 2], -1.0, 1.0)) - np.arcsin(np.clip(fwd[:, 2], -1.0, 1.0))
    angle = np.hypot(pan, tilt)
    turn = pan[:, None] * _UP + tilt[:, None] * right
    axis = turn / np.maximum(angle, 1e-12)[:, None]
    rate = np.where(angle > threshold, max_rate, max_rate * angle / np.maximum(threshold, 1e-9))
    return axis * rate[:, None] - omega


def avoidance(position: np.ndarray, forward: np.ndarray, right: np.ndarray, half_fov: np.ndarray,
              omega: np.ndarray, max_rate: np.ndarray, pairs: np.ndarray, near: float, far: float) -> np.ndarray:
    """Algorithm 6: pan away from cameras whose frusta overlap this one's.

    Parameters
    ----------
    position, forward, right : (c, 3) float
    half_fov : (c,) float
        Horizontal half field of view, radians.
    pairs : (p, 2) int
        Candidate camera pairs from a KD-tree (each used both ways).
    near, far : float
        Depth range of the 2D frustum test, metres.

    Returns
    -------
    (c, 3) float64
        T_avoid, about the world's up axis (a pan: these cameras do not roll).
    """
    out = np.zeros_like(omega)
    if len(pairs) == 0:
        return out
    c = np.concatenate([pairs[:, 0], pairs[:, 1]])
    i = np.concatenate([pairs[:, 1], pairs[:, 0]])

    def flat(v):
        f = v[:, :2]
        return f / np.maximum(np.linalg.norm(f, axis=1, keepdims=True), 1e-9)

    hit = frustums_intersect_2d(position[c, :2], flat(forward[c]), half_fov[c],
                                position[i, :2], flat(forward[i]), half_fov[i], near, far)
    c, i = c[hit], i[hit]
    # Seed 000 was written in Unity (left-handed, clockwise-positive yaw): its
    # (-alpha, up) for a camera on the right is a turn to the left, away from
    # it. Here a positive rate about +Z turns left.
    on_right = np.einsum("ij,ij->i", position[i] - position[c], right[c]) > 0
    # One pan per camera, away from the side most overlapping cameras are on (summed per pair, three
    # overlapping cameras would turn one three times as hard, off its event).
    side = np.zeros(len(omega))
    np.add.at(side, c, np.where(on_right, 1.0, -1.0))
    hit = np.unique(c)
    out[hit] = np.sign(side[hit])[:, None] * max_rate[hit, None] * _UP - omega[hit]
    return out
