"""Toric space (Lino and Christie 2015; seed 002, section 4.1 and appendix C): two-target camera framing.

Conventions
-----------
Screen positions ``p = (x, y)`` are normalised device coordinates: x from
-1 (left edge) to 1 (right edge), y from -1 (bottom) to 1 (top), the centre
at (0, 0). The field of view ``fov_x`` is horizontal, in radians, and
``aspect`` is width / height, so the top edge is at ``tan(fov_x / 2) / aspect``.
Cameras look down their -Z axis with +Y up (USD), and poses are row-vector
camera-to-world matrices whose rows are right, up, back and the eye
(:func:`usdcrowd.core.view.look_at`).

Two screen positions fix the angle ``alpha`` between the rays to the two
targets A and B; every camera that sees A and B under that angle lies on a
spindle torus around AB, parametrised by two angles:

- ``theta`` in (0, 2 (pi - alpha)): twice the angle at A between AB and
  AC (C the camera). Small theta puts the camera near the line AB beyond B
  looking back at A over B's shoulder; large theta, over A's shoulder.
- ``phi`` in (-pi, pi]: the turn of the plane (A, B, C) about AB. 0 puts
  the camera level with AB on the side of ``up x AB``; positive phi
  raises it (it looks down on the pair); pi / 2 is straight above the
  line AB.

Given (pA, pB, theta, phi) the camera position follows from the law of
sines in triangle ABC, and its orientation is the one rotation that maps
the two camera-space rays onto the two world directions to A and B: both
targets land exactly on pA and pB (no roll is free).
"""

from __future__ import annotations

import numpy as np

_Z_UP = np.array([0.0, 0.0, 1.0])
# Below these the problem has no well-defined answer.
MIN_TARGET_DISTANCE = 1e-6      # metres between A and B
MIN_ALPHA = 1e-6                # radians between the two screen rays
MAX_VERTICAL_COS = 1.0 - 1e-9   # |cos| between AB and up: AB vertical leaves phi undefined


class ToricError(ValueError):
    """A configuration no camera can meet, or for which toric coordinates are undefined."""


def screen_rays(p, fov_x: float, aspect: float) -> np.ndarray:
    """(..., 3) unit camera-space directions through screen positions ``p`` (..., 2) (module conventions)."""
    p = np.asarray(p, dtype=np.float64)
    t = np.tan(0.5 * float(fov_x))
    d = np.stack([p[..., 0] * t, p[..., 1] * t / float(aspect), -np.ones(p.shape[:-1])], -1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def screen_ray(p, fov_x: float, aspect: float) -> np.ndarray:
    """(3,) unit camera-space direction through screen position ``p`` (see the module's conventions)."""
    return screen_rays(np.asarray(p, dtype=np.float64).reshape(2), fov_x, aspect)


def _angle(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Angle between vectors along the last axis, radians (atan2: exact near 0 and pi)."""
    return np.arctan2(np.linalg.norm(np.cross(u, v), axis=-1), np.einsum("...i,...i->...", u, v))


def framing_angle(p_a, p_b, fov_x: float, aspect: float):
    """The angle alpha between the rays through ``p_a`` and ``p_b``, radians (float, or (t,) for (t, 2) inputs)."""
    alpha = _angle(screen_rays(p_a, fov_x, aspect), screen_rays(p_b, fov_x, aspect))
    return float(alpha) if np.ndim(alpha) == 0 else alpha


def axes(a: np.ndarray, b: np.ndarray, up: np.ndarray):
    """The toric frame of targets ``a`` and ``b`` ((t, 3)): (t, 3) x along AB, y = up x AB (horizontal),
    z the up direction made orthogonal to AB; (t,) |AB|.

    Raises
    ------
    ToricError
        Targets too close together, or one above the other.
    """
    ab = b - a
    d = np.linalg.norm(ab, axis=-1)
    bad = ~np.isfinite(d) | (d < MIN_TARGET_DISTANCE)
    if bad.any():
        k = int(np.argmax(bad))
        raise ToricError(f"targets {d[k]:.3g} m apart{_at(k, len(d))}: toric coordinates need two distinct targets")
    x = ab / d[:, None]
    u = up / np.linalg.norm(up)
    vertical = np.abs(x @ u) > MAX_VERTICAL_COS
    if vertical.any():
        raise ToricError(f"the targets are one above the other{_at(int(np.argmax(vertical)), len(d))}: "
                         "phi is undefined for a vertical AB")
    z = u - (x @ u)[:, None] * x
    z /= np.linalg.norm(z, axis=-1, keepdims=True)
    y = np.cross(z, x)
    return x, y, z, d


def _at(k: int, n: int) -> str:
    return f" (frame index {k})" if n > 1 else ""


def _frames(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(t, 3, 3) orthonormal bases (as columns) from u and the part of v orthogonal to it."""
    e1 = u / np.linalg.norm(u, axis=-1, keepdims=True)
    e2 = v - np.einsum("ti,ti->t", v, e1)[:, None] * e1
    e2 /= np.linalg.norm(e2, axis=-1, keepdims=True)
    return np.stack([e1, e2, np.cross(e1, e2)], axis=-1)


def toric_to_poses(a, b, p_a, p_b, theta, phi, fov_x: float, aspect: float, up=_Z_UP) -> np.ndarray:
    """The cameras that frame targets ``a`` and ``b`` at ``p_a`` and ``p_b`` from toric angles (theta, phi).

    Vectorised over frames: one camera per row.

    Parameters
    ----------
    a, b : (t, 3) float
        Target positions, metres.
    p_a, p_b : (t, 2) float
        Where they appear on screen (normalised device coordinates).
    theta, phi : (t,) float
        Toric angles, radians (module conventions).
    fov_x, aspect : float
        Horizontal field of view (radians) and width / height.
    up : (3,) float
        World up.

    Returns
    -------
    (t, 4, 4) float64
        Row-vector camera-to-world matrices.

    Raises
    ------
    ToricError
        Targets too close together or one above the other, screen positions
        too close together, or theta outside (0, 2 (pi - alpha)); the
        message names the first frame at fault.
    """
    a, b = (np.atleast_2d(np.asarray(v, dtype=np.float64)) for v in (a, b))
    n = len(a)
    p_a, p_b = (np.broadcast_to(np.asarray(v, dtype=np.float64), (n, 2)) for v in (p_a, p_b))
    theta, phi = (np.broadcast_to(np.asarray(v, dtype=np.float64), (n,)) for v in (theta, phi))
    up = np.asarray(up, dtype=np.float64)
    ray_a, ray_b = screen_rays(p_a, fov_x, aspect), screen_rays(p_b, fov_x, aspect)
    alpha = _angle(ray_a, ray_b)
    close = ~(alpha >= MIN_ALPHA)
    if close.any():
        k = int(np.argmax(close))
        raise ToricError(f"screen positions {tuple(p_a[k])} and {tuple(p_b[k])} coincide{_at(k, n)}: "
                         "no angle between the targets")
    beta = 0.5 * theta
    outside = ~((beta > 0.0) & (beta < np.pi - alpha))
    if outside.any():
        k = int(np.argmax(outside))
        raise ToricError(f"theta {theta[k]:.6g} is outside (0, {2 * (np.pi - alpha[k]):.6g}) for these screen "
                         f"positions{_at(k, n)}")
    x, y, z, d = axes(a, b, up)
    # Law of sines in ABC: the angle at C is alpha, at A beta, at B pi - alpha - beta.
    ac = d * np.sin(alpha + beta) / np.sin(alpha)
    direction = (np.cos(beta)[:, None] * x
                 + np.sin(beta)[:, None] * (np.cos(phi)[:, None] * y + np.sin(phi)[:, None] * z))
    eye = a + ac[:, None] * direction
    # The rotation taking the camera-space rays onto the world directions of A and B.
    cam = _frames(ray_a, ray_b)
    world = _frames(a - eye, b - eye)
    m = np.zeros((n, 4, 4))
    m[:, :3, :3] = cam @ np.swapaxes(world, 1, 2)     # row vectors: rows are the camera axes in world
    m[:, 3, :3] = eye
    m[:, 3, 3] = 1.0
    return m


def toric_to_pose(a, b, p_a, p_b, theta: float, phi: float, fov_x: float, aspect: float,
                  up=_Z_UP) -> np.ndarray:
    """One camera of :func:`toric_to_poses`: (3,) targets, (2,) screen positions, scalar angles -> (4, 4)."""
    return toric_to_poses(np.reshape(a, (1, 3)), np.reshape(b, (1, 3)), np.reshape(p_a, (1, 2)),
                          np.reshape(p_b, (1, 2)), [theta], [phi], fov_x, aspect, up)[0]


def pose_to_toric(cam_to_world, a, b, fov_x: float, aspect: float, up=_Z_UP):
    """Toric coordinates (p_a, p_b, theta, phi) of a camera framing targets ``a`` and ``b``.

    The inverse of :func:`toric_to_pose` for the same field of view, aspect and up.

    Raises
    ------
    ToricError
        A target behind the camera, targets too close together or one above the other.
    """
    m = np.asarray(cam_to_world, dtype=np.float64)
    a, b, up = (np.asarray(v, dtype=np.float64) for v in (a, b, up))
    eye, rot = m[3, :3], m[:3, :3]
    t = np.tan(0.5 * float(fov_x))
    screen = []
    for target in (a, b):
        c = (target - eye) @ rot.T           # camera space (rows of rot are the camera axes)
        if c[2] >= 0:
            raise ToricError("a target is behind the camera: no screen position")
        screen.append(np.array([c[0] / (-c[2] * t), c[1] * float(aspect) / (-c[2] * t)]))
    x, y, z, _ = axes(a[None], b[None], up)
    beta, phi = angles_at_a((eye - a)[None], x, y, z)
    return screen[0], screen[1], 2.0 * float(beta[0]), float(phi[0])


def angles_at_a(ac: np.ndarray, x: np.ndarray, y: np.ndarray, z: np.ndarray):
    """(t,) beta, the angle at A between AB and A-to-camera ``ac`` ((t, 3)), and phi, its turn about AB,
    radians, in the toric frame ``x, y, z`` of :func:`axes` (theta is 2 beta)."""
    return _angle(x, ac), np.arctan2(np.einsum("ti,ti->t", ac, z), np.einsum("ti,ti->t", ac, y))
