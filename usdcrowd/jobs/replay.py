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
    known = np.isfinite(z)
    heights = np.full(len(tracks), np.nan)
    if known.any():
        for i in np.unique(tracks.person[known]):
            heights[i] = np.median(z[known & (tracks.person == i)])
    usable = np.isfinite(heights).all() and ((heights >= BODY_HEIGHT_RANGE[0]) & (heights <= BODY_HEIGHT_RANGE[1])).all()
    if height_from == "file" and not usable:
        lo, hi = BODY_HEIGHT_RANGE
        raise UsdcrowdError(f"--height-from file needs every person's Z (head height) between {lo} and {hi} m",
                            file=tracks.source)
    return heights if usable else None


def write_scenario(path: Path, tracks, xy: np.ndarray, fps: float, heights: np.ndarray | None, seed: int,
                   scenery: str | None) -> str:
    """The scenario stage of a replay (see the module's docstring); returns its path."""
    from pxr import Sdf

    from .. import schema
    from ..atomic import export_layer
    from .templates import replace_scenery

    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.defaultPrim = "World"
    layer.startTimeCode, layer.endTimeCode = 1.0, float(len(xy))
    layer.timeCodesPerSecond = layer.framesPerSecond = fps
    layer.pseudoRoot.SetInfo("upAxis", "Z")
    layer.pseudoRoot.SetInfo("metersPerUnit", 1.0)
    source = os.path.relpath(os.path.abspath(tracks.source), path.parent.resolve())
    layer.customLayerData = {"usdcrowd": {"seed": int(seed), "replay": {
        "source": source, "format": tracks.fmt, "fileFps": float(tracks.fps)}}}
    layer.comment = (f"People replayed from {os.path.basename(tracks.source)} ({tracks.fmt}); "
                     "Z up, metres. Written by usdcrowd replay.")
    schema.author_fallbacks(layer)
    with Sdf.ChangeBlock():
        world = Sdf.CreatePrimInLayer(layer, "/World")
        world.specifier, world.typeName, world.kind = Sdf.SpecifierDef, "Xform", "assembly"
        _ground(layer, xy)
        _people(layer, tracks, xy, heights)
    if scenery is not None:
        replace_scenery(layer, scenery, path)
    export_layer(layer, path)
    return str(path)


def _ground(layer, xy: np.ndarray) -> None:
    """A flat floor under everywhere the people walk, GROUND_MARGIN wider."""
    from pxr import Gf, Sdf, Vt

    T = Sdf.ValueTypeNames
    lo, hi = np.nanmin(xy, axis=(0, 1)) - GROUND_MARGIN, np.nanmax(xy, axis=(0, 1)) + GROUND_MARGIN
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


def _people(layer, tracks, xy: np.ndarray, heights: np.ndarray | None) -> None:
    """One walking CrowdGroup, a person per track id, standing where they are first seen."""
    from pxr import Gf, Sdf

    T, U = Sdf.ValueTypeNames, Sdf.VariabilityUniform
    for path, kind in (("/World/Crowd", "Scope"), ("/World/Crowd/People", "CrowdGroup")):
        spec = Sdf.CreatePrimInLayer(layer, path)
        spec.specifier, spec.typeName = Sdf.SpecifierDef, kind
    group = layer.GetPrimAtPath("/World/Crowd/People")
    for name, value in (("characterType", "human"), ("personality", "civilian"), ("behavior", "walk"),
                        ("condition", "isolated")):
        Sdf.AttributeSpec(group, f"crowd:{name}", T.Token, U).default = value
    first = np.argmax(np.isfinite(xy[..., 0]), axis=0)
    for i, person in enumerate(tracks.ids):
        spec = Sdf.CreatePrimInLayer(layer, f"/World/Crowd/People/{person_name(person)}")
        spec.specifier, spec.typeName = Sdf.SpecifierDef, "SkelRoot"
        spec.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["CrowdAgentAPI"]))
        Sdf.AttributeSpec(spec, "crowd:agentId", T.Int, U).default = int(person)
        x, y = xy[first[i], i]
        Sdf.AttributeSpec(spec, "crowd:startPosition", T.Point3f, U).default = Gf.Vec3f(float(x), float(y), 0.0)
        if heights is not None:
            Sdf.AttributeSpec(spec, "crowd:height", T.Float, U).default = float(heights[i])


def person_name(person: int) -> str:
    """The prim name of track id ``person`` (a prim name cannot hold a minus sign)."""
    return f"Person_{person}" if person >= 0 else f"Person_m{-person}"


def replay_shot(trajectories: str | os.PathLike, out_dir: str | os.PathLike, fmt: str | None = None,
                fps: float | None = None, shot_fps: float | None = None, scenery: str | None = None,
                height_from: str = "auto", seed: int = 0, cameras: int = 4, max_gap_s: float = 2.0,
                events: bool = True, progress: bool = True, limits=None):
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
    cameras : int
        Camera agents that scout and track the shot's events (the overview camera comes besides).
    max_gap_s : float
        Longest gap in a person's rows interpolated across; longer, they leave and come back.

    Returns
    -------
    ShotResult
    """
    from ..atomic import output_dir, restored_on_failure
    from ..core.limits import DEFAULT
    from ..exchange.recorded_tracks import read_tracks
    from ..exchange.replay_motion import sample_tracks
    from .pipeline import author_shot

    if height_from not in HEIGHT_SOURCES:
        raise UsdcrowdError(f"--height-from is one of {', '.join(HEIGHT_SOURCES)}, got {height_from!r}")
    tracks = read_tracks(trajectories, fmt, fps)
    rate = shot_fps or shot_rate(tracks.fps)
    limits = limits or DEFAULT
    if len(tracks) > limits.max_agents:
        raise UsdcrowdError(f"{len(tracks):,} people: more than the {limits.max_agents:,} accepted "
                            f"(raise it with --max-agents)", file=tracks.source)
    duration = float(tracks.seconds.max())
    if duration * rate + 1 > limits.max_frames:
        raise UsdcrowdError(f"{duration:.0f} s at {rate:g} fps is more than the {limits.max_frames:,} frames "
                            f"accepted (raise it with --max-frames)", file=tracks.source)
    seconds, xy = sample_tracks(tracks, rate, max_gap_s)
    if len(seconds) < 2:
        raise UsdcrowdError("the file spans a single frame: nothing moves", file=tracks.source)
    heights = body_heights(tracks, height_from)
    out = Path(out_dir)
    scenario = out / SCENARIO
    output_dir(out, "shot")
    with restored_on_failure([scenario]):
        write_scenario(scenario, tracks, xy, rate, heights, seed, scenery)
        return author_shot(scenario, out, _source(tracks, xy, rate), seed=seed, progress=progress,
                           camera_count=cameras, events=events, limits=limits)


def _source(tracks, xy: np.ndarray, fps: float):
    """The replay's crowd source for :func:`~usdcrowd.jobs.pipeline.author_shot`: chunks of frames in the
    scenario's agent rows."""
    from ..exchange.replay_motion import chunks, crowd_frames

    def source(scenario: model.Scenario):
        from ..sim.paths import Terrain

        column = {int(p): i for i, p in enumerate(tracks.ids)}
        order = np.array([column[int(a)] for a in scenario.agents.agent_id])
        terrain = Terrain(scenario.field("height"))
        ground = None if terrain.flat else terrain.height
        frames = crowd_frames(xy[:, order], fps, scenario.time.start, scenario.agents.height, ground)
        return chunks(frames, 64)

    return source
