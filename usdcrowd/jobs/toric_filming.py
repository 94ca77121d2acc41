"""Toric cameras on an existing shot (seed 002): ``usdcrowd frame`` and ``usdcrowd features`` run here.

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
from typing import TYPE_CHECKING
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core import model
from .. import schema
from ..core.errors import StageError, UsdcrowdError
from ..usd.cameras import CAMERAS as CAMERAS_LAYER

if TYPE_CHECKING:
    from ..cameras.features import CinematicFeatures

FOCAL_LENGTH = 50.0        # mm: a 40 degree horizontal field on 36 mm, within the seed's 30-45 degrees
APERTURE = 36.0            # mm, horizontal
TRANSITION = 1.0           # seconds a switch of pair takes
STYLE_TRANSITION = 2.0     # seconds a learned camera takes to pass from one reference's style to the next


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


def shot_features(shot, camera: str | None, agent_a: str, agent_b: str, times=None,
                  width: int = 1920, height: int = 1080) -> tuple[CinematicFeatures, dict]:
    """Cinematic features of a shot's camera filming two of its agents.

    Parameters
    ----------
    shot : path-like or ShotScene
    camera : str or None
        Camera prim path (None: the first camera).
    agent_a, agent_b : str
        Agent prim paths, or their last path component when it is unique.
    times : sequence of float, optional
        Time codes (default: every frame of the shot).
    width, height : int
        Image size the screen boxes are measured in (its aspect is the framing's).

    Returns
    -------
    features : CinematicFeatures
    about : dict
        Camera and agent paths, field of view and aspect (for the JSON).
    """
    from ..cameras.features import cinematic_features, head_and_facing
    from ..scenario.shot_scene import ShotScene

    scene = shot if isinstance(shot, ShotScene) else ShotScene(shot)
    paths = scene.agent_paths
    ia, ib = agent_row(scene, agent_a), agent_row(scene, agent_b)
    times = np.asarray(scene.time_codes if times is None else times, dtype=np.float64)
    scene.check_times(times)
    heads, yaws, grounds, boxes, mats, fovs = [], [], [], [], [], []
    view = None
    for t in times:
        view = scene.camera(camera, t)
        poses = scene.agents(t, [ia, ib])
        head, yaw = head_and_facing(poses.joints_world)
        key = poses.keypoints()
        uv, z = view.project(key, width, height)
        size = np.where((z > 0).all(axis=1), np.ptp(uv[..., 0], axis=1) * np.ptp(uv[..., 1], axis=1), 0.0)
        heads.append(head)
        yaws.append(yaw)
        grounds.append(key[:, -1])
        boxes.append(size)
        mats.append(view.cam_to_world)
        fovs.append(np.radians(view.fov_x()))          # per frame: a zooming camera's lens changes
    heads, yaws, grounds, boxes, fovs = (np.array(v) for v in (heads, yaws, grounds, boxes, fovs))
    aspect = width / height
    features = cinematic_features(times, heads[:, 0], heads[:, 1], yaws[:, 0], yaws[:, 1], grounds[:, 0],
                                  grounds[:, 1], boxes[:, 0], boxes[:, 1], np.array(mats), fovs, aspect)
    about = {"shot": scene.path, "camera": view.path, "A": paths[ia], "B": paths[ib],
             "fov_x_deg": [float(v) for v in np.degrees(fovs)] if np.ptp(fovs) > 0 else float(np.degrees(fovs[0])),
             "aspect": aspect}
    return features, about


def agent_row(scene, name: str) -> int:
    """``scene.agent_row(name)``; when no agent has that name, the error suggests the nearest ones.

    Raises
    ------
    StageError
        No such agent (the nearest names suggested), or more than one with that name.
    """
    paths = scene.agent_paths
    if any(p == name or p.rsplit("/", 1)[-1] == name for p in paths):
        return scene.agent_row(name)            # one, or several to tell apart by path
    near = nearest_agents(name, paths)
    hint = f"did you mean {' or '.join(repr(n) for n in near)}? " if near else ""
    raise StageError(f"no agent named {name!r} in this stage ({hint}`usdcrowd inspect {scene.path} --agents` lists "
                     f"its {len(paths)} agents)", file=scene.path, prim=name)


def nearest_agents(name: str, paths: list[str], n: int = 3) -> list[str]:
    """Up to ``n`` agents whose names (or, for a ``name`` with a slash, paths) are nearest ``name``,
    ignoring case: by name where the name is unique, else by path."""
    import difflib
    from collections import Counter

    names = [p.rsplit("/", 1)[-1] for p in paths]
    count = Counter(names)
    shown: dict[str, list[str]] = {}
    for key, nm, path in zip(paths if "/" in name else names, names, paths):
        shown.setdefault(key.lower(), []).append(nm if count[nm] == 1 else path)
    hits = difflib.get_close_matches(name.lower(), list(shown), n=n, cutoff=0.6)
    return list(dict.fromkeys(s for h in hits for s in shown[h]))[:n]


def _hidden(scene, row: int, time: float) -> str | None:
    """Why the agent at ``row`` is not seen at ``time`` (an invisible leader, or hidden), or None."""
    from pxr import UsdGeom

    prim = scene.stage.GetPrimAtPath(scene.agent_paths[row])
    role = prim.GetAttribute("crowd:role")
    if role and role.Get() == "invisibleLeader":
        return "an invisible leader (crowd:role = invisibleLeader)"
    if UsdGeom.Imageable(prim).ComputeVisibility(time) == UsdGeom.Tokens.invisible:
        return f"invisible at frame {time:g} (visibility)"
    return None


def check_spans(scene, spans: list[PairSpan]) -> list[tuple[float, int, int]]:
    """Rows of each span's agents, refusing what cannot be filmed.

    Raises
    ------
    StageError
        An agent that is not in the shot (the nearest names suggested) or
        that is not visible, the same agent twice, or spans that do not
        start in order within the shot.
    """
    if not spans:
        raise StageError("no characters to frame: give --targets A B", file=scene.path)
    out = []
    lo, hi = float(scene.time_codes[0]), float(scene.time_codes[-1])
    for k, span in enumerate(spans):
        ia, ib = agent_row(scene, span.a), agent_row(scene, span.b)
        for row in (ia, ib):
            why = _hidden(scene, row, float(span.start) if k else lo)
            if why:
                raise StageError(f"the target {scene.agent_paths[row]} is {why}: a toric camera frames two "
                                 f"characters the viewer sees; choose another (`usdcrowd inspect {scene.path} "
                                 "--agents` says which are visible)", file=scene.path, prim=scene.agent_paths[row])
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
    from ..cameras.features import head_and_facing
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
    from ..scenario.events import read_events
    from ..scenario.stageio import time_range

    times = scene.time_codes
    fps = float(scene.fps)
    if not span * fps >= 1.0:               # else a span a frame: countless edges
        raise StageError(f"a span (--span) of {span:g} s is shorter than a frame (1/{fps:g} s)", file=scene.path)
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
    from ..scenario import shot_scenario

    scenario = shot_scenario(scene)
    return None if scenario is None else scenario.obstacles


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
    from ..cameras.behaviors import behavior_track
    from ..cameras.smoothing import smooth_track
    from ..scenario.shot_scene import ShotScene

    scene = ShotScene(shot_path)
    times = scene.time_codes
    if isinstance(spans, str):
        spans = auto_spans(scene, span, progress=progress)
    rows = check_spans(scene, spans)
    path = _camera_path(scene, name or camera_name(behavior.name, scene.agent_paths[rows[0][1]],
                                                    scene.agent_paths[rows[0][2]], auto=len(rows) > 1))
    signals = target_signals(scene, spans, times, transition, progress)
    fov_x = 2.0 * np.arctan(0.5 * APERTURE / focal_length)
    result = behavior_track(behavior, times, scene.fps, signals.heads_a, signals.heads_b, signals.yaw_a,
                            signals.yaw_b, fov_x, aspect, obstacles=shot_obstacles(scene))
    if smooth:
        result = _track_features(smooth_track(result.cam_to_world), signals, fov_x, aspect)
    track = _camera_track(path, times, result.cam_to_world, focal_length, aspect)
    written = _author(scene, track, result, signals, behavior.name, behavior.shot, smooth)
    return written, track, result, signals


def _camera_path(scene, prim_name: str) -> str:
    """/<default prim>/Cameras/<name>, refusing a name a camera that is not toric already has."""
    root = scene.stage.GetDefaultPrim()
    path = f"{root.GetPath() if root else ''}/Cameras/{prim_name}"
    existing = scene.stage.GetPrimAtPath(path)
    if existing and not existing.HasAPI(schema.TORIC_CAMERA_API):
        raise StageError("a camera that is not a toric camera already has this name (choose another with --name)",
                         file=scene.path, prim=path)
    cameras = Path(scene.path).parent / CAMERAS_LAYER
    if not cameras.is_file():
        raise StageError("the shot has no cameras layer to add a camera to", file=os.fspath(cameras))
    return path


def _track_features(m: np.ndarray, signals: TargetSignals, fov_x: float, aspect: float):
    """A BehaviorTrack of given poses: their toric coordinates (NaN where a head is behind the camera)."""
    from ..cameras.behaviors import BehaviorTrack
    from ..cameras.toric import ToricError, pose_to_toric

    toric = np.full((len(m), 6), np.nan)
    for i in range(len(m)):
        try:
            p_a, p_b, theta, phi = pose_to_toric(m[i], signals.heads_a[i], signals.heads_b[i], fov_x, aspect)
        except ToricError:
            continue
        toric[i] = [*p_a, *p_b, theta, phi]
    mid = 0.5 * (signals.heads_a + signals.heads_b)
    return BehaviorTrack(m, toric[:, 0:2], toric[:, 2:4], toric[:, 4], toric[:, 5],
                         np.linalg.norm(m[:, 3, :3] - mid, axis=1))


def _camera_track(path: str, times, m: np.ndarray, focal_length: float, aspect: float) -> model.CameraTrack:
    return model.CameraTrack(path, np.array(times, dtype=np.float64), m, np.full(len(times), focal_length),
                             APERTURE, APERTURE / aspect, near=0.05, far=1000.0)


def _author(scene, track, result, signals: TargetSignals, behavior: str, shot_size: str, smooth: bool,
            extra: dict | None = None) -> str:
    from ..scenario.parent_space import ParentSpace
    from ..usd.cameras import add_camera

    intent = {"behavior": behavior, "shot_size": shot_size, "smoothed": smooth,
              "target_a": signals.target_a, "target_b": signals.target_b,
              "p_a": result.p_a, "p_b": result.p_b, "theta": result.theta, "phi": result.phi, **(extra or {})}
    return add_camera(Path(scene.path).parent / CAMERAS_LAYER, track, intent,
                      parents=ParentSpace(scene.stage, track.times))


# ------------------------------------------------------------------ learned behaviors (section 5)
@dataclass
class Reference:
    """A reference clip read from a stage: a camera filming two characters."""

    path: str
    camera: str
    a: str
    b: str
    character: np.ndarray      # (t, 10)
    camera_features: np.ndarray  # (t, 8)
    shot_size: str
    from_clip: bool = False    # estimated from a film clip's 2D poses: its pair motion is unknown

    @property
    def model_path(self) -> Path:
        """The camera model that reads it (:data:`usdcrowd.cameras.moe.CLIP_WEIGHTS` for a film clip)."""
        from ..cameras.moe import CLIP_WEIGHTS, WEIGHTS

        return CLIP_WEIGHTS if self.from_clip else WEIGHTS


def read_reference(shot_path, camera: str | None = None, targets: tuple[str, str] | None = None,
                   progress: bool = False) -> Reference:
    """The cinematic features of a reference stage's camera filming two characters.

    Without ``camera`` the reference's toric camera is taken (its first, in
    stage order, when it has several). Without ``targets`` the camera must be
    a toric camera (its first targets are taken). Frames where a head is
    behind the camera carry the last frame's camera features.

    Raises
    ------
    StageError
        No such camera, no toric camera to take, no targets to take, or no
        frame that frames both heads.
    """
    from ..cameras.features import head_and_facing
    from ..cameras.moe import camera_features, character_features, frame_span
    from ..cameras.toric import ToricError, pose_to_toric
    from .pipeline import frame_progress
    from ..scenario.shot_scene import ShotScene

    scene = ShotScene(shot_path)
    times = scene.time_codes
    first = scene.camera(camera if camera is not None else toric_camera(scene), times[0])
    if targets is None:
        if first.toric is None:
            raise StageError("the reference camera is not a toric camera: name its two characters with "
                             "--like-targets A B", file=scene.path, prim=first.path)
        targets = (first.toric["target_a"], first.toric["target_b"])
    rows = [agent_row(scene, targets[0]), agent_row(scene, targets[1])]
    if rows[0] == rows[1]:
        raise StageError("the reference's two characters are the same agent", file=scene.path, prim=targets[0])
    heads = np.zeros((len(times), 2, 3))
    eyes = np.zeros((len(times), 3))
    yaws = np.zeros((len(times), 2))
    toric = np.full((len(times), 6), np.nan)
    fov_x, aspect = np.radians(first.fov_x()), first.horizontal_aperture / first.vertical_aperture
    with frame_progress(len(times), "read reference", progress) as bar:
        for i, t in enumerate(times):
            heads[i], yaws[i] = head_and_facing(scene.agents(t, rows).joints_world)
            view = scene.camera(first.path, t)
            eyes[i] = view.cam_to_world[3, :3]
            try:
                p_a, p_b, theta, phi = pose_to_toric(view.cam_to_world, heads[i, 0], heads[i, 1], fov_x, aspect)
                toric[i] = [*p_a, *p_b, theta, phi]
            except ToricError:
                pass
            bar.update(1)
    ok = np.isfinite(toric).all(axis=1)
    if not ok.any():
        raise StageError("the reference camera never has both characters in front of it", file=scene.path,
                         prim=first.path)
    last = np.maximum.accumulate(np.where(ok, np.arange(len(ok)), -1))
    toric = toric[np.where(last >= 0, last, int(np.argmax(ok)))]
    cam = camera_features(toric[:, 0:2], toric[:, 2:4], toric[:, 4], toric[:, 5],
                          frame_span(eyes, heads[:, 0], fov_x, aspect))
    char = character_features(heads[:, 0], heads[:, 1], yaws[:, 0], yaws[:, 1], scene.fps)
    size = first.toric["shot_size"] if first.toric and first.toric["shot_size"] else _shot_size_of(
        heads[:, 0], np.array([scene.camera(first.path, t).cam_to_world for t in times[:: max(1, len(times) // 24)]]),
        times, fov_x, aspect)
    return Reference(scene.path, first.path, scene.agent_paths[rows[0]], scene.agent_paths[rows[1]], char, cam, size)


def read_clip_reference(path, focal_length: float = FOCAL_LENGTH, fps: float | None = None, progress: bool = False,
                        char_mean=None) -> Reference:
    """The cinematic features of a film clip (a video, or a folder of frames), estimated from 2D poses.

    The two main characters' poses are detected and associated
    (:mod:`usdcrowd.cameras.clip_poses`), brought to the learned model's frame
    rate, and turned into features by :class:`usdcrowd.cameras.estimator.FeatureEstimator`
    (section 4). A is the main character (appendix B: the larger on screen,
    on average over the frames where both are found). ``focal_length`` is the clip's lens (mm on a 36 mm aperture);
    ``fps`` the clip's frame rate where the file does not say (a folder).

    Raises
    ------
    UsdcrowdError
        Not readable, the pose detector missing (the ``video`` extra), or two
        people in too few frames.
    """
    from ..cameras import clip_poses
    from ..cameras.estimator import FeatureEstimator
    from ..cameras.moe import CLIP_WEIGHTS, SPAN, CameraMoE
    from ..cameras.moe_data import ASPECT, FOV_X, FPS
    from .pipeline import frame_progress

    frames, clip_fps = clip_poses.read_frames(path)
    fps = clip_fps or fps or FPS
    with frame_progress(len(frames), "detect poses", progress) as bar:
        per_frame = clip_poses.detect(frames, lambda: bar.update(1))
    joints, found = clip_poses.associate(per_frame, clip_poses.torso_colours(frames, per_frame))
    both = float(found.all(axis=1).mean())
    if both < clip_poses.MIN_FOUND:
        raise UsdcrowdError(f"two people found in only {100 * both:.0f} % of the clip's {len(frames)} frames "
                            f"(at least {100 * clip_poses.MIN_FOUND:.0f} % needed)", file=os.fspath(path))
    h, w = frames[0].shape[:2]
    joints = clip_poses.to_ndc(clip_poses.fill(joints, found), w, h, focal_length, FOV_X, ASPECT)
    main = clip_poses.main_character(joints, found)
    if main == 1:                                 # A is the main character, as a stage's first target is
        joints = joints[:, ::-1]
    if abs(fps - FPS) > 1e-6:                 # the estimator's window and the gate's steps are in the model's frames
        src = np.arange(len(joints)) / fps
        dst = np.arange(0.0, src[-1] + 1e-9, 1.0 / FPS)
        flat = joints.reshape(len(joints), -1)
        joints = np.column_stack([np.interp(dst, src, col) for col in flat.T]).reshape(-1, *joints.shape[1:])
    if char_mean is None:
        char_mean = CameraMoE(CLIP_WEIGHTS).w["char_mean"]
    char, cam = FeatureEstimator().features(joints, char_mean)
    return Reference(os.fspath(path), "the camera", "the main character", "the other", char, cam,
                     _nearest_shot_size(float(np.exp(np.median(cam[:, SPAN])))), from_clip=True)


def toric_camera(scene) -> str:
    """The path of a stage's toric camera (ToricCameraAPI, or a ``crowd:toric:behavior``): its first.

    Raises
    ------
    StageError
        The stage has none (its cameras named).
    """
    for path in scene.camera_paths:
        prim = scene.stage.GetPrimAtPath(path)
        if prim.HasAPI(schema.TORIC_CAMERA_API) or prim.HasAttribute("crowd:toric:behavior"):
            return path
    raise StageError(f"the reference has no toric camera (its cameras: {', '.join(scene.camera_paths) or 'none'}): "
                     "name the one to learn from with --camera, and its characters with --like-targets A B",
                     file=scene.path)


def _shot_size_of(heads_a: np.ndarray, cams: np.ndarray, times, fov_x: float, aspect: float) -> str:
    """The shot size whose span is nearest (in ratio) the one the camera's distance to A gives."""
    from ..cameras.behaviors import fov_y

    idx = np.linspace(0, len(heads_a) - 1, len(cams)).round().astype(int)
    dist = np.linalg.norm(cams[:, 3, :3] - heads_a[idx], axis=1).mean()
    return _nearest_shot_size(2 * dist * np.tan(0.5 * fov_y(fov_x, aspect)))


def _nearest_shot_size(span: float) -> str:
    """The shot size whose span (metres the frame's height covers at A) is nearest ``span``, in ratio."""
    from ..cameras.behaviors import SHOT_SIZES

    return min(SHOT_SIZES, key=lambda k: abs(np.log(SHOT_SIZES[k].span / span)))


def frame_like(shot_path, reference: Reference | list[tuple[Reference, float]], spans: list[PairSpan] | str, name: str | None = None,
               smooth: bool = False, focal_length: float = FOCAL_LENGTH, aspect: float = 16 / 9,
               span: float = 5.0, model=None, progress: bool = True):
    """Add a camera that films the shot's pair the way the reference's camera filmed its own (section 5).

    The gating network reads the reference's features once (the behavior mix
    it shows); the prediction network, with the experts blended by it, is
    rolled out over the new pair's character features, its first framing
    made from the gate and the characters alone (a blind start, settled
    over :data:`usdcrowd.cameras.retarget.SETTLE_FRAMES` frames before the shot).
    ``reference`` may be a list of (reference, from time code) pairs: the
    style switches over time. Each reference's style is rolled out over the
    whole shot, and the camera passes from one to the next over
    :data:`STYLE_TRANSITION` seconds (:func:`usdcrowd.cameras.retarget.blend_features`):
    the network, fed its own past, keeps a camera where it is, so blending
    the experts alone left it where the first style had put it.

    Returns
    -------
    path, track, features, signals, weights
        As :func:`frame_shot`, and the gating network's expert weights: (m,),
        or (n, m), one row per reference, with several.
    """
    from ..cameras.behaviors import clear_of_obstacles
    from ..cameras.moe import CameraMoE, character_features, eyes_of_features, level_camera, screen_height
    from ..cameras.retarget import blend_features, retarget_features, switch_weights
    from ..cameras.smoothing import smooth_track
    from ..scenario.shot_scene import ShotScene

    models = {}

    def model_for(r: Reference):        # a stage reference and a film clip are read by their own models
        if model is not None:
            return model
        if r.model_path not in models:
            models[r.model_path] = CameraMoE(r.model_path)
        return models[r.model_path]

    scene = ShotScene(shot_path)
    times = scene.time_codes
    if isinstance(spans, str):
        spans = auto_spans(scene, span, progress=progress)
    rows = check_spans(scene, spans)
    path = _camera_path(scene, name or camera_name("learned", scene.agent_paths[rows[0][1]],
                                                    scene.agent_paths[rows[0][2]], auto=len(rows) > 1))
    signals = target_signals(scene, spans, times, TRANSITION, progress)
    timeline = reference if isinstance(reference, list) else [(reference, times[0])]
    reference = timeline[0][0]
    gates = [model_for(r).gate(r.character, r.camera_features) for r, _ in timeline]
    char = character_features(signals.heads_a, signals.heads_b, signals.yaw_a, signals.yaw_b, scene.fps)
    fov_x = 2.0 * np.arctan(0.5 * APERTURE / focal_length)
    # A model trained with blind samples frames the new pair itself; the reference's first framing is
    # another pair's (an older model starts from it).
    cams = [retarget_features(model_for(r), g, char, None if model_for(r).config.blind > 0 else r.camera_features[0])
            for g, (r, _) in zip(gates, timeline)]
    cam = cams[0] if len(cams) == 1 else blend_features(
        cams, switch_weights([f for _, f in timeline], times, scene.fps, STYLE_TRANSITION))
    eye = eyes_of_features(cam, signals.heads_a, signals.heads_b, fov_x, aspect)
    obstacles = shot_obstacles(scene)
    if obstacles is not None and len(obstacles):
        # In front of a wall, on the line from the pair: the pair keeps its place on screen, the camera level.
        eye = clear_of_obstacles(0.5 * (signals.heads_a + signals.heads_b), eye, obstacles)
    m = level_camera(eye, signals.heads_a, signals.heads_b, screen_height(cam), fov_x, aspect)
    if smooth:
        m = smooth_track(m)
    result = _track_features(m, signals, fov_x, aspect)
    track = _camera_track(path, times, result.cam_to_world, focal_length, aspect)
    here = os.path.dirname(scene.path)
    mixes, styles = zip(*(model_for(r).mix_and_style(g) for g, (r, _) in zip(gates, timeline)))
    extra = {"expert_weights": mixes[0], "reference": os.path.relpath(reference.path, here),
             "reference_style": styles[0]}
    if len(timeline) > 1:
        extra.update({"references": [os.path.relpath(r.path, here) for r, _ in timeline],
                      "reference_from": [times[0]] + [f for _, f in timeline[1:]], "reference_weights": mixes})
    written = _author(scene, track, result, signals, "learned", reference.shot_size, smooth, extra)
    return written, track, result, signals, mixes[0] if len(mixes) == 1 else np.array(mixes)
