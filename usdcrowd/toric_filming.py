"""Toric cameras on an existing shot (seed 002): ``usdcrowd frame`` runs here.

The two characters come back from the shot's crowd layer (their heads and
shoulders, posed by the three-bone rig), a behavior of
:mod:`usdcrowd.cameras.behaviors` frames them, and the camera is added to
the shot's cameras.usda beside the others, with its behavior, shot size and
per-frame toric features (ToricCameraAPI).

Where the pair changes during the shot (``spans``), the new targets' head
positions and facings are blended in over ``transition`` seconds (section 7
of the seed: "their positions need to be interpolated to avoid a jump").
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import model, schema
from .errors import StageError

FOCAL_LENGTH = 50.0        # mm: a 40 degree horizontal field on 36 mm, within the seed's 30-45 degrees
APERTURE = 36.0            # mm, horizontal
TRANSITION = 1.0           # seconds a switch of pair takes


@dataclass(frozen=True)
class PairSpan:
    """From time code ``start`` on, the camera frames ``a`` (the main character) and ``b``."""

    start: float
    a: str
    b: str


@dataclass
class TargetSignals:
    """What a behavior follows, per frame (t frames).

    Attributes
    ----------
    heads_a, heads_b : (t, 3) float64
        Head points of A and B, metres (blended during a switch).
    yaw_a, yaw_b : (t,) float64
        Their shoulders' facing, radians.
    target_a, target_b : list[str]
        Prim paths of A and B (the new pair from a switch's first frame).
    """

    heads_a: np.ndarray
    heads_b: np.ndarray
    yaw_a: np.ndarray
    yaw_b: np.ndarray
    target_a: list[str]
    target_b: list[str]


def check_spans(scene, spans: list[PairSpan]) -> list[tuple[float, int, int]]:
    """Rows of each span's agents, refusing what cannot be filmed.

    Raises
    ------
    StageError
        An agent that is not in the shot, the same agent twice, or spans
        that do not start in order within the shot.
    """
    if not spans:
        raise StageError("no characters to frame: give --targets A B", file=scene.path)
    out = []
    lo, hi = float(scene.time_codes[0]), float(scene.time_codes[-1])
    for k, span in enumerate(spans):
        ia, ib = scene.agent_row(span.a), scene.agent_row(span.b)
        if ia == ib:
            raise StageError(f"the two targets are the same agent ({scene.agent_paths[ia]}): a toric camera "
                             "frames two characters", file=scene.path, prim=scene.agent_paths[ia])
        if k and span.start <= spans[k - 1].start:
            raise StageError(f"pair switches must be in order: frame {span.start:g} comes after "
                             f"{spans[k - 1].start:g}", file=scene.path)
        if k and not lo < span.start <= hi:
            raise StageError(f"switch at frame {span.start:g} is outside the shot's frames {lo:g}-{hi:g}",
                             file=scene.path)
        out.append((float(span.start) if k else lo, ia, ib))
    return out


def target_signals(scene, spans: list[PairSpan], times, transition: float = TRANSITION,
                   progress: bool = False) -> TargetSignals:
    """Heads and facings of the characters each span frames, blended across switches.

    Only the agents named in ``spans`` are posed.
    """
    from .cameras.features import head_and_facing
    from .pipeline import frame_progress

    rows = check_spans(scene, spans)
    times = np.asarray(times, dtype=np.float64)
    needed = sorted({r for _, ia, ib in rows for r in (ia, ib)})
    col = {r: k for k, r in enumerate(needed)}
    heads = np.zeros((len(times), len(needed), 3))
    yaws = np.zeros((len(times), len(needed)))
    with frame_progress(len(times), "read characters", progress) as bar:
        for i, t in enumerate(times):
            heads[i], yaws[i] = head_and_facing(scene.agents(t, needed).joints_world)
            bar.update(1)
    starts = np.array([s for s, _, _ in rows])
    span = np.searchsorted(starts, times, side="right") - 1
    span = np.maximum(span, 0)
    fa = np.array([col[rows[k][1]] for k in span])
    fb = np.array([col[rows[k][2]] for k in span])
    idx = np.arange(len(times))
    ha, hb, ya, yb = heads[idx, fa], heads[idx, fb], yaws[idx, fa], yaws[idx, fb]
    fps = float(scene.fps)
    for k in range(1, len(rows)):
        start, _, _ = rows[k]
        _, pa, pb = rows[k - 1]
        w = np.clip((times - start) / max(transition * fps, 1e-9), 0.0, 1.0)
        w = w * w * (3.0 - 2.0 * w)                       # smoothstep: no jump in speed at either end
        during = (times >= start) & (w < 1.0)
        if not during.any():
            continue
        wd = w[during][:, None]
        ha[during] = (1 - wd) * heads[during, col[pa]] + wd * ha[during]
        hb[during] = (1 - wd) * heads[during, col[pb]] + wd * hb[during]
        ya[during] = _blend_angle(yaws[during, col[pa]], ya[during], wd[:, 0])
        yb[during] = _blend_angle(yaws[during, col[pb]], yb[during], wd[:, 0])
    paths = scene.agent_paths
    return TargetSignals(ha, hb, ya, yb, [paths[rows[k][1]] for k in span], [paths[rows[k][2]] for k in span])


def auto_spans(scene, span: float = 5.0, step: float = 0.5, reach: float = 4.0, keep: float = 0.5,
               progress: bool = False) -> list[PairSpan]:
    """The pair to frame in each ``span`` seconds of a shot with many characters.

    Every ``step`` seconds the visible agents' ground positions are sampled;
    pairs that come within ``reach`` metres are candidates. A candidate's
    cost over a span is its mean distance (a sample where either is hidden
    counts as ``2 * reach``), less ``reach`` for the share of the span they
    spend together in a CrowdEvent of two (a talk, a trade): the
    two-character moments the scene itself declares. A span keeps the pair
    of the span before while its cost is within ``keep`` metres of the
    best, so the camera does not switch for a small gain.

    Returns
    -------
    list[PairSpan]
        Consecutive spans with the same pair merged; the first starts at the
        shot's first frame.

    Raises
    ------
    StageError
        No two visible agents ever come within ``reach`` of each other.
    """
    from scipy.spatial import cKDTree

    from .pipeline import frame_progress
    from .scenario.events import read_events
    from .scenario.stageio import time_range

    times = scene.time_codes
    fps = float(scene.fps)
    samples = times[:: max(1, int(round(step * fps)))]
    n = len(scene.agent_paths)
    ground = np.zeros((len(samples), n, 2))
    visible = np.zeros((len(samples), n), dtype=bool)
    with frame_progress(len(samples), "find pairs", progress) as bar:
        for i, t in enumerate(samples):
            poses = scene.agents(t)
            ground[i], visible[i] = poses.keypoints()[:, -1, :2], poses.visible
            bar.update(1)
    pairs = set()
    for i in range(len(samples)):
        rows = np.flatnonzero(visible[i])
        if len(rows) > 1:
            pairs |= {(int(rows[a]), int(rows[b])) for a, b in cKDTree(ground[i, rows]).query_pairs(reach)}
    if not pairs:
        raise StageError(f"no two visible characters come within {reach:g} m of each other: name the pair with "
                         "--targets A B", file=scene.path)
    pairs = np.array(sorted(pairs))
    dist = np.linalg.norm(ground[:, pairs[:, 0]] - ground[:, pairs[:, 1]], axis=-1)
    dist = np.where(visible[:, pairs[:, 0]] & visible[:, pairs[:, 1]], dist, 2 * reach)
    together = np.zeros_like(dist)
    rows = {p: i for i, p in enumerate(scene.agent_paths)}
    index = {(int(a), int(b)): k for k, (a, b) in enumerate(pairs)}
    for event in read_events(scene.stage, rows, time_range(scene.stage)):
        if len(event.members) != 2 or event.start > event.end:
            continue
        k = index.get(tuple(sorted(int(m) for m in event.members)))
        if k is not None:
            together[:, k] = (samples >= event.start) & (samples <= event.end)
    cost = dist - reach * together
    edges = np.arange(times[0], times[-1] + 1e-9, span * fps)
    out, current = [], None
    for start in edges:
        inside = (samples >= start) & (samples < start + span * fps)
        mean = cost[inside].mean(axis=0) if inside.any() else cost[-1:].mean(axis=0)
        best = int(np.argmin(mean))
        if current is None or mean[current] - mean[best] > keep:
            current = best
        a, b = (scene.agent_paths[r] for r in pairs[current])
        if not out or (out[-1].a, out[-1].b) != (a, b):
            out.append(PairSpan(float(start), a, b))
    return out


def _blend_angle(a: np.ndarray, b: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Angles from a to b by w, the short way round."""
    return np.arctan2((1 - w) * np.sin(a) + w * np.sin(b), (1 - w) * np.cos(a) + w * np.cos(b))


def shot_obstacles(scene):
    """The scenery footprints of the scenario a shot refers to (none if it names no scenario)."""
    from .scenario import load_scenario

    ref = dict(scene.stage.GetRootLayer().customLayerData.get("usdcrowd", {})).get("scenario")
    if not ref:
        return None
    return load_scenario(os.path.join(os.path.dirname(os.path.abspath(scene.path)), ref)).obstacles


def camera_name(behavior: str, a: str, b: str, auto: bool = False) -> str:
    """A valid prim name for a behavior's camera on A and B, e.g. ``Orbit_A_B`` (``Orbit_Pairs`` for many)."""
    from pxr import Tf

    parts = [behavior.replace("-", " ").title().replace(" ", "")]
    parts += ["Pairs"] if auto else [a.rsplit("/", 1)[-1], b.rsplit("/", 1)[-1]]
    return Tf.MakeValidIdentifier("_".join(parts))


def frame_shot(shot_path: str | os.PathLike, behavior, spans: list[PairSpan] | str, name: str | None = None,
               smooth: bool = False, focal_length: float = FOCAL_LENGTH, aspect: float = 16 / 9,
               transition: float = TRANSITION, span: float = 5.0, progress: bool = True):
    """Add a toric camera following ``behavior`` on the shot's characters to its cameras.usda.

    Parameters
    ----------
    shot_path : path-like
        The shot stage (shot.usda).
    behavior : Behavior
        See :mod:`usdcrowd.cameras.behaviors`.
    spans : list[PairSpan] or "auto"
        The pair framed, from each span's start (the first span from the
        shot's start); "auto": chosen per ``span`` seconds (:func:`auto_spans`).
    name : str, optional
        Camera prim name (default from the behavior and the first pair).
    smooth : bool
        Smooth the final track (seed 002, section 7.2).
    focal_length : float
        mm, on a 36 mm horizontal aperture.
    aspect : float
        Width / height of the images it is framed for.

    Returns
    -------
    path : str
        The cameras layer written.
    track : CameraTrack
    features : BehaviorTrack
        The toric coordinates authored (of the smoothed track when smoothed).
    signals : TargetSignals
    """
    from .cameras.behaviors import BehaviorTrack, behavior_track
    from .cameras.smoothing import smooth_track
    from .cameras.toric import ToricError, pose_to_toric
    from .render.scene import ShotScene
    from .usd.cameras import CAMERAS, add_camera

    scene = ShotScene(shot_path)
    cameras = Path(scene.path).parent / CAMERAS
    if not cameras.is_file():
        raise StageError("the shot has no cameras layer to add a camera to", file=os.fspath(cameras))
    times = scene.time_codes
    if isinstance(spans, str):
        spans = auto_spans(scene, span, progress=progress)
    rows = check_spans(scene, spans)
    root = scene.stage.GetDefaultPrim()
    prim_name = name or camera_name(behavior.name, scene.agent_paths[rows[0][1]], scene.agent_paths[rows[0][2]],
                                    auto=len(rows) > 1)
    path = f"{root.GetPath() if root else ''}/Cameras/{prim_name}"
    existing = scene.stage.GetPrimAtPath(path)
    if existing and not existing.HasAPI(schema.TORIC_CAMERA_API):
        raise StageError("a camera that is not a toric camera already has this name (choose another with --name)",
                         file=scene.path, prim=path)
    signals = target_signals(scene, spans, times, transition, progress)
    fov_x = 2.0 * np.arctan(0.5 * APERTURE / focal_length)
    result = behavior_track(behavior, times, scene.fps, signals.heads_a, signals.heads_b, signals.yaw_a,
                            signals.yaw_b, fov_x, aspect, obstacles=shot_obstacles(scene))
    if smooth:
        m = smooth_track(result.cam_to_world)
        toric = np.full((len(times), 6), np.nan)
        for i in range(len(times)):
            try:
                p_a, p_b, theta, phi = pose_to_toric(m[i], signals.heads_a[i], signals.heads_b[i], fov_x, aspect)
            except ToricError:              # smoothing put a head behind the camera: no screen position
                continue
            toric[i] = [*p_a, *p_b, theta, phi]
        result = BehaviorTrack(m, toric[:, 0:2], toric[:, 2:4], toric[:, 4], toric[:, 5], result.distance)
    track = model.CameraTrack(path, times.copy(), result.cam_to_world, np.full(len(times), focal_length),
                              APERTURE, APERTURE / aspect, near=0.05, far=1000.0)
    written = add_camera(cameras, track, {
        "behavior": behavior.name, "shot_size": behavior.shot, "smoothed": smooth,
        "target_a": signals.target_a, "target_b": signals.target_b,
        "p_a": result.p_a, "p_b": result.p_b, "theta": result.theta, "phi": result.phi})
    return written, track, result, signals
