"""The shot stage: a root layer that sublayers what was generated over what was authored.

::

    shot.usda       lights and settings added by usdcrowd (strongest)
      cameras.usda  camera trajectories (generated)
      crowd.usdc    agents' skeletons, animation, state (generated)
      scenario      the user's stage, referred to in place, never rewritten

Re-running the cameras rewrites only cameras.usda; a DCC tool's edits go in
shot.usda or a stronger layer of its own.
"""

from __future__ import annotations

import os

import numpy as np

from .. import __version__, model
from ..atomic import atomic_path
from ..scenario.stageio import StageFrame
from ..view import look_at

# The package's one look-at helper, under the name this module used to define.
look_at_matrix = look_at

SHOT = "shot.usda"
CROWD = "crowd.usdc"
CAMERAS = "cameras.usda"
CROWD_CAMERA = "Cameras/CrowdCam"      # under the default prim
# Lens of the generated overview camera: a 35 mm full-frame 16:9 crop.
FOCAL_LENGTH = 28.0
H_APERTURE = 36.0
V_APERTURE = 20.25


def _relative(target: str, start_dir: str) -> str:
    rel = os.path.relpath(os.path.abspath(target), os.path.abspath(start_dir))
    return rel if rel.startswith(".") else f"./{rel}"


def write_shot(out_dir: str | os.PathLike, scenario_path: str, time: model.TimeRange, frame: StageFrame,
               default_prim: str, seed: int, add_lights: bool) -> str:
    """Write shot.usda in ``out_dir``, sublayering cameras, crowd and scenario.

    Parameters
    ----------
    add_lights : bool
        Add a sun and a sky dome (UsdLux) because the scenario has no light.
    """
    from pxr import Gf, Sdf

    out_dir = os.fspath(out_dir)
    final = os.path.join(out_dir, SHOT)
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.subLayerPaths = [f"./{CAMERAS}", f"./{CROWD}", _relative(scenario_path, out_dir)]
    layer.defaultPrim = default_prim
    layer.startTimeCode, layer.endTimeCode = time.start, time.end
    layer.timeCodesPerSecond = layer.framesPerSecond = time.fps
    layer.pseudoRoot.SetInfo("upAxis", frame.up_axis)
    layer.pseudoRoot.SetInfo("metersPerUnit", frame.meters_per_unit)
    layer.customLayerData = {"usdcrowd": {"version": __version__, "seed": int(seed),
                                          "scenario": _relative(scenario_path, out_dir)}}
    if add_lights:
        root = f"/{default_prim}" if default_prim else ""
        with Sdf.ChangeBlock():
            _define_scope(layer, f"{root}/Lights")
            sun = Sdf.CreatePrimInLayer(layer, f"{root}/Lights/Sun")
            sun.specifier, sun.typeName = Sdf.SpecifierDef, "DistantLight"
            _set(sun, "inputs:intensity", Sdf.ValueTypeNames.Float, 3.0)
            _set(sun, "inputs:angle", Sdf.ValueTypeNames.Float, 0.53)
            _set(sun, "inputs:color", Sdf.ValueTypeNames.Color3f, Gf.Vec3f(1.0, 0.96, 0.9))
            rot = (40.0, 0.0, 30.0) if frame.up_axis == "Z" else (-50.0, 30.0, 0.0)
            _set(sun, "xformOp:rotateXYZ", Sdf.ValueTypeNames.Float3, Gf.Vec3f(*rot))
            _set(sun, "xformOpOrder", Sdf.ValueTypeNames.TokenArray, ["xformOp:rotateXYZ"], uniform=True)
            sky = Sdf.CreatePrimInLayer(layer, f"{root}/Lights/Sky")
            sky.specifier, sky.typeName = Sdf.SpecifierDef, "DomeLight"
            _set(sky, "inputs:intensity", Sdf.ValueTypeNames.Float, 0.6)
            _set(sky, "inputs:color", Sdf.ValueTypeNames.Color3f, Gf.Vec3f(0.75, 0.85, 1.0))
    with atomic_path(final) as tmp:
        layer.Export(os.fspath(tmp))
    return final


def _define_scope(layer, path: str) -> None:
    """A typeless ``def`` at ``path``: defined (so its children are traversed)
    without overriding the type the scenario may give it."""
    from pxr import Sdf

    Sdf.CreatePrimInLayer(layer, path).specifier = Sdf.SpecifierDef


def _set(spec, name, type_name, value, uniform=False):
    from pxr import Sdf

    attr = Sdf.AttributeSpec(spec, name, type_name, Sdf.VariabilityUniform if uniform else Sdf.VariabilityVarying)
    attr.default = value
    return attr


def write_cameras(out_dir: str | os.PathLike, centre: np.ndarray, spread: np.ndarray, times: np.ndarray,
                  frame: StageFrame, default_prim: str, time: model.TimeRange) -> str:
    """Write cameras.usda with one camera framing the whole crowd.

    A placeholder for the steering-camera agents (seed 000): the camera keeps
    the crowd's centroid in view from a fixed bearing, at a distance that fits
    the crowd's spread into the field of view, smoothed over time.

    Parameters
    ----------
    centre : (t, 3) float
        Centroid of the visible agents, canonical metres.
    spread : (t,) float
        Largest distance of a visible agent from the centroid, metres.
    times : (t,) float
        Time codes.
    """
    from pxr import Gf, Sdf, Vt

    # Half a metre around the outermost agent, and at least a 3 m wide view.
    spread = np.maximum(np.asarray(spread, dtype=np.float64) + 0.5, 1.5)
    # Smooth the framing so the camera does not jitter with individual agents.
    k = max(1, int(time.fps))
    kernel = np.ones(k) / k
    pad = lambda a: np.pad(a, [(k // 2, k - 1 - k // 2)] + [(0, 0)] * (a.ndim - 1), mode="edge")
    centre = np.stack([np.convolve(pad(centre[:, j]), kernel, mode="valid") for j in range(3)], 1)
    spread = np.convolve(pad(spread), kernel, mode="valid")
    half_fov = np.arctan(0.5 * V_APERTURE / FOCAL_LENGTH)
    distance = spread / np.tan(half_fov)
    bearing = np.array([0.0, -np.cos(np.radians(35)), np.sin(np.radians(35))])
    target = centre + np.array([0.0, 0.0, 1.0])
    eye = target + distance[:, None] * bearing
    cam_to_world = look_at_matrix(eye, target) @ frame.from_canonical

    out_dir = os.fspath(out_dir)
    final = os.path.join(out_dir, CAMERAS)
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.defaultPrim = default_prim
    layer.startTimeCode, layer.endTimeCode = time.start, time.end
    layer.timeCodesPerSecond = layer.framesPerSecond = time.fps
    layer.pseudoRoot.SetInfo("upAxis", frame.up_axis)
    layer.pseudoRoot.SetInfo("metersPerUnit", frame.meters_per_unit)
    root = f"/{default_prim}" if default_prim else ""
    T = Sdf.ValueTypeNames
    with Sdf.ChangeBlock():
        _define_scope(layer, f"{root}/Cameras")
        cam = Sdf.CreatePrimInLayer(layer, f"{root}/{CROWD_CAMERA}")
        cam.specifier, cam.typeName = Sdf.SpecifierDef, "Camera"
        _set(cam, "focalLength", T.Float, FOCAL_LENGTH)
        _set(cam, "horizontalAperture", T.Float, H_APERTURE)
        _set(cam, "verticalAperture", T.Float, V_APERTURE)
        _set(cam, "clippingRange", T.Float2, Gf.Vec2f(0.1 / frame.meters_per_unit, 1000.0 / frame.meters_per_unit))
        op = Sdf.AttributeSpec(cam, "xformOp:transform", T.Matrix4d)
        for t, m in zip(times, cam_to_world):
            layer.SetTimeSample(op.path, float(t), Gf.Matrix4d(m.tolist()))
        _set(cam, "xformOpOrder", T.TokenArray, Vt.TokenArray(["xformOp:transform"]), uniform=True)
    with atomic_path(final) as tmp:
        layer.Export(os.fspath(tmp))
    return final
