"""CrowdEvent prims and camera agents read once into tables.

Every part that needs events (ground truth, the preview's markers, ``inspect``,
the cameras) or camera agents reads them here, in canonical units (Z up,
metres), as :class:`usdcrowd.core.model.EventTable` and
:class:`usdcrowd.core.model.CameraAgentTable`.
"""

from __future__ import annotations

import math

import numpy as np

from ..core import model
from .. import schema
from ..core.errors import ScenarioError
from .stageio import stage_frame, time_range

def layer_generator(layer) -> str | None:
    """Which usdcrowd command generated ``layer`` ("usdcrowd simulate", "usdcrowd cameras"), None for others.

    Told by the ``customLayerData["usdcrowd"]["generator"]`` usdcrowd writes,
    not by the file's name: a user's own sublayer may be called cameras.usda.
    """
    data = layer.customLayerData.get("usdcrowd") if layer.customLayerData else None
    return (data.get("generator") or None) if data else None


def is_generated_layer(layer) -> bool:
    """True for a layer usdcrowd generated (the crowd layer and its parts, cameras.usda)."""
    return layer_generator(layer) is not None


def _is_authored(prim) -> bool:
    """True when the prim is defined (``def``) in a layer usdcrowd did not generate.

    Events defined in generated layers were detected (cameras.usda holds those
    `usdcrowd cameras` had to detect), and say so (``crowd:detected``, which a
    flattened or exported shot keeps); any other was authored.
    """
    from pxr import Sdf

    flag = prim.GetAttribute("crowd:detected")
    if flag and flag.Get():                 # says so itself: survives flattening into one layer
        return False
    for spec in prim.GetPrimStack():
        if spec.specifier == Sdf.SpecifierDef and not is_generated_layer(spec.layer):
            return True
    return False


def _agent_ids(stage, agent_rows: dict[str, int]) -> np.ndarray:
    """(n,) int64 crowd:agentId of each row, -1 where the stage has no such agent."""
    n = max(agent_rows.values(), default=-1) + 1
    ids = np.full(n, -1, np.int64)
    for path, row in agent_rows.items():
        prim = stage.GetPrimAtPath(path)
        attr = prim.GetAttribute("crowd:agentId") if prim else None
        v = attr.Get() if attr else None
        if v is not None:
            ids[row] = int(v)
    return ids


def _sampled(attr, times: np.ndarray, default) -> list:
    """Values of ``attr`` at ``times`` (one read when it is not time-sampled)."""
    if not attr or not attr.HasValue():
        return [default] * len(times)
    if attr.GetNumTimeSamples() == 0:
        return [attr.Get()] * len(times)
    return [attr.Get(float(t)) for t in times]


def read_events(stage, agent_rows: dict[str, int], time: model.TimeRange,
                agent_ids: np.ndarray | None = None) -> model.EventTable:
    """Every CrowdEvent prim of a stage, sampled at the shot's frames.

    Parameters
    ----------
    stage : Usd.Stage
    agent_rows : dict[str, int]
        Agent prim path -> row (of the caller's agent arrays). Members that
        are not in it are ignored.
    time : TimeRange
        The shot's frames: events are clamped to it and sampled at each of
        its time codes from their start to their end.
    agent_ids : (n,) int, optional
        crowd:agentId of each row, to map ``crowd:memberIds``; default: read
        from the agents' prims on the stage (agents that are not on the
        stage, such as clones before simulation, then match no id).

    Returns
    -------
    EventTable
        Authored events first (stage order), then the ones the simulation
        detected (defined in crowd.usdc or its parts), sorted by path. An
        event wholly outside ``time`` keeps its row, with ``start > end``
        and no samples.

    Notes
    -----
    ``crowd:memberIds`` (time-sampled agent ids), when authored, says who
    takes part at each frame; ids outside ``crowd:members`` add to the
    members. Without it every member takes part from start to end.
    ``crowd:center`` and ``crowd:radius`` are converted from stage units.

    Raises
    ------
    ScenarioError
        For a crowd:kind outside EVENT_KINDS.
    """
    from pxr import Usd

    from .parent_space import ParentSpace

    frame = stage_frame(stage)
    space = ParentSpace(stage, time.codes)
    ids = np.asarray(agent_ids, dtype=np.int64) if agent_ids is not None else _agent_ids(stage, agent_rows)
    id_row = {int(a): r for r, a in enumerate(ids) if a >= 0}
    authored, detected = [], []
    for prim in Usd.PrimRange(stage.GetPseudoRoot()):
        if prim.GetTypeName() != schema.EVENT:
            continue
        ev = _read_event(stage, prim, agent_rows, id_row, time, frame, space)
        (authored if ev.authored else detected).append(ev)
    return model.EventTable(authored + sorted(detected, key=lambda e: e.path))


def _read_event(stage, prim, agent_rows: dict[str, int], id_row: dict[int, int], time: model.TimeRange,
                frame, space) -> model.Event:
    """One CrowdEvent prim, clamped to ``time`` and sampled at its codes, in canonical units."""
    from .parent_space import scale_of, transform_points

    path = str(prim.GetPath())
    kind = str(prim.GetAttribute("crowd:kind").Get())
    if kind not in model.EVENT_KINDS:
        raise ScenarioError(f"unknown event kind {kind!r} (one of {', '.join(model.EVENT_KINDS)})",
                            file=stage.GetRootLayer().identifier, prim=path, attribute="crowd:kind")
    codes = time.codes
    start = max(float(prim.GetAttribute("crowd:startTime").Get()), time.start)
    end = min(float(prim.GetAttribute("crowd:endTime").Get()), time.end)
    times = codes[(codes >= start - 1e-6) & (codes <= end + 1e-6)]
    members, active = _event_members(prim, agent_rows, id_row, times)

    center = np.array(_sampled(prim.GetAttribute("crowd:center"), times, (0.0, 0.0, 0.0)),
                      dtype=np.float64).reshape(-1, 3)
    radius = np.array(_sampled(prim.GetAttribute("crowd:radius"), times, 1.0), dtype=np.float64)
    # Centre and radius are in the event's parent space: a moved shot moves its events.
    to_world = space.world(path, times)
    center, radius = transform_points(center, to_world), radius * scale_of(to_world)
    return model.Event(path, model.code(model.EVENT_KINDS, kind), start, end, members, times, active,
                       frame.points_to_canonical(center), frame.length_to_canonical(radius),
                       authored=_is_authored(prim))


def _event_members(prim, agent_rows: dict[str, int], id_row: dict[int, int], times: np.ndarray):
    """Member rows ``(k,) int32``, ascending, and who takes part at each of ``times``, ``(m, k) bool``."""
    rel = prim.GetRelationship("crowd:members")
    rows = {agent_rows[str(p)] for p in (rel.GetTargets() if rel else []) if str(p) in agent_rows}
    ids_attr = prim.GetAttribute("crowd:memberIds")
    per_frame = None
    if ids_attr and ids_attr.HasAuthoredValue():
        per_frame = [{id_row[int(a)] for a in (v or []) if int(a) in id_row}
                     for v in _sampled(ids_attr, times, [])]
        rows = rows.union(*per_frame)
    members = np.array(sorted(rows), dtype=np.int32)
    if per_frame is None:
        return members, np.ones((len(times), len(members)), dtype=bool)
    col = {r: j for j, r in enumerate(members)}
    active = np.zeros((len(times), len(members)), dtype=bool)
    for i, present in enumerate(per_frame):
        active[i, [col[r] for r in present]] = True
    return members, active


def _bad_op(prim, time) -> str:
    """The name of the first transform op of ``prim`` (or an ancestor) whose value is not finite."""
    from pxr import UsdGeom

    p = prim
    while p and not p.IsPseudoRoot():
        xf = UsdGeom.Xformable(p)
        for op in (xf.GetOrderedXformOps() if xf else []):
            value = op.Get(time)
            if value is not None and not np.isfinite(np.asarray(value, dtype=np.float64)).all():
                return op.GetName() if p == prim else f"{op.GetName()} of {p.GetPath()}"
        p = p.GetParent()
    return "xformOpOrder"


def read_camera_agents(stage, time: float | None = None) -> model.CameraAgentTable:
    """Every camera with CameraAgentAPI, its initial state in canonical units.

    Parameters
    ----------
    stage : Usd.Stage
    time : float, optional
        Time code of the initial transform and lens; default: the first
        frame of the stage's time range.

    Returns
    -------
    CameraAgentTable
        In stage order. Unauthored values take the schema's fallbacks;
        angles are turned from the schema's degrees into radians. Speeds,
        forces, distances and elevations are metres as the schema states
        (not stage units); the transform and the clipping range are turned
        from stage units into metres, and the transform's scale is removed
        (lenses do not scale with units), as ShotScene does.
    """
    from pxr import Usd, UsdGeom

    frame = stage_frame(stage)
    t = time_range(stage).start if time is None else float(time)
    cache = UsdGeom.XformCache(Usd.TimeCode(t))
    rows = [_camera_agent(stage, prim, cache, frame, t) for prim in Usd.PrimRange(stage.GetPseudoRoot())
            if prim.IsA(UsdGeom.Camera) and prim.HasAPI(schema.CAMERA_AGENT_API)]
    if not rows:
        return model.CameraAgentTable.empty()

    def col(name, dtype=np.float64):
        return np.array([r[name] for r in rows], dtype=dtype)

    return model.CameraAgentTable(
        [r["path"] for r in rows], col("cam_to_world"), col("focal_length"), col("horizontal_aperture"),
        col("vertical_aperture"), col("near"), col("far"), col("mode", np.int8), col("max_speed"),
        col("max_force"), col("max_angular_speed"), col("arrival_distance"), col("aim_threshold"),
        col("separation_distance"), col("view_angle"), col("elevation"), [r["target"] for r in rows])


def _camera_agent(stage, prim, cache, frame, t: float) -> dict:
    """One camera agent's row: its pose and lens at ``t`` and its CameraAgentAPI values, checked."""
    from pxr import UsdGeom

    from ..core.view import lens_problem
    from .ranges import range_problem
    from .stageio import camera_frame, camera_lens

    source = stage.GetRootLayer().identifier
    m = camera_frame(cache.GetLocalToWorldTransform(prim), frame)
    if not np.isfinite(m).all():
        raise ScenarioError("not a finite value", file=source, prim=str(prim.GetPath()), attribute=_bad_op(prim, t))

    def fail(message, attribute):
        raise ScenarioError(message, file=source, prim=str(prim.GetPath()), attribute=attribute)

    def get(name):
        value = prim.GetAttribute(f"crowd:camera:{name}").Get()
        if isinstance(value, str) or value is None:
            return value
        values = [value] if isinstance(value, (int, float)) else list(value)
        if not all(math.isfinite(float(v)) for v in values):
            fail(f"not a finite number: {value}", f"crowd:camera:{name}")
        # The same words as `usdcrowd validate` (one problem, one line).
        problem = range_problem(name if name == "elevationRange" else f"camera:{name}",
                                value if isinstance(value, (int, float)) else tuple(values))
        if problem:
            fail(problem, f"crowd:camera:{name}")
        return value

    for lens in ("focalLength", "horizontalAperture", "verticalAperture"):
        value = prim.GetAttribute(lens).Get(t)
        problem = lens_problem(lens, value) if value is not None else "is not set"
        if problem:
            fail(problem, lens)
    get("elevationRange")
    mode = str(get("mode"))
    if mode not in model.CAMERA_MODES:
        fail(f"unknown camera mode {mode!r} (one of {', '.join(model.CAMERA_MODES)})", "crowd:camera:mode")
    target = prim.GetRelationship("crowd:camera:target")
    targets = target.GetTargets() if target else []
    # In the units of the layers that authored them, as the renderers read them.
    focal, h_ap, v_ap, near, far = camera_lens(UsdGeom.Camera(prim), t, frame)
    return dict(
        path=str(prim.GetPath()), cam_to_world=m,
        focal_length=focal, horizontal_aperture=h_ap, vertical_aperture=v_ap, near=near, far=far,
        mode=model.code(model.CAMERA_MODES, mode), max_speed=float(get("maxSpeed")),
        max_force=float(get("maxForce")), max_angular_speed=math.radians(get("maxAngularSpeed")),
        arrival_distance=float(get("arrivalDistance")),
        aim_threshold=math.radians(get("aimAngleThreshold")),
        separation_distance=float(get("separationDistance")), view_angle=float(get("viewAngle")),
        elevation=tuple(float(v) for v in get("elevationRange")),
        target=str(targets[0]) if targets else None)
