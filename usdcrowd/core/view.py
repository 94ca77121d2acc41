"""Cameras as numpy: a view with its lens, the look-at helper, annotation records.

Pure core (no ``pxr``, no renderer): :mod:`usdcrowd.render`,
:mod:`usdcrowd.groundtruth`, :mod:`usdcrowd.cameras` and :mod:`usdcrowd.usd`
share these. Matrices follow USD's row-vector convention (``p' = p @ M``,
translation in the last row); a camera looks down its local -Z with +Y up
and +X to the right, in canonical Z-up metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

_Z_UP = (0.0, 0.0, 1.0)


def look_at(eye, target, up=_Z_UP) -> np.ndarray:
    """Camera-to-world matrices of cameras at ``eye`` looking at ``target``.

    The camera's right axis is horizontal (perpendicular to ``up``): no roll.
    Where the view is parallel to ``up`` (straight down or up) the camera's
    +Y is the world +Y (or +X when ``up`` is along Y). Where ``eye`` equals
    ``target`` the camera looks along +X.

    Parameters
    ----------
    eye, target : (3,) or (t, 3) float
        Canonical metres; broadcast against each other.
    up : (3,) or (t, 3) float
        World up, +Z by default.

    Returns
    -------
    (t, 4, 4) float64
        Row-vector camera-to-world matrices (rows: right, up, back = -forward,
        eye); t = 1 for single points.
    """
    eye = np.atleast_2d(np.asarray(eye, dtype=np.float64))
    target = np.atleast_2d(np.asarray(target, dtype=np.float64))
    eye, target = np.broadcast_arrays(eye, target)
    up = np.broadcast_to(np.atleast_2d(np.asarray(up, dtype=np.float64)), eye.shape)
    up = up / np.linalg.norm(up, axis=-1, keepdims=True)
    forward = target - eye
    norm = np.linalg.norm(forward, axis=-1, keepdims=True)
    forward = np.where(norm > 0, forward / np.where(norm > 0, norm, 1.0), [1.0, 0.0, 0.0])
    right = np.cross(forward, up)
    rn = np.linalg.norm(right, axis=-1, keepdims=True)
    degenerate = rn[:, 0] < 1e-9
    if degenerate.any():
        # Looking along up: keep the world Y (or X) as the camera's up.
        cam_up = np.where(np.abs(up[degenerate, 1:2]) > 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
        right[degenerate] = np.cross(cam_up, -forward[degenerate])
        rn[degenerate] = np.linalg.norm(right[degenerate], axis=-1, keepdims=True)
    right = right / rn
    m = np.zeros((len(eye), 4, 4))
    m[:, 0, :3], m[:, 1, :3], m[:, 2, :3], m[:, 3, :3] = right, np.cross(right, forward), -forward, eye
    m[:, 3, 3] = 1.0
    return m


def mm_per_lens_unit(meters_per_unit: float) -> float:
    """Millimetres in one unit of UsdGeom.Camera's lens attributes on a stage of ``meters_per_unit``.

    USD gives ``focalLength``, ``horizontalAperture`` and ``verticalAperture``
    in tenths of a scene unit: millimetres on a centimetre stage, 0.1 m on a
    metre stage (a 35 mm lens is 0.35 there, as Blender writes it). usdcrowd
    keeps lenses in millimetres (:class:`CameraView`) and converts where it
    reads or writes a stage.
    """
    return 100.0 * float(meters_per_unit)


def fov(focal_length, aperture) -> np.ndarray:
    """Field of view in radians across an ``aperture`` (same unit as ``focal_length``)."""
    return 2.0 * np.arctan(0.5 * np.asarray(aperture, dtype=np.float64) / np.asarray(focal_length, dtype=np.float64))


@dataclass
class CameraView:
    """A camera at one time code.

    Attributes
    ----------
    cam_to_world : (4, 4) float64
        Camera space to canonical world; the camera looks down its local -Z
        with +Y up (USD's convention).
    focal_length, horizontal_aperture, vertical_aperture : float
        Lens values as authored (their unit cancels out in the field of view).
    near, far : float
        Clipping range in metres.
    agent_state : str or None
        For camera agents: "scouting" or "tracking" at this time.
    tracked_event : str or None
        For camera agents: the CrowdEvent tracked ("" while scouting).
    f_stop : float
        Relative aperture (UsdGeom.Camera fStop); 0: a pinhole, everything sharp.
    focus_distance : float
        Distance to the plane in focus, metres (with ``f_stop`` > 0).
    toric : dict or None
        For toric cameras (ToricCameraAPI): ``behavior``, ``shot_size``,
        ``smoothed``, ``target_a``, ``target_b``, and the authored ``p_a``,
        ``p_b`` (NDC) and ``theta``, ``phi`` (degrees) at this time.
    cut : dict or None
        For a cut camera (CutCameraAPI, ``usdcrowd edit``): ``on_air`` (the
        camera whose pose it has), ``event``, ``shot`` (from 1) and ``reason``.
    """

    path: str
    time: float
    cam_to_world: np.ndarray
    focal_length: float
    horizontal_aperture: float
    vertical_aperture: float
    near: float
    far: float
    agent_state: str | None = None
    tracked_event: str | None = None
    toric: dict | None = None
    f_stop: float = 0.0
    focus_distance: float = 0.0
    cut: dict | None = None

    @property
    def depth_of_field(self) -> bool:
        """A thin lens (fStop and focusDistance both > 0), else a pinhole."""
        return self.f_stop > 0 and self.focus_distance > 0

    @property
    def aperture_radius(self) -> float:
        """Radius of the lens opening, metres: focal length / (2 fStop) (0 for a pinhole)."""
        return self.focal_length * 1e-3 / (2.0 * self.f_stop) if self.depth_of_field else 0.0

    @property
    def world_to_cam(self) -> np.ndarray:
        return np.linalg.inv(self.cam_to_world)

    @property
    def position(self) -> np.ndarray:
        return self.cam_to_world[3, :3].copy()

    def fov_x(self) -> float:
        """Horizontal field of view in degrees."""
        return float(np.degrees(fov(self.focal_length, self.horizontal_aperture)))

    def fov_y(self) -> float:
        """Vertical field of view in degrees (of the authored apertures, not of an image's aspect)."""
        return float(np.degrees(fov(self.focal_length, self.vertical_aperture)))

    def intrinsics(self, width: int, height: int) -> np.ndarray:
        """(3, 3) pinhole matrix K for an image of ``width`` x ``height`` pixels.

        The horizontal aperture fills the image width; pixels are square, so
        the vertical field of view follows the image's aspect (usdrecord's
        behaviour when the aspects differ). Pixel centres are at +0.5.
        """
        f = width * self.focal_length / self.horizontal_aperture
        return np.array([[f, 0.0, width / 2.0], [0.0, f, height / 2.0], [0.0, 0.0, 1.0]])

    def project(self, points: np.ndarray, width: int, height: int):
        """Project world points to pixels.

        Parameters
        ----------
        points : (..., 3) float
            Canonical world positions.

        Returns
        -------
        uv : (..., 2) float64
            Pixel coordinates (x right, y down; pixel centres at +0.5).
        z : (...) float64
            Depth along the view axis, metres (positive in front).
        """
        p = np.asarray(points, dtype=np.float64)
        cam = p @ self.world_to_cam[:3, :3] + self.world_to_cam[3, :3]
        z = -cam[..., 2]
        k = self.intrinsics(width, height)
        with np.errstate(divide="ignore", invalid="ignore"):
            u = k[0, 2] + k[0, 0] * cam[..., 0] / z
            v = k[1, 2] - k[1, 1] * cam[..., 1] / z
        return np.stack([u, v], -1), z


def camera_record(cam: CameraView, width: int, height: int) -> dict:
    """Intrinsics and extrinsics of one frame, for annotation files.

    Returns
    -------
    dict
        ``K`` (3x3, pixels, centres at +0.5), ``world_to_camera_opencv``
        (4x4 column-vector matrix to OpenCV camera axes: x right, y down,
        z forward), ``camera_to_world_usd`` (4x4 row-vector, USD axes),
        position, lens values and clipping range.
    """
    flip = np.diag([1.0, -1.0, -1.0])                    # USD camera axes -> OpenCV axes
    w2c = cam.world_to_cam                               # row vectors: p_cam = p @ R + t
    r = (w2c[:3, :3] @ flip).T
    t = w2c[3, :3] @ flip
    ext = np.eye(4)
    ext[:3, :3], ext[:3, 3] = r, t
    return {
        "camera": cam.path, "time": cam.time, "width": int(width), "height": int(height),
        "K": cam.intrinsics(width, height).tolist(),
        "world_to_camera_opencv": ext.tolist(),
        "camera_to_world_usd": cam.cam_to_world.tolist(),
        "position": cam.position.tolist(),
        "focal_length": cam.focal_length, "horizontal_aperture": cam.horizontal_aperture,
        "vertical_aperture": cam.vertical_aperture, "fov_x_deg": cam.fov_x(),
        "clipping_range": [cam.near, cam.far],
        "f_stop": cam.f_stop, "focus_distance": cam.focus_distance,
        # What the camera was doing and why (seed 000's camera agents; None for other cameras).
        "agent_state": cam.agent_state, "tracked_event": cam.tracked_event,
        # A toric camera's authored intent (seed 002; None for other cameras).
        "toric": cam.toric,
        # An edited cut's camera on air at this frame and why (None for other cameras).
        "cut": cam.cut,
    }


def lens_problem(name: str, value) -> str | None:
    """What makes a UsdGeom.Camera lens value unusable by any renderer, or None.

    ``name`` is "focalLength", "horizontalAperture", "verticalAperture" (each
    must be a finite number > 0) or "clippingRange" ((near, far) with
    0 < near < far). The renderers refuse such a camera and ``validate``
    reports it, in these words.
    """
    if name == "clippingRange":
        near, far = float(value[0]), float(value[1])
        if not (np.isfinite(near) and np.isfinite(far) and 0 < near < far):
            return f"must be 0 < near < far, got ({near:g}, {far:g})"
        return None
    if not (np.isfinite(float(value)) and float(value) > 0):
        return f"must be > 0, got {float(value):g}"
    return None
