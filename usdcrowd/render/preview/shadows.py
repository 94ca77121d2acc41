"""The sun's shadow map: where to put it and how big.

One orthographic depth map from the stage's first DistantLight, refitted
every frame to the part of the scene the camera can see (the view frustum,
clipped to a shadow distance, intersected with the box holding scenery and
characters), so its texels are spent where they show. Characters are
essential shadow casters (seed 003), drawn into it at their level of detail.
"""

from __future__ import annotations

import numpy as np

from ...core.view import look_at


def light_basis(sun_dir: np.ndarray) -> np.ndarray:
    """(3, 3) rows right, up, towards-sun of the light's frame (orthonormal)."""
    d = np.asarray(sun_dir, dtype=np.float64)
    d = d / np.linalg.norm(d)
    # A camera looking from the sun (down -d); near-vertical suns keep +Y up.
    helper = (0.0, 0.0, 1.0) if abs(d[2]) < 0.95 else (0.0, 1.0, 0.0)
    return look_at(np.zeros(3), -d, up=helper)[0, :3, :3]


def box_corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(8, 3) corners of an axis-aligned box."""
    idx = np.array([[i >> 0 & 1, i >> 1 & 1, i >> 2 & 1] for i in range(8)], dtype=bool)
    return np.where(idx, hi, lo)


def frustum_corners(cam_to_world: np.ndarray, focal_px: float, width: int, height: int,
                    near: float, far: float) -> np.ndarray:
    """(8, 3) world corners of a pinhole frustum between ``near`` and ``far``."""
    hx, hy = width / 2.0 / focal_px, height / 2.0 / focal_px
    pts = [(sx * hx * d, sy * hy * d, -d) for d in (near, far) for sx in (-1, 1) for sy in (-1, 1)]
    p = np.array(pts)
    return p @ cam_to_world[:3, :3] + cam_to_world[3, :3]


def fit_light_matrix(sun_dir: np.ndarray, scene_lo: np.ndarray, scene_hi: np.ndarray,
                     view_corners: np.ndarray | None, size: int):
    """Row-vector world-to-clip matrix of the sun's orthographic shadow map.

    Parameters
    ----------
    sun_dir : (3,) float
        Unit direction towards the sun.
    scene_lo, scene_hi : (3,) float
        Box of every shadow caster and receiver.
    view_corners : (k, 3) float or None
        Corners of the region the camera sees; the map covers its overlap
        with the scene box (None: the whole box).
    size : int
        Texels along a side.

    Returns
    -------
    matrix : (4, 4) float64
        ``clip = [p, 1] @ matrix``; depth -1 nearest the sun.
    texel : float
        World size of one texel, metres.
    """
    basis = light_basis(sun_dir)
    scene = box_corners(scene_lo, scene_hi) @ basis.T
    lo, hi = scene.min(0), scene.max(0)
    if view_corners is not None:
        v = np.asarray(view_corners) @ basis.T
        lo[:2] = np.maximum(lo[:2], v[:, :2].min(0))
        hi[:2] = np.minimum(hi[:2], v[:, :2].max(0))
        bad = hi[:2] <= lo[:2]           # the camera sees none of the scene box
        lo[:2] = np.where(bad, scene[:, :2].min(0), lo[:2])
        hi[:2] = np.where(bad, scene[:, :2].max(0), hi[:2])
    # Square texels: the larger side sets the resolution; a margin keeps
    # edge filtering inside the map.
    span = float(max(hi[0] - lo[0], hi[1] - lo[1])) * 1.02 + 1e-3
    centre = 0.5 * (lo + hi)
    depth = float(hi[2] - lo[2]) + 2.0
    m = np.zeros((4, 4))
    m[:3, 0] = basis[0] * (2.0 / span)
    m[:3, 1] = basis[1] * (2.0 / span)
    m[:3, 2] = -basis[2] * (2.0 / depth)         # towards the sun = nearer = smaller depth
    m[3, 0] = -centre[0] * 2.0 / span
    m[3, 1] = -centre[1] * 2.0 / span
    m[3, 2] = (centre[2]) * 2.0 / depth
    m[3, 3] = 1.0
    return m, span / size


def pixel_footprint(centres: np.ndarray, world_to_cam: np.ndarray, focal_px: float,
                    quantile: float = 0.05) -> float | None:
    """Metres one screen pixel spans at the nearer characters (a low depth quantile), or None.

    Parameters
    ----------
    centres : (n, 3) float
        World positions of the drawn characters.
    world_to_cam : (4, 4) float
        Row-vector view matrix.
    focal_px : float
    """
    if len(centres) == 0:
        return None
    z = -(np.asarray(centres) @ world_to_cam[:3, 2] + world_to_cam[3, 2])
    z = z[z > 1e-3]
    return float(np.quantile(z, quantile)) / focal_px if len(z) else None


# Screen pixels a shadow-map texel spans at the nearer characters. The map's
# bilinear comparison already blurs an edge over two texels, and a software
# rasteriser pays for every texel a crowd covers in the map: two pixels a
# texel quarter that cost (half the frame in a dense crowd) for an edge
# softened by one pixel more.
TEXEL_PIXELS = 2.0


def used_size(span: float, footprint: float | None, size: int, step: int = 128, least: int = 512,
              texel_pixels: float = TEXEL_PIXELS) -> int:
    """Texels per side to render: one per ``texel_pixels`` screen pixels at ``footprint``, in ``step``s, at most ``size``."""
    if footprint is None or footprint <= 0:
        return size
    want = int(np.ceil(span / (footprint * texel_pixels) / step)) * step
    return int(min(size, max(least, want)))
