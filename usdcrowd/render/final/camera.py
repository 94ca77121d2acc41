"""UsdGeom.Camera as a Mitsuba sensor, and the exact per-pixel rays of the ground-truth passes.

Both follow :meth:`CameraView.intrinsics`: the horizontal aperture fills the
image width, pixels are square, the principal point is the image centre and
pixel centres sit at +0.5. A point that ``CameraView.project`` puts at pixel
(u, v) is where the beauty image shows it, and where the ground-truth ray of
pixel (floor(u), floor(v)) looks when u, v are pixel centres.

Axes: USD cameras look down local -Z with +Y up and +X right; Mitsuba's
perspective sensor looks down local +Z with +Y up, so its +X points left.
The two frames differ by a half turn about Y: ``diag(-1, 1, -1)``.
"""

from __future__ import annotations

import numpy as np

from ...core.view import CameraView, camera_record

# Mitsuba camera space -> USD camera space (row vectors): x and z flip.
_MITSUBA_TO_USD = np.diag([-1.0, 1.0, -1.0, 1.0])


def sensor_to_world(cam: CameraView) -> np.ndarray:
    """(4, 4) float64 Mitsuba sensor-to-world matrix, *column-vector* convention (``mi.Transform4f``)."""
    return (_MITSUBA_TO_USD @ cam.cam_to_world).T



def sensor_dict(cam: CameraView, width: int, height: int, spp: int, rfilter: str = "box",
                sampler: str = "independent") -> dict:
    """Mitsuba ``perspective`` sensor for ``cam`` on a ``width`` x ``height`` linear RGB film.

    Parameters
    ----------
    cam : CameraView
    width, height : int
        Image size in pixels.
    spp : int
        Samples per pixel of the beauty pass.
    rfilter : str
        Reconstruction filter of the beauty film ("box", "gaussian", ...). Box
        by default: each sample lands in its own pixel, so a pixel's samples
        are summed by one thread in one order and the same command gives the
        same bytes (a Gaussian filter's overlapping footprints are summed by
        whichever threads get there first: 10-15 % of pixels differed in
        their last bits between identical runs); its noise is also
        uncorrelated between pixels, which a denoiser needs, and it renders
        about a quarter faster.
    sampler : str
        Mitsuba sampler of the beauty (one of SAMPLERS).

    A camera with depth of field (``cam.depth_of_field``) becomes Mitsuba's
    ``thinlens``: aperture radius focal length / (2 fStop), focused at
    focusDistance. Only the beauty: the ground-truth passes stay pinhole
    (exact at the pixel centres).
    """
    import mitsuba as mi

    lens = {"type": "perspective"}
    if cam.depth_of_field:               # UsdGeom.Camera fStop and focusDistance: a thin lens
        lens = {"type": "thinlens", "aperture_radius": cam.aperture_radius, "focus_distance": cam.focus_distance}
    return {
        **lens,
        "fov": cam.fov_x(),
        "fov_axis": "x",
        "near_clip": max(cam.near, 1e-4),
        "far_clip": cam.far,
        "to_world": mi.ScalarTransform4f(sensor_to_world(cam).tolist()),
        "sampler": {"type": sampler, "sample_count": int(spp)},
        "film": {"type": "hdrfilm", "width": int(width), "height": int(height), "pixel_format": "rgb",
                 "rfilter": {"type": rfilter}},
    }


def pixel_rays(cam: CameraView, width: int, height: int):
    """One ray per pixel centre, clipped like the sensor (near/far are planes, not spheres).

    Returns
    -------
    origin : (h*w, 3) float64
        Where each ray crosses the near plane, world metres.
    direction : (h*w, 3) float64
        Unit directions, row-major pixel order (row 0 at the top).
    length : (h*w,) float64
        Distance from the near plane to the far plane along each ray.
    start : (h*w,) float64
        Distance from the camera centre to ``origin``.
    cos_axis : (h*w,) float64
        Cosine between each ray and the view axis: ``z = distance * cos_axis``.
    """
    k = cam.intrinsics(width, height)
    u = np.arange(width, dtype=np.float64) + 0.5
    v = np.arange(height, dtype=np.float64) + 0.5
    uu, vv = np.meshgrid(u, v)
    # USD camera space: x right, y up, looking down -z (z = -1 on the unit plane).
    d_cam = np.stack([(uu - k[0, 2]) / k[0, 0], -(vv - k[1, 2]) / k[1, 1], -np.ones_like(uu)], -1).reshape(-1, 3)
    scale = np.linalg.norm(d_cam, axis=1)
    d_world = d_cam @ cam.cam_to_world[:3, :3]
    direction = d_world / np.linalg.norm(d_world, axis=1, keepdims=True)
    near = max(cam.near, 1e-4)
    origin = cam.position + direction * (near * scale)[:, None]
    return origin, direction, (cam.far - near) * scale, near * scale, 1.0 / scale
