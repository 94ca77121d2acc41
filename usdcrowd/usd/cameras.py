"""cameras.usda: camera tracks as UsdGeom.Camera prims with time samples.

Cameras the scenario defines (its camera agents) are written as ``over``s:
their transform op order is replaced by one time-sampled
``xformOp:transform``, and the authored lens and CameraAgentAPI values stay
where the user wrote them. Generated cameras are defined here, with
CameraAgentAPI applied when they are agents.

Every transform is the camera's pose in its parent's space
(:mod:`usdcrowd.scenario.parent_space`), so a layer or a set that moves the shot
moves its cameras with it. Composed to the world, the rotation rows are of
unit length in the stage's units (no metersPerUnit scale), so a viewer that
inverts the whole matrix gets camera-space depths in stage units, which is
what ``clippingRange`` is in.
"""

from __future__ import annotations

import os

import numpy as np

from .. import __version__, schema
from ..core import model
from ..atomic import export_layer
from ..scenario.stageio import StageFrame
from ..core.view import mm_per_lens_unit
from ..scenario.parent_space import in_parent

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
                        extra: dict | None = None, events_writer=None, keep_toric: bool = False,
                        parents=None) -> str:
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
    keep_toric : bool
        Keep the toric cameras (``usdcrowd frame``'s) of the cameras.usda
        being replaced.
    parents : ParentSpace, optional
        The stage the tracks were computed on: each pose is authored in its
        parent's space there (default: parents at the identity).
    """
    from pxr import Sdf

    out_dir = os.fspath(out_dir)
    final = os.path.join(out_dir, CAMERAS)
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.defaultPrim = default_prim
    layer.startTimeCode, layer.endTimeCode = time.start, time.end
    layer.timeCodesPerSecond = layer.framesPerSecond = time.fps
    layer.pseudoRoot.SetInfo("upAxis", frame.up_axis)
    layer.pseudoRoot.SetInfo("metersPerUnit", frame.meters_per_unit)
    layer.customLayerData = {"usdcrowd": {"generator": "usdcrowd cameras", "version": __version__,
                                          **(extra or {})}}
    with Sdf.ChangeBlock():
        for track in tracks:
            _write_track(layer, track, frame, track.path in defined,
                         parents.of(track.path, track.times) if parents is not None else None)
        if events_writer is not None:
            events_writer(layer)
        if keep_toric and os.path.exists(final):
            _copy_toric(Sdf.Layer.OpenAsAnonymous(final), layer, {t.path for t in tracks})
    _count_cameras(layer)
    return export_layer(layer, final)


def _write_track(layer, track: model.CameraTrack, frame: StageFrame, over: bool, parent=None):
    """Author one camera track into ``layer`` (inside the caller's change block); returns its prim spec.

    ``parent``: (4, 4) or (t, 4, 4) local-to-world of the camera's parent, stage units (None: identity).
    """
    from pxr import Gf, Sdf, Vt

    T = Sdf.ValueTypeNames
    mpu = frame.meters_per_unit
    lens = mm_per_lens_unit(mpu)            # lenses in tenths of a scene unit, as USD means them
    _parents(layer, track.path)
    spec = Sdf.CreatePrimInLayer(layer, track.path)
    if over:
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
    if not over or len(set(fl)) > 1:     # the user's own lens stays theirs
        focal = Sdf.AttributeSpec(spec, "focalLength", T.Float)
        focal.default = fl[0]           # what readers that ask without a time get: a fixed lens has only it
        if len(set(fl)) > 1:
            for i in _changes(fl):
                if i > 0:       # held until the change: USD interpolates a float between its samples
                    layer.SetTimeSample(focal.path, float(track.times[i - 1]), fl[i - 1])
                layer.SetTimeSample(focal.path, float(track.times[i]), fl[i])
    op = Sdf.AttributeSpec(spec, "xformOp:transform", T.Matrix4d)
    poses = np.broadcast_to(in_parent(stage_poses(track.cam_to_world, frame), parent),
                            (len(track.times), 4, 4))
    if len(poses) and (poses == poses[0]).all():
        op.default = Gf.Matrix4d(poses[0].tolist())     # a static camera: one pose, not one per frame
    else:
        for t, m in zip(track.times, poses):
            layer.SetTimeSample(op.path, float(t), Gf.Matrix4d(m.tolist()))
    _set(spec, "xformOpOrder", T.TokenArray, Vt.TokenArray(["xformOp:transform"]), uniform=True)
    if track.state is not None:
        st = Sdf.AttributeSpec(spec, STATE, T.Token)
        names = [model.CAMERA_MODES[int(s)] for s in track.state]
        for i in _changes(names):
            layer.SetTimeSample(st.path, float(track.times[i]), names[i])
        tr = Sdf.AttributeSpec(spec, TRACKED, T.String)
        for i in _changes(track.tracked):
            layer.SetTimeSample(tr.path, float(track.times[i]), track.tracked[i])
    return spec


def _is_toric(spec) -> bool:
    return schema.TORIC_CAMERA_API in list(spec.GetInfo("apiSchemas").GetAddedOrExplicitItems())


def _copy_toric(old, layer, replaced: set[str]) -> None:
    """Copy the toric cameras of an earlier cameras layer (``usdcrowd frame``'s) into ``layer``."""
    from pxr import Sdf

    found = []
    old.Traverse(old.pseudoRoot.path, lambda path: found.append(path) if path.IsPrimPath() else None)
    for path in found:
        spec = old.GetPrimAtPath(path)
        if spec and _is_toric(spec) and str(path) not in replaced:
            _parents(layer, str(path))
            Sdf.CopySpec(old, path, layer, path)


def add_camera(cameras_path: str | os.PathLike, track: model.CameraTrack, toric: dict | None,
               parents=None, author=None) -> str:
    """Add (or replace) one camera, toric or plain (``toric`` None), in an existing cameras layer,
    atomically; the others are kept.

    Parameters
    ----------
    cameras_path : path-like
        The shot's cameras.usda.
    track : CameraTrack
        Canonical metres.
    toric : dict or None
        ``behavior``, ``shot_size``, ``smoothed`` and per frame ``target_a``,
        ``target_b`` (lists of prim paths), ``p_a``, ``p_b`` ((t, 2) NDC),
        ``theta``, ``phi`` ((t,) radians); for a learned camera also
        ``expert_weights`` and ``reference`` (the reference stage's path),
        and ``reference_style`` where the model's experts read one;
        for a style switched over time also ``references``, ``reference_from``
        (time codes) and ``reference_weights`` (one row per reference).
    parents : ParentSpace, optional
        The stage the track was computed on (see :func:`write_camera_tracks`).
    author : callable(layer, spec), optional
        Authors more on the camera's prim spec, inside the change block
        (an edited cut's record: :mod:`usdcrowd.usd.cut`).
    """
    from pxr import Sdf

    from ..scenario.stageio import layer_frame

    final = os.fspath(cameras_path)
    layer = Sdf.Layer.OpenAsAnonymous(final)
    frame = layer_frame(layer)
    with Sdf.ChangeBlock():
        if layer.GetPrimAtPath(track.path):
            parent = layer.GetPrimAtPath(track.path).nameParent
            del parent.nameChildren[track.path.rsplit("/", 1)[-1]]
        spec = _write_track(layer, track, frame, over=False,
                            parent=parents.of(track.path, track.times) if parents is not None else None)
        if toric is not None:
            _toric_values(layer, spec, track, toric)
        if author is not None:
            author(layer, spec)
    _count_cameras(layer)
    written = export_layer(layer, final)
    # A stage this process still holds (the one the camera was computed on) sees the new file too.
    held = Sdf.Layer.Find(final)
    if held:
        held.Reload()
    return written


def camera_specs(layer) -> list[str]:
    """Paths of the cameras a cameras layer holds, sorted: those it defines (``Camera``) and its
    ``over``s of the scenario's own cameras (which carry a transform)."""
    from pxr import Sdf

    found = []

    def visit(path):
        if not path.IsPrimPath():
            return
        spec = layer.GetPrimAtPath(path)
        if spec.typeName == "Camera" or (spec.specifier == Sdf.SpecifierOver and not spec.typeName
                                         and "xformOp:transform" in spec.attributes):
            found.append(str(path))

    layer.Traverse(layer.pseudoRoot.path, visit)
    return sorted(found)


def cameras_in(path: str | os.PathLike) -> list[str]:
    """Paths of the cameras the cameras layer at ``path`` holds (see :func:`camera_specs`)."""
    from pxr import Sdf

    return camera_specs(Sdf.Layer.OpenAsAnonymous(os.fspath(path)))


def _count_cameras(layer) -> None:
    """Record in customLayerData["usdcrowd"]["cameras"] how many cameras the layer holds (kept ones too)."""
    data = dict(layer.customLayerData)
    if "usdcrowd" in data:                  # a cameras layer usdcrowd made (not one it only adds to)
        data["usdcrowd"] = {**dict(data["usdcrowd"]), "cameras": len(camera_specs(layer))}
        layer.customLayerData = data


def _toric_values(layer, spec, track: model.CameraTrack, toric: dict) -> None:
    """The toric camera's schema and its time-sampled intent (inside the caller's change block)."""
    from pxr import Gf, Sdf, Vt

    T = Sdf.ValueTypeNames
    spec.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=[schema.TORIC_CAMERA_API]))
    _set(spec, "crowd:toric:behavior", T.Token, toric["behavior"], uniform=True)
    _set(spec, "crowd:toric:shotSize", T.Token, toric["shot_size"], uniform=True)
    _set(spec, "crowd:toric:smoothed", T.Bool, bool(toric["smoothed"]), uniform=True)
    if toric.get("expert_weights") is not None:
        _set(spec, "crowd:toric:expertWeights", T.FloatArray,
             Vt.FloatArray([float(v) for v in toric["expert_weights"]]), uniform=True)
        _set(spec, "crowd:toric:reference", T.Asset, Sdf.AssetPath(toric["reference"]), uniform=True)
    if toric.get("reference_style") is not None:
        _set(spec, "crowd:toric:referenceStyle", T.FloatArray,
             Vt.FloatArray([float(v) for v in toric["reference_style"]]), uniform=True)
    if toric.get("references"):
        _set(spec, "crowd:toric:references", T.AssetArray,
             Sdf.AssetPathArray([Sdf.AssetPath(r) for r in toric["references"]]), uniform=True)
        _set(spec, "crowd:toric:referenceFrom", T.FloatArray,
             Vt.FloatArray([float(f) for f in toric["reference_from"]]), uniform=True)
        _set(spec, "crowd:toric:referenceWeights", T.FloatArray,
             Vt.FloatArray([float(v) for v in np.ravel(toric["reference_weights"])]), uniform=True)
    times = [float(t) for t in track.times]
    for name, key in (("crowd:toric:targetA", "target_a"), ("crowd:toric:targetB", "target_b")):
        attr = Sdf.AttributeSpec(spec, name, T.String)
        values = list(toric[key])
        for i in _changes(values):
            layer.SetTimeSample(attr.path, times[i], values[i])
    for name, key in (("crowd:toric:pA", "p_a"), ("crowd:toric:pB", "p_b")):
        attr = Sdf.AttributeSpec(spec, name, T.Float2)
        for t, v in zip(times, np.asarray(toric[key], dtype=np.float64)):
            if np.isfinite(v).all():        # none where a smoothed camera lost a head behind it
                layer.SetTimeSample(attr.path, t, Gf.Vec2f(float(v[0]), float(v[1])))
    for name, key in (("crowd:toric:theta", "theta"), ("crowd:toric:phi", "phi")):
        attr = Sdf.AttributeSpec(spec, name, T.Float)
        for t, v in zip(times, np.degrees(np.asarray(toric[key], dtype=np.float64))):
            if np.isfinite(v):
                layer.SetTimeSample(attr.path, t, float(v))


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
