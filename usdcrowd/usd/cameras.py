"""cameras.usda: camera tracks as UsdGeom.Camera prims with time samples.

Cameras the scenario defines (its camera agents) are written as ``over``s:
their transform op order is replaced by one time-sampled
``xformOp:transform``, and the authored lens and CameraAgentAPI values stay
where the user wrote them. Generated cameras are defined here, with
CameraAgentAPI applied when they are agents.

Every transform is a world pose: the op order starts with
``!resetXformStack!``, so a transformed parent (a camera rig, a DCC
stage's root) does not move the camera a second time. Its rotation rows are
of unit length in the stage's units (no metersPerUnit scale), so a viewer
that inverts the whole matrix gets camera-space depths in stage units, which
is what ``clippingRange`` is in.
"""

from __future__ import annotations

import os

import numpy as np

from .. import __version__, model
from ..atomic import export_layer
from ..scenario.stageio import StageFrame
from ..view import mm_per_lens_unit

CAMERAS = "cameras.usda"
STATE = "crowd:camera:state"
TRACKED = "crowd:camera:trackedEvent"
_AGENT_ATTRS = (("max_speed", "crowd:camera:maxSpeed", 1.0), ("max_force", "crowd:camera:maxForce", 1.0),
                ("max_angular_speed", "crowd:camera:maxAngularSpeed", "deg"),
                ("arrival_distance", "crowd:camera:arrivalDistance", 1.0),
                ("aim_threshold", "crowd:camera:aimAngleThreshold", "deg"),
                ("separation_distance", "crowd:camera:separationDistance", 1.0),
                ("view_angle", "crowd:camera:viewAngle", None))


def _changes(values: list) -> list[int]:
    """Indices where a per-frame value differs from the one before (always 0)."""
    return [i for i in range(len(values)) if i == 0 or values[i] != values[i - 1]]


def write_camera_tracks(out_dir: str | os.PathLike, tracks: list[model.CameraTrack], frame: StageFrame,
                        default_prim: str, time: model.TimeRange, defined: set[str] = frozenset(),
                        extra: dict | None = None, events_writer=None) -> str:
    """Write cameras.usda atomically.

    Parameters
    ----------
    tracks : list[CameraTrack]
        Canonical metres; converted to the stage's axes and units here.
    defined : set[str]
        Paths of cameras that the layers below already define (written as ``over``).
    extra : dict, optional
        Added to the layer's customLayerData["usdcrowd"] (seed, counts).
    events_writer : callable(layer), optional
        Authors more prims into the layer before it is saved (events detected
        when re-filming a shot whose crowd layer has none).
    """
    from pxr import Gf, Sdf, Vt

    out_dir = os.fspath(out_dir)
    final = os.path.join(out_dir, CAMERAS)
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.defaultPrim = default_prim
    layer.startTimeCode, layer.endTimeCode = time.start, time.end
    layer.timeCodesPerSecond = layer.framesPerSecond = time.fps
    layer.pseudoRoot.SetInfo("upAxis", frame.up_axis)
    layer.pseudoRoot.SetInfo("metersPerUnit", frame.meters_per_unit)
    layer.customLayerData = {"usdcrowd": {"generator": "usdcrowd cameras", "version": __version__,
                                          "cameras": len(tracks), **(extra or {})}}
    T = Sdf.ValueTypeNames
    mpu = frame.meters_per_unit
    lens = mm_per_lens_unit(mpu)            # lenses in tenths of a scene unit, as USD means them
    with Sdf.ChangeBlock():
        for track in tracks:
            _parents(layer, track.path)
            spec = Sdf.CreatePrimInLayer(layer, track.path)
            if track.path in defined:
                spec.specifier = Sdf.SpecifierOver
            else:
                spec.specifier, spec.typeName = Sdf.SpecifierDef, "Camera"
                _set(spec, "horizontalAperture", T.Float, float(track.horizontal_aperture) / lens)
                _set(spec, "verticalAperture", T.Float, float(track.vertical_aperture) / lens)
                _set(spec, "clippingRange", T.Float2, Gf.Vec2f(track.near / mpu, track.far / mpu))
                if track.agent is not None:
                    spec.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["CameraAgentAPI"]))
                    _agent_values(spec, track.agent)
            fl = [float(f) / lens for f in track.focal_length]
            if track.path not in defined or len(set(fl)) > 1:     # the user's own lens stays theirs
                focal = Sdf.AttributeSpec(spec, "focalLength", T.Float)
                focal.default = fl[0]           # what readers that ask without a time get
                for i in _changes(fl):
                    layer.SetTimeSample(focal.path, float(track.times[i]), fl[i])
            op = Sdf.AttributeSpec(spec, "xformOp:transform", T.Matrix4d)
            for t, m in zip(track.times, stage_poses(track.cam_to_world, frame)):
                layer.SetTimeSample(op.path, float(t), Gf.Matrix4d(m.tolist()))
            _set(spec, "xformOpOrder", T.TokenArray, Vt.TokenArray(["!resetXformStack!", "xformOp:transform"]),
                 uniform=True)
            if track.state is not None:
                st = Sdf.AttributeSpec(spec, STATE, T.Token)
                names = [model.CAMERA_MODES[int(s)] for s in track.state]
                for i in _changes(names):
                    layer.SetTimeSample(st.path, float(track.times[i]), names[i])
                tr = Sdf.AttributeSpec(spec, TRACKED, T.String)
                for i in _changes(track.tracked):
                    layer.SetTimeSample(tr.path, float(track.times[i]), track.tracked[i])
        if events_writer is not None:
            events_writer(layer)
    return export_layer(layer, final)


def stage_poses(cam_to_world: np.ndarray, frame: StageFrame) -> np.ndarray:
    """(t, 4, 4) canonical camera-to-world matrices as world poses in the stage's axes and units.

    The rotation rows stay of unit length (a camera is not scaled); only the
    position changes unit.
    """
    m = np.asarray(cam_to_world, dtype=np.float64) @ frame.from_canonical
    m[:, :3, :3] /= np.linalg.norm(m[:, :3, :3], axis=2, keepdims=True)
    return m


def _agent_values(spec, agent: dict) -> None:
    from pxr import Gf, Sdf

    T = Sdf.ValueTypeNames
    for key, name, unit in _AGENT_ATTRS:
        v = float(agent[key])
        _set(spec, name, T.Float, float(np.degrees(v)) if unit == "deg" else v, uniform=True)
    lo, hi = agent["elevation"]
    _set(spec, "crowd:camera:elevationRange", T.Float2, Gf.Vec2f(float(lo), float(hi)), uniform=True)
    mode = agent.get("mode")
    if mode is not None:
        _set(spec, "crowd:camera:mode", T.Token, model.CAMERA_MODES[int(mode)], uniform=True)


def _parents(layer, path: str) -> None:
    """Typeless ``def``s above ``path`` (traversed, without overriding the scenario's types)."""
    from pxr import Sdf

    parts = path.strip("/").split("/")[:-1]
    for k in range(1, len(parts) + 1):
        p = "/" + "/".join(parts[:k])
        if not layer.GetPrimAtPath(p):
            Sdf.CreatePrimInLayer(layer, p).specifier = Sdf.SpecifierDef


def _set(spec, name, type_name, value, uniform=False):
    from pxr import Sdf

    attr = Sdf.AttributeSpec(spec, name, type_name, Sdf.VariabilityUniform if uniform else Sdf.VariabilityVarying)
    attr.default = value
    return attr
