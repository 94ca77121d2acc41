"""Toric space (Lino and Christie 2015; seed 002, section 4.1 and appendix C): two-target camera framing.

Conventions
-----------
Screen positions ``p = (x, y)`` are normalised device coordinates: x from
-1 (left edge) to 1 (right edge), y from -1 (bottom) to 1 (top), the centre
at (0, 0). The field of view ``fov_x`` is horizontal, in radians, and
``aspect`` is width / height, so the top edge is at ``tan(fov_x / 2) / aspect``.
Cameras look down their -Z axis with +Y up (USD), and poses are row-vector
camera-to-world matrices whose rows are right, up, back and the eye
(:func:`usdcrowd.view.look_at`).

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


def screen_ray(p, fov_x: float, aspect: float) -> np.ndarray:
    """(3,) unit camera-space direction through screen position ``p`` (see the module's conventions)."""
    x, y = (float(v) for v in p)
    t = np.tan(0.5 * float(fov_x))
    d = np.array([x * t, y * t / float(aspect), -1.0])
    return d / np.linalg.norm(d)


def framing_angle(p_a, p_b, fov_x: float, aspect: float) -> float:
    """The angle alpha between the rays through ``p_a`` and ``p_b``, radians."""
    a, b = screen_ray(p_a, fov_x, aspect), screen_ray(p_b, fov_x, aspect)
    return float(np.arctan2(np.linalg.norm(np.cross(a, b)), np.dot(a, b)))


def _axes(a: np.ndarray, b: np.ndarray, up: np.ndarray):
    """x along AB, y = up x AB (horizontal), z the up direction made orthogonal to AB; and |AB|."""
    ab = b - a
    d = float(np.linalg.norm(ab))
    if not np.isfinite(d) or d < MIN_TARGET_DISTANCE:
        raise ToricError(f"targets {d:.3g} m apart: toric coordinates need two distinct targets")
    x = ab / d
    u = up / np.linalg.norm(up)
    if abs(float(np.dot(x, u))) > MAX_VERTICAL_COS:
        raise ToricError("the targets are one above the other: phi is undefined for a vertical AB")
    z = u - np.dot(u, x) * x
    z /= np.linalg.norm(z)
    y = np.cross(z, x)
    return x, y, z, d


def _frame(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(3, 3) orthonormal basis (as columns) from u and the part of v orthogonal to it."""
    e1 = u / np.linalg.norm(u)
    e2 = v - np.dot(v, e1) * e1
    e2 /= np.linalg.norm(e2)
    return np.stack([e1, e2, np.cross(e1, e2)], axis=1)


def toric_to_pose(a, b, p_a, p_b, theta: float, phi: float, fov_x: float, aspect: float,
                  up=_Z_UP) -> np.ndarray:
    """The camera that frames targets ``a`` and ``b`` at ``p_a`` and ``p_b`` from toric angles (theta, phi).

    Parameters
    ----------
    a, b : (3,) float
        Target positions, metres.
    p_a, p_b : (2,) float
        Where they appear on screen (normalised device coordinates).
    theta, phi : float
        Toric angles, radians (module conventions).
    fov_x, aspect : float
        Horizontal field of view (radians) and width / height.
    up : (3,) float
        World up.

    Returns
    -------
    (4, 4) float64
        Row-vector camera-to-world matrix.

    Raises
    ------
    ToricError
        Targets too close together or one above the other, screen positions
        too close together, or theta outside (0, 2 (pi - alpha)).
    """
    a, b, up = (np.asarray(v, dtype=np.float64) for v in (a, b, up))
    alpha = framing_angle(p_a, p_b, fov_x, aspect)
    if alpha < MIN_ALPHA:
        raise ToricError(f"screen positions {tuple(p_a)} and {tuple(p_b)} coincide: no angle between the targets")
    beta = 0.5 * float(theta)
    if not 0.0 < beta < np.pi - alpha:
        raise ToricError(f"theta {theta:.6g} is outside (0, {2 * (np.pi - alpha):.6g}) for these screen positions")
    x, y, z, d = _axes(a, b, up)
    # Law of sines in ABC: the angle at C is alpha, at A beta, at B pi - alpha - beta.
    ac = d * np.sin(alpha + beta) / np.sin(alpha)
    direction = np.cos(beta) * x + np.sin(beta) * (np.cos(phi) * y + np.sin(phi) * z)
    eye = a + ac * direction
    # The rotation taking the camera-space rays onto the world directions of A and B.
    cam = _frame(screen_ray(p_a, fov_x, aspect), screen_ray(p_b, fov_x, aspect))
    world = _frame(a - eye, b - eye)
    rot = world @ cam.T                      # column vectors: world = rot @ camera
    m = np.eye(4)
    m[:3, :3] = rot.T                        # row-vector convention: rows are the camera axes in world
    m[3, :3] = eye
    return m


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
    x, y, z, _ = _axes(a, b, up)
    ac = eye - a
    beta = float(np.arctan2(np.linalg.norm(np.cross(x, ac)), np.dot(x, ac)))
    phi = float(np.arctan2(np.dot(ac, z), np.dot(ac, y)))
    return screen[0], screen[1], 2.0 * beta, phi
