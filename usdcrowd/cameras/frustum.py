"""What a camera sees: points in frusta, and seed 000's 2D frustum intersection.

Every test is vectorised over (camera, thing) pairs that a spatial index
proposed, so the cost follows what is near, not cameras times characters.
"""

from __future__ import annotations

import numpy as np


def half_tangents(focal_length, horizontal_aperture, vertical_aperture, aspect: float | None = None):
    """tan of the half fields of view (x, y), each (...) float64.

    With ``aspect`` (width / height of the image), the vertical one follows
    the image as the renderers do (the horizontal aperture fills the width).
    """
    tx = 0.5 * np.asarray(horizontal_aperture, dtype=np.float64) / np.asarray(focal_length, dtype=np.float64)
    ty = (tx / aspect) if aspect else 0.5 * np.asarray(vertical_aperture, dtype=np.float64) / np.asarray(
        focal_length, dtype=np.float64)
    return tx, ty


def points_in_frustum(points: np.ndarray, position: np.ndarray, forward: np.ndarray, right: np.ndarray,
                      up: np.ndarray, tan_x, tan_y, near, far) -> tuple[np.ndarray, np.ndarray]:
    """Which points each paired camera sees, and how far they are.

    Parameters
    ----------
    points : (m, 3) float
        World points, one per pair.
    position, forward, right, up : (m, 3) float
        The paired camera's centre and unit axes.
    tan_x, tan_y, near, far : (m,) float or scalars
        Half-angle tangents and depth range (metres).

    Returns
    -------
    inside : (m,) bool
    distance : (m,) float64
        Euclidean distance to the camera centre, metres.
    """
    d = np.asarray(points, dtype=np.float64) - position
    z = np.einsum("ij,ij->i", d, forward)
    x = np.einsum("ij,ij->i", d, right)
    y = np.einsum("ij,ij->i", d, up)
    inside = (z > near) & (z < far) & (np.abs(x) <= tan_x * z) & (np.abs(y) <= tan_y * z)
    return inside, np.linalg.norm(d, axis=1)


def _ray_hits(p0, d0, p1, d1):
    """Intersections of 2D rays p0 + s d0 and p1 + t d1 (arrays (m, 2)); NaN where parallel or behind."""
    cross = d0[:, 0] * d1[:, 1] - d0[:, 1] * d1[:, 0]
    w = p1 - p0
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (w[:, 0] * d1[:, 1] - w[:, 1] * d1[:, 0]) / cross
        t = (w[:, 0] * d0[:, 1] - w[:, 1] * d0[:, 0]) / cross
    ok = (np.abs(cross) > 1e-9) & (s >= 0) & (t >= 0)
    hit = p0 + s[:, None] * d0
    return np.where(ok[:, None], hit, np.nan)


def frustums_intersect_2d(pc: np.ndarray, fc: np.ndarray, half_c, pi: np.ndarray, fi: np.ndarray, half_i,
                          near, far) -> np.ndarray:
    """Seed 000's frustum collision test (Figure 9), seen from above.

    Each frustum is its two side rays (left and right edges of the horizontal
    field of view). The four crossings of c's sides with i's sides are
    projected on both forward vectors; the frusta collide when, for one
    crossing, both projections lie between the near and far distances.

    Parameters
    ----------
    pc, pi : (m, 2) float
        Camera centres seen from above (x, y).
    fc, fi : (m, 2) float
        Unit horizontal forward vectors.
    half_c, half_i : (m,) float
        Horizontal half fields of view, radians.
    near, far : float or (m,) float
        Depth range in which a shared view counts, metres.

    Returns
    -------
    (m,) bool
    """
    def sides(f, half):
        c, s = np.cos(half), np.sin(half)
        left = np.stack([c * f[:, 0] - s * f[:, 1], s * f[:, 0] + c * f[:, 1]], 1)
        right = np.stack([c * f[:, 0] + s * f[:, 1], -s * f[:, 0] + c * f[:, 1]], 1)
        return left, right

    out = np.zeros(len(pc), dtype=bool)
    for dc in sides(fc, np.asarray(half_c, dtype=np.float64)):
        for di in sides(fi, np.asarray(half_i, dtype=np.float64)):
            hit = _ray_hits(pc, dc, pi, di)
            zc = np.einsum("ij,ij->i", hit - pc, fc)
            zi = np.einsum("ij,ij->i", hit - pi, fi)
            with np.errstate(invalid="ignore"):
                out |= (zc > near) & (zc < far) & (zi > near) & (zi < far)
    return out
