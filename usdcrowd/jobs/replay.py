"""``usdcrowd replay``: a shot whose people walk recorded or peer trajectories.

The trajectory file (:mod:`usdcrowd.exchange.recorded_tracks`) becomes a
scenario stage written beside the shot (``replay.usda``: the ground, or the
user's scenery, and one CrowdAgentAPI prim per person, ``crowd:agentId`` the
file's id), and its motion (:mod:`usdcrowd.exchange.replay_motion`) takes the
simulation's place in :func:`usdcrowd.jobs.pipeline.author_shot`: the same
layers, events, camera agents and picture as ``simulate`` writes. Attributes
the file does not give (build, clothes, height unless the file has head
heights) are drawn from the seed as for a template's clones.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core import model
from ..core.errors import UsdcrowdError

SCENARIO = "replay.usda"
# Ground around the walked area when no scenery is given, metres.
GROUND_MARGIN = 3.0
# Head heights (PedPy's Z) read as body heights only in this range; other Z columns are not heights.
BODY_HEIGHT_RANGE = (1.2, 2.3)
HEIGHT_SOURCES = ("auto", "file", "drawn")
# Frames made at a time (memory follows this, not the recording's length).
CHUNK_FRAMES = 128
# Camera agents of a replay without a companion scenario (besides the overview camera).
DEFAULT_CAMERAS = 4


def shot_rate(file_fps: float) -> float:
    """The shot's frames per second for a file's: the file's own between 10 and 60, else 25."""
    return float(file_fps) if 10.0 <= file_fps <= 60.0 else 25.0


def body_heights(tracks, height_from: str) -> np.ndarray | None:
    """(n,) each person's median head height where the file's Z column holds heights, else None (drawn).

    Raises
    ------
    UsdcrowdError
        ``height_from="file"`` and the file has no Z, or Z that are no body heights.
    """
    if height_from == "drawn":
        return None
    z = tracks.head
    heights = np.full(len(tracks), np.nan)
    if np.isfinite(z).any():
        bounds = tracks.row_bounds
        for i, (a, b) in enumerate(zip(bounds[:-1], bounds[1:])):
            mine = z[a:b][np.isfinite(z[a:b])]
            heights[i] = np.median(mine) if len(mine) else np.nan
    lo, hi = BODY_HEIGHT_RANGE
    usable = bool(np.isfinite(heights).all() and ((heights >= lo) & (heights <= hi)).all())
    if height_from == "file" and not usable:
        raise UsdcrowdError(f"--height-from file needs every person's Z (head height) between {lo} and {hi} m",
                            file=tracks.source)
    return heights if usable else None


def write_scenario(path: Path, tracks, sampler, heights: np.ndarray | None, seed: int,
                   scenery: str | None = None, companion: str | None = None, id_offset: int = 0) -> str:
    """The scenario stage of a replay (see the module's docstring); returns its path.

    With ``companion`` (a scenario stage) the replay sublayers it: its scenery, lights, camera agents and
    events come along, a person whose id one of its agents has is that agent (its group, attributes and
    clothes), the others join a group of their own; its clones and the agents the file does not have are
    switched off.
    """
    from pxr import Sdf

    from .. import schema
    from ..atomic import export_layer
    from .templates import replace_scenery

    layer = Sdf.Layer.CreateAnonymous(".usda")
    stage = _companion_stage(companion) if companion else None
    root = stage.GetDefaultPrim().GetName() if stage else "World"
    layer.defaultPrim = root
    layer.startTimeCode, layer.endTimeCode = 1.0, float(sampler.n_frames)
    layer.timeCodesPerSecond = layer.framesPerSecond = sampler.fps
    layer.pseudoRoot.SetInfo("upAxis", "Z")
    layer.pseudoRoot.SetInfo("metersPerUnit", 1.0)
    relative = lambda f: os.path.relpath(os.path.abspath(f), path.parent.resolve())  # noqa: E731
    about = {"source": relative(tracks.source), "format": tracks.fmt, "fileFps": float(tracks.fps)}
    if id_offset:
        about["idOffset"] = int(id_offset)          # agent id = the file's id + idOffset
    if companion:
        about["companion"] = relative(companion)
        layer.subLayerPaths = [relative(companion)]
    layer.customLayerData = {"usdcrowd": {"seed": int(seed), "replay": about}}
    layer.comment = (f"People replayed from {os.path.basename(tracks.source)} ({tracks.fmt}); "
                     "Z up, metres. Written by usdcrowd replay.")
    schema.author_fallbacks(layer)
    with Sdf.ChangeBlock():
        if stage is None:
            world = Sdf.CreatePrimInLayer(layer, "/World")
            world.specifier, world.typeName, world.kind = Sdf.SpecifierDef, "Xform", "assembly"
            _ground(layer, tracks.xy.min(axis=0), tracks.xy.max(axis=0))
        _people(layer, tracks, sampler.first_xy, heights, stage, root)
    if scenery is not None:
        replace_scenery(layer, scenery, path)
    export_layer(layer, path)
    return str(path)


def _companion_stage(companion: str):
    """The companion scenario, opened; refused unless Z up in metres with a default prim (the replay's
    positions are the file's metres)."""
    from pxr import UsdGeom

    from ..scenario import open_stage

    stage = open_stage(companion)
    if not stage.GetDefaultPrim():
        raise UsdcrowdError("a companion scenario needs a defaultPrim", file=companion)
    if UsdGeom.GetStageUpAxis(stage) != "Z" or abs(UsdGeom.GetStageMetersPerUnit(stage) - 1.0) > 1e-9:
        raise UsdcrowdError("a companion scenario must be Z up in metres, as the trajectories are", file=companion)
    return stage


def _ground(layer, lo: np.ndarray, hi: np.ndarray) -> None:
    """A flat floor under everywhere the people walk (``lo``, ``hi``: (2,) corners), GROUND_MARGIN wider."""
    from pxr import Gf, Sdf, Vt

    T = Sdf.ValueTypeNames
    lo, hi = lo - GROUND_MARGIN, hi + GROUND_MARGIN
    scope = Sdf.CreatePrimInLayer(layer, "/World/Scenery")
    scope.specifier, scope.typeName = Sdf.SpecifierDef, "Scope"
    mesh = Sdf.CreatePrimInLayer(layer, "/World/Scenery/Ground")
    mesh.specifier, mesh.typeName = Sdf.SpecifierDef, "Mesh"
    corners = [(lo[0], lo[1], 0), (hi[0], lo[1], 0), (hi[0], hi[1], 0), (lo[0], hi[1], 0)]
    for name, kind, value in (
            ("faceVertexCounts", T.IntArray, Vt.IntArray([4])),
            ("faceVertexIndices", T.IntArray, Vt.IntArray([0, 1, 2, 3])),
            ("points", T.Point3fArray, Vt.Vec3fArray([Gf.Vec3f(*map(float, c)) for c in corners])),
            ("extent", T.Float3Array, Vt.Vec3fArray([Gf.Vec3f(float(lo[0]), float(lo[1]), 0.0),
                                                    Gf.Vec3f(float(hi[0]), float(hi[1]), 0.0)])),
            ("primvars:displayColor", T.Color3fArray, Vt.Vec3fArray([Gf.Vec3f(0.5, 0.5, 0.48)]))):
        Sdf.AttributeSpec(mesh, name, kind).default = value
    Sdf.AttributeSpec(mesh, "subdivisionScheme", T.Token, Sdf.VariabilityUniform).default = "none"


def _people(layer, tracks, start: np.ndarray, heights: np.ndarray | None, companion=None,
            root: str = "World") -> None:
    """A person per track id, standing where they are first seen: the companion's agent of that id, or one
    of a walking CrowdGroup ``People``."""
    from pxr import Gf, Sdf

    T, U = Sdf.ValueTypeNames, Sdf.VariabilityUniform
    known = _companion_agents(companion)
    used = []
    for i, person in enumerate(tracks.ids):
        path = known.pop(int(person), None)
        if path is not None and str(companion.GetPrimAtPath(path).GetAttribute("crowd:role").Get()) == "invisibleLeader":
            raise UsdcrowdError(f"track {int(person)} is the companion's invisible leader: it would walk unseen; "
                                "give the track another id or the agent another role", file=tracks.source,
                                prim=path, attribute="crowd:role")
        if path is None:
            path = f"{_people_group(layer, companion, root)}/{person_name(person)}"
            spec = Sdf.CreatePrimInLayer(layer, path)
            spec.specifier, spec.typeName = Sdf.SpecifierDef, "SkelRoot"
            spec.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["CrowdAgentAPI"]))
            Sdf.AttributeSpec(spec, "crowd:agentId", T.Int, U).default = int(person)
        used.append(path)
        spec = Sdf.CreatePrimInLayer(layer, path)
        x, y = start[i]
        Sdf.AttributeSpec(spec, "crowd:startPosition", T.Point3f, U).default = Gf.Vec3f(float(x), float(y), 0.0)
        if heights is not None:
            Sdf.AttributeSpec(spec, "crowd:height", T.Float, U).default = float(heights[i])
    _switch_off(layer, companion, set(known.values()), used)


def _people_group(layer, companion, root: str) -> str:
    """The group of the people a companion does not have (made on first use)."""
    from pxr import Sdf

    T, U = Sdf.ValueTypeNames, Sdf.VariabilityUniform
    path = f"/{root}/Crowd/People"
    if layer.GetPrimAtPath(path):
        return path
    for where, kind in ((f"/{root}/Crowd", "Scope"), (path, "CrowdGroup")):
        if companion is None or not companion.GetPrimAtPath(where):
            spec = Sdf.CreatePrimInLayer(layer, where)
            spec.specifier, spec.typeName = Sdf.SpecifierDef, kind
    group = Sdf.CreatePrimInLayer(layer, path)      # an over where the companion has the group already
    for name, value in (("characterType", "human"), ("personality", "civilian"), ("behavior", "walk"),
                        ("condition", "isolated")):
        Sdf.AttributeSpec(group, f"crowd:{name}", T.Token, U).default = value
    return path


def _companion_agents(companion) -> dict[int, str]:
    """{crowd:agentId: prim path} of the companion's authored agents."""
    from .. import schema

    if companion is None:
        return {}
    return {int(p.GetAttribute("crowd:agentId").Get()): str(p.GetPath()) for p in companion.Traverse()
            if schema.is_agent(p) and p.GetAttribute("crowd:agentId").HasAuthoredValue()}


def _switch_off(layer, companion, unused: set[str], used: list[str]) -> None:
    """The companion's clones and the agents the file does not have (``unused``), off; then its groups
    that hold none of the ``used`` agents."""
    from pxr import Sdf

    if companion is None:
        return
    T, U = Sdf.ValueTypeNames, Sdf.VariabilityUniform
    for path in unused:
        Sdf.CreatePrimInLayer(layer, path).active = False
    groups = [p for p in companion.Traverse() if p.GetTypeName() == "CrowdGroup"]
    for g in groups:
        spec = Sdf.CreatePrimInLayer(layer, g.GetPath())
        Sdf.AttributeSpec(spec, "crowd:clones", T.Int, U).default = 0
    for g in groups:
        inside = f"{g.GetPath()}/"
        if not any(p.startswith(inside) for p in used):
            Sdf.CreatePrimInLayer(layer, g.GetPath()).active = False


def person_name(person: int) -> str:
    """The prim name of track id ``person`` (a prim name cannot hold a minus sign)."""
    return f"Person_{person}" if person >= 0 else f"Person_m{-person}"


def replay_shot(trajectories: str | os.PathLike, out_dir: str | os.PathLike, fmt: str | None = None,
                fps: float | None = None, shot_fps: float | None = None, scenery: str | None = None,
                height_from: str = "auto", seed: int = 0, cameras: int | None = None, max_gap_s: float = 2.0,
                events: bool = True, progress: bool = True, limits=None, companion: str | None = None):
    """Write a shot whose people follow ``trajectories``: ``replay.usda`` (its scenario), then the shot.

    Parameters
    ----------
    fmt, fps : see :func:`usdcrowd.exchange.recorded_tracks.read_tracks`.
    shot_fps : float, optional
        Frames per second of the shot; default :func:`shot_rate` of the file's.
    scenery : str, optional
        A USD file from a DCC tool for the people to walk in (placed as ``usdcrowd new --scenery`` places it).
    height_from : str
        One of HEIGHT_SOURCES: the file's Z (head heights), drawn from the seed, or the file's where usable.
    cameras : int, optional
        Camera agents that scout and track the shot's events (the overview camera comes besides);
        default: the companion's, else DEFAULT_CAMERAS.
    max_gap_s : float
        Longest gap in a person's rows interpolated across; longer, they leave and come back.
    companion : str, optional
        A scenario stage giving scenery, lights, camera agents, events and the attributes of the people
        whose ids its agents have (see :func:`write_scenario`).

    Returns
    -------
    ReplayResult
    """
    from ..atomic import output_dir, restored_on_failure
    from ..core.limits import DEFAULT
    from ..exchange.recorded_tracks import read_tracks
    from ..exchange.replay_motion import TrackSampler
    from .pipeline import author_shot

    if scenery is not None and companion is not None:
        raise UsdcrowdError("give --scenery or --scenario, not both: the companion scenario brings its scenery")
    if height_from not in HEIGHT_SOURCES:
        raise UsdcrowdError(f"--height-from is one of {', '.join(HEIGHT_SOURCES)}, got {height_from!r}")
    tracks = read_tracks(trajectories, fmt, fps)
    offset = _id_offset(tracks)
    tracks.ids = tracks.ids + offset
    rate = shot_fps or shot_rate(tracks.fps)
    limits = limits or DEFAULT
    if len(tracks) > limits.max_agents:
        raise UsdcrowdError(f"{len(tracks):,} people: more than the {limits.max_agents:,} accepted "
                            f"(raise it with --max-agents)", file=tracks.source)
    duration = float(tracks.seconds.max())
    if duration * rate + 1 > limits.max_frames:
        raise UsdcrowdError(f"{duration:.0f} s at {rate:g} fps is more than the {limits.max_frames:,} frames "
                            f"accepted (raise it with --max-frames)", file=tracks.source)
    sampler = TrackSampler(tracks, rate, max_gap_s)
    if sampler.n_frames < 2:
        raise UsdcrowdError("the file spans a single frame: nothing moves", file=tracks.source)
    heights = body_heights(tracks, height_from)
    out = Path(out_dir)
    scenario = out / SCENARIO
    output_dir(out, "shot")
    with restored_on_failure([scenario]):
        write_scenario(scenario, tracks, sampler, heights, seed, scenery, companion, offset)
        if cameras is None and companion is None:
            cameras = DEFAULT_CAMERAS
        shot = author_shot(scenario, out, _source(tracks, sampler), seed=seed, progress=progress,
                           camera_count=cameras, events=events, limits=limits, label="replay")
    return ReplayResult(shot, tracks.fmt, tracks.fps, len(tracks.frame), offset)


@dataclass
class ReplayResult:
    """What ``replay`` read and wrote: the shot, the file's layout and frame rate, its rows, and what was
    added to its ids (USD's and MOT's ids start at 1)."""

    shot: object
    fmt: str
    file_fps: float
    rows: int
    id_offset: int


def _id_offset(tracks) -> int:
    """What to add to the file's ids so the smallest is at least 1; refused where the largest would pass
    the largest agent id."""
    from ..scenario.ranges import MAX_AGENT_ID

    offset = max(0, 1 - int(tracks.ids.min()))
    if int(tracks.ids.max()) + offset > MAX_AGENT_ID:
        raise UsdcrowdError(f"person ids {int(tracks.ids.min())} to {int(tracks.ids.max())} do not fit usdcrowd's "
                            f"1 to {MAX_AGENT_ID:,}", file=tracks.source)
    return offset


def _source(tracks, sampler):
    """The replay's crowd source for :func:`~usdcrowd.jobs.pipeline.author_shot`: chunks of CHUNK_FRAMES
    frames, columns in the scenario's agent rows."""
    from ..exchange.replay_motion import ReplayMotion

    def source(scenario: model.Scenario):
        from ..sim.paths import Terrain

        column = {int(p): i for i, p in enumerate(tracks.ids)}
        lost = [k for k, a in enumerate(scenario.agents.agent_id) if int(a) not in column]
        if lost:
            raise UsdcrowdError("a companion scenario's agent without a crowd:agentId of the file's tracks stays "
                                "on: give it a track's id, or deactivate it", file=scenario.source,
                                prim=scenario.agents.path[lost[0]], attribute="crowd:agentId")
        order = np.array([column[int(a)] for a in scenario.agents.agent_id])
        terrain = Terrain(scenario.field("height"))
        height = np.empty(len(order))
        height[order] = scenario.agents.height
        motion = ReplayMotion(sampler, scenario.time.start, height, None if terrain.flat else terrain.height)
        for frames in motion.chunks(CHUNK_FRAMES):
            yield frames.agents(order)

    return source
