"""Camera orientations as unit quaternions, and the maps to and from matrices.

A camera's orientation ``q`` (w, x, y, z) rotates its local axes into the
world: with USD's row-vector convention, ``quat_to_matrix(q)`` has the
camera's right, up and back (-forward) axes as rows, which are the first
three rows of its camera-to-world matrix. Cameras look down local -Z.

Angular velocities are rotation vectors in the world frame (axis times
radians per second): a step ``q <- exp(w dt) q`` is the quaternion product of
seed 000's Algorithm 2 for one time step.
"""

from __future__ import annotations

import numpy as np

from ..character.rig import quat_conjugate, quat_multiply, quat_to_matrix

_UP = np.array([0.0, 0.0, 1.0])


def matrix_to_quat(m: np.ndarray) -> np.ndarray:
    """Unit quaternions of row-vector rotation matrices.

    Parameters
    ----------
    m : (..., 3, 3) float
        Orthonormal, row-vector convention (``v' = v @ m``).

    Returns
    -------
    (..., 4) float64
        (w, x, y, z) with w >= 0.
    """
    from scipy.spatial.transform import Rotation

    m = np.asarray(m, dtype=np.float64)
    # scipy takes column-convention matrices and returns (x, y, z, w).
    xyzw = Rotation.from_matrix(np.swapaxes(m, -1, -2).reshape(-1, 3, 3)).as_quat()
    q = np.roll(xyzw, 1, axis=-1).reshape(m.shape[:-2] + (4,))
    return q * np.where(q[..., :1] < 0, -1.0, 1.0)


def axes(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World forward, right and up vectors of cameras with orientations ``q`` (..., 4)."""
    r = quat_to_matrix(q)
    return -r[..., 2, :], r[..., 0, :], r[..., 1, :]


def level_from_forward(forward: np.ndarray) -> np.ndarray:
    """(..., 4) roll-free orientations looking along ``forward`` (..., 3).

    The camera's right axis stays horizontal (a camera on a tripod or crane
    head pans and tilts, it does not roll). Straight-down views keep +Y up.
    """
    from ..core.view import look_at

    f = np.asarray(forward, dtype=np.float64)
    flat = f.reshape(-1, 3)
    m = look_at(np.zeros_like(flat), flat)
    return matrix_to_quat(m[:, :3, :3]).reshape(f.shape[:-1] + (4,))


def relevel(q: np.ndarray) -> np.ndarray:
    """Remove the roll that integrating torques leaves behind, keeping the forward axis."""
    return level_from_forward(axes(q)[0])


def rotation_to(q_from: np.ndarray, q_to: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World-frame rotation taking ``q_from`` to ``q_to`` as (angle, axis).

    This is seed 000's quaternion difference ``q_d q_c^-1`` of Algorithm 5.

    Returns
    -------
    angle : (...) float64
        Radians in [0, pi].
    axis : (...) 3 float64
        Unit axes (+Z where the angle is 0).
    """
    d = quat_multiply(q_to, quat_conjugate(q_from))
    d = d * np.where(d[..., :1] < 0, -1.0, 1.0)             # the shorter way round
    s = np.linalg.norm(d[..., 1:], axis=-1)
    angle = 2.0 * np.arctan2(s, np.clip(d[..., 0], -1.0, 1.0))
    axis = np.where(s[..., None] > 1e-12, d[..., 1:] / np.maximum(s, 1e-12)[..., None], _UP)
    return angle, axis


def integrate(q: np.ndarray, omega: np.ndarray, dt: float) -> np.ndarray:
    """Turn orientations ``q`` (..., 4) by world angular velocities ``omega`` (..., 3) for ``dt`` seconds."""
    rate = np.linalg.norm(omega, axis=-1)
    angle = rate * dt
    axis = np.where(rate[..., None] > 1e-12, omega / np.maximum(rate, 1e-12)[..., None], _UP)
    half = 0.5 * angle
    step = np.concatenate([np.cos(half)[..., None], np.sin(half)[..., None] * axis], -1)
    out = quat_multiply(step, q)
    return out / np.linalg.norm(out, axis=-1, keepdims=True)
