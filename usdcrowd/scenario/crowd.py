"""A shot's crowd layer read back into :class:`usdcrowd.core.model.CrowdFrames`.

The crowd layer (see :mod:`usdcrowd.usd.crowd_layer`) holds each agent's
skeleton animation, with its world placement in the root joint, and its state
tokens. This reader undoes both: positions and headings come out of the root
and torso joints through the animation model
(:func:`usdcrowd.character.root.recover_root_motion`), the state codes out of
the ``crowd:state:*`` tokens. Cameras and event detection can then work on a
shot without simulating it again.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..core import model
from .. import schema
from ..core.errors import StageError
from .samples import sample_values
from .stageio import open_stage, stage_frame, time_range

@dataclass
class CrowdInfo:
    """What :func:`read_crowd` says about its rows besides the frames.

    Attributes
    ----------
    path : list[str]
        Prim path of each agent's SkelRoot (stage order).
    agent_id : (n,) int32
        crowd:agentId.
    visible : (n,) bool
        Rendered at the first frame read (not an invisible leader, not hidden).
    group : list[str]
        Path of each agent's CrowdGroup (crowd:group, else its parent prim).
    height : (n,) float64
        crowd:height, metres.
    time : TimeRange
        Time codes and rate of the frames read.
    shot_time : TimeRange
        The stage's whole time range.
    """

    path: list[str]
    agent_id: np.ndarray
    visible: np.ndarray
    group: list[str]
    height: np.ndarray
    time: model.TimeRange
    shot_time: model.TimeRange

    def __len__(self) -> int:
        return len(self.path)

    @property
    def rows(self) -> dict[str, int]:
        """Agent prim path -> row."""
        return {p: i for i, p in enumerate(self.path)}


def _agents(stage):
    """(SkelRoot prim, SkelAnimation prim) of every animated agent, stage order."""
    from pxr import Usd, UsdSkel

    out = []
    it = iter(Usd.PrimRange(stage.GetPseudoRoot()))
    for prim in it:
        if not schema.is_agent(prim):
            continue
        it.PruneChildren()
        src = UsdSkel.BindingAPI(prim).GetAnimationSourceRel().GetTargets()
        anim = stage.GetPrimAtPath(src[0]) if src else None
        if anim and anim.IsA(UsdSkel.Animation):
            out.append((prim, anim))
    return out


def _samples(attr, times: list[float], dtype, shape: tuple[int, int]) -> np.ndarray:
    """Values of an array attribute at ``times``, as one (len(times), *shape) array.

    Samples come straight from the layers that hold them (the crowd layer or
    its value clips), else composed per frame
    (:func:`usdcrowd.scenario.samples.sample_values`). Vt arrays become numpy
    through their buffers, joined once.
    """
    values = sample_values(attr, times)
    try:
        flat = np.frombuffer(b"".join([memoryview(v).tobytes() for v in values]), dtype=dtype)
        return flat.reshape((len(times),) + shape)
    except (TypeError, ValueError):
        raise StageError(f"{attr.GetName()} is not sampled with {shape[0]} joints at every frame",
                         prim=str(attr.GetPrim().GetPath())) from None


def _tokens(attr, times: np.ndarray, vocabulary: tuple[str, ...], default: int = 0) -> np.ndarray:
    """(len(times),) int8 codes of a token attribute sampled where it changes (tokens hold)."""
    samples = attr.GetTimeSamples() if attr else []
    if not samples:
        v = attr.Get() if attr else None
        return np.full(len(times), vocabulary.index(str(v)) if v is not None else default, np.int8)
    values = [str(attr.Get(t)) for t in samples]
    unknown = sorted(set(values) - set(vocabulary))
    if unknown:
        raise StageError(f"value {unknown[0]!r} is not one of {', '.join(vocabulary)}"
                         + (" (a layer that holds it is missing or unreadable)" if unknown[0] == "None" else ""),
                         prim=str(attr.GetPrim().GetPath()), attribute=attr.GetName())
    codes = np.array([vocabulary.index(v) for v in values], np.int8)
    # The last sample at or before each time; the first one holds before it.
    k = np.clip(np.searchsorted(np.asarray(samples), times, side="right") - 1, 0, len(samples) - 1)
    return codes[k]


def _frames(frames, shot: model.TimeRange) -> np.ndarray:
    if frames is None:
        return shot.codes
    if isinstance(frames, model.TimeRange):
        start, end = frames.start, frames.end
    else:
        start, end = frames
    if start < shot.start - 1e-6 or end > shot.end + 1e-6 or end < start:
        raise ValueError(f"frames {start:g}-{end:g} are not within the shot's {shot.start:g}-{shot.end:g}")
    return model.TimeRange(float(start), float(end), shot.fps).codes


def read_crowd(shot, frames=None) -> tuple[model.CrowdFrames, CrowdInfo]:
    """Read the simulated crowd of a shot back into frames.

    Parameters
    ----------
    shot : path-like or Usd.Stage
        A shot stage (or any stage whose agents have a SkelAnimation).
    frames : TimeRange or (start, end), optional
        Frames to read, inclusive, within the stage's time range; default
        all of them.

    Returns
    -------
    frames : CrowdFrames
        ``t`` frames of the ``n`` animated agents, rows in stage order:

        - ``position`` (t, n, 3) and ``heading`` (t, n): ground contact and
          yaw in canonical metres and radians (the agent's own transform and
          the stage's upAxis / metersPerUnit undone). Exact to the float32
          rounding of the stage (about 1e-7), blends between animation
          classes included;
        - ``velocity`` (t, n, 2): backward differences of the positions
          times the frame rate, the frame before the first one read taking
          part when the shot has it; the shot's first frame takes the
          forward difference (one frame alone: zero);
        - ``behavior``, ``anim_class``, ``health`` (t, n): codes of the
          ``crowd:state:*`` tokens;
        - ``anim_phase`` (t, n): zeros, and ``look_at`` (t, n, 3): NaN. The
          skeleton gives the sine of the cycle's phase and the head's
          direction, not the phase or the point looked at;
        - ``path_method`` (n,): crowd:pathMethod codes;
        - ``present`` (t, n): who is shown at each frame, where an agent's
          visibility is time-sampled (a replay), else None.
    info : CrowdInfo
        Paths, ids, visibility, groups and heights of the rows; time ranges.

    Raises
    ------
    StageError
        When the stage has no animated agent, or an agent's samples are missing.
    ValueError
        When ``frames`` is not within the stage's time range.
    """
    from pxr import Usd

    from ..character.root import recover_root_motion

    stage = shot if isinstance(shot, Usd.Stage) else open_stage(os.fspath(shot))
    source = stage.GetRootLayer().identifier
    agents = _agents(stage)
    if not agents:
        raise StageError("no animated agent (a shot stage has a SkelAnimation per agent)", file=source)
    shot_time = time_range(stage)
    codes = _frames(frames, shot_time)
    anim_class, since, begin, first = _class_history(agents, codes, shot_time)
    window = shot_time.start + np.arange(int(round(codes[0] - shot_time.start)) - first + begin,
                                         int(round(codes[-1] - shot_time.start)) + 1, dtype=np.float64)
    rot, trans, scale = _skeletons(agents, window)
    position, heading = recover_root_motion(rot[:, :, 0], trans, rot[:, :, 1], scale,
                                            anim_class[begin:], since[begin:])
    position, heading = _to_world(stage, agents, window, position, heading, source)
    velocity = np.zeros(position.shape[:2] + (2,))
    if len(window) > 1:
        velocity[1:] = np.diff(position[..., :2], axis=0) * shot_time.fps
        velocity[0] = velocity[1]
    keep = slice(first - begin, None)
    out = _frames_of(agents, codes, position[keep], heading[keep], velocity[keep], anim_class[first:])
    return out, _info(agents, codes, shot_time)


def _class_history(agents, codes: np.ndarray, shot_time: model.TimeRange):
    """Each agent's animation class from far enough back to start reading at an unblended frame.

    Blends between animation classes carry their key pose forward, so each agent is read from one of
    its unblended frames at or before the frame before the first one wanted (for the velocity). The
    class history comes from a short look-back, longer only while some agent blends all through it,
    so reading a window of a long shot costs the window, not the shot.

    Returns
    -------
    anim_class, since : (h, n) int
        Classes and frames since each changed, over the history read.
    begin : int
        Row of the history where reading the skeletons starts.
    first : int
        Row of the history of the first frame wanted.
    """
    from ..character.animation import BLEND_FRAMES
    from ..character.root import blend_weight, frames_since_change

    first_abs = int(round(codes[0] - shot_time.start))
    want_abs = max(first_abs - 1, 0)
    end_abs = int(round(codes[-1] - shot_time.start))
    lookback = 4 * BLEND_FRAMES
    while True:
        # BLEND_FRAMES more history than searched: the blend counts are exact from there on.
        h0 = max(0, want_abs - lookback - BLEND_FRAMES)
        history = shot_time.start + np.arange(h0, end_abs + 1, dtype=np.float64)
        anim_class = np.stack([_tokens(p.GetAttribute("crowd:state:animClass"), history, model.ANIM_CLASSES)
                               for p, _ in agents], 1)
        since = frames_since_change(anim_class)
        lo = 0 if h0 == 0 else BLEND_FRAMES
        settled = blend_weight(since[lo:want_abs - h0 + 1]) >= 1.0
        if h0 == 0 or settled.any(axis=0).all():
            break
        lookback *= 4
    begin = lo + int(min(np.flatnonzero(settled[:, a])[-1] for a in range(len(agents))))
    return anim_class, since, begin, first_abs - h0


def _skeletons(agents, window: np.ndarray):
    """Root and torso rotations ((t, n, 2, 4) w-first), root translations (t, n, 3) and scales (n,)."""
    n = len(agents)
    rot = np.empty((len(window), n, 2, 4))
    trans = np.empty((len(window), n, 3))
    scale = np.empty(n)
    times = window.tolist()
    for a, (prim, anim) in enumerate(agents):
        r = _samples(anim.GetAttribute("rotations"), times, np.float32, (3, 4))
        t = _samples(anim.GetAttribute("translations"), times, np.float32, (3, 3))
        rot[:, a] = np.roll(r[:, :2], 1, axis=-1)              # (x, y, z, w) -> (w, x, y, z)
        trans[:, a] = t[:, 0]
        s = anim.GetAttribute("scales").Get(float(window[0]))
        scale[a] = float(s[0][0]) if s else 1.0
    return rot, trans, scale


def _to_world(stage, agents, window, position: np.ndarray, heading: np.ndarray, source: str):
    """Skeleton space to canonical world: the agent's own transform and its parents' (which a layer
    over the shot, or a set referencing it, may move or animate) and the stage frame."""
    from ..character.rig import wrap_angle
    from .parent_space import ParentSpace

    to_canonical = stage_frame(stage).to_canonical
    space = ParentSpace(stage, window)
    for a, (prim, _) in enumerate(agents):
        m = space.world(str(prim.GetPath())) @ to_canonical
        if np.allclose(m, np.eye(4), atol=1e-9):
            continue
        r3 = m[..., :3, :3]
        s3 = np.linalg.norm(r3, axis=-1)
        if not (np.allclose(s3, s3[..., :1], rtol=1e-6)
                and np.allclose(r3[..., 2, :2], 0, atol=1e-6 * float(s3.max()))):
            raise StageError("the agent's transform tilts or stretches its skeleton", file=source,
                             prim=str(prim.GetPath()))
        position[:, a] = (position[:, a] @ r3 if r3.ndim == 2 else np.einsum("ti,tij->tj", position[:, a], r3)) \
            + m[..., 3, :3]
        heading[:, a] += np.arctan2(r3[..., 0, 1], r3[..., 0, 0])
    return position, wrap_angle(heading)


def _frames_of(agents, codes, position, heading, velocity, anim_class) -> model.CrowdFrames:
    """The frames wanted, with the state tokens read at them."""
    t_out, n = len(codes), len(agents)

    def state(name, vocab):
        return np.stack([_tokens(p.GetAttribute(f"crowd:state:{name}"), codes, vocab) for p, _ in agents], 1)

    def path_method(prim):
        v = prim.GetAttribute("crowd:pathMethod").Get()
        return model.PATH_METHODS.index(str(v)) if v else 0

    return model.CrowdFrames(
        times=codes, position=position.astype(np.float32), heading=heading.astype(np.float32),
        velocity=velocity.astype(np.float32), behavior=state("behavior", model.BEHAVIORS),
        anim_class=anim_class.astype(np.int8), anim_phase=np.zeros((t_out, n), np.float32),
        health=state("health", model.HEALTH_STATES), look_at=np.full((t_out, n, 3), np.nan, np.float32),
        path_method=np.array([path_method(p) for p, _ in agents], np.int8), present=_presence(agents, codes))


def _presence(agents, codes: np.ndarray) -> np.ndarray | None:
    """(t, n) who is shown at each frame, where visibility is time-sampled (a replay's people come and go);
    None where no agent's visibility changes over time."""
    from pxr import UsdGeom

    def sampled(img) -> bool:      # one sample counts: someone never present has a single "invisible" one
        attr = img.GetVisibilityAttr()
        return attr.GetNumTimeSamples() > 0 or attr.ValueMightBeTimeVarying()

    varying = [(a, img) for a, img in enumerate(UsdGeom.Imageable(p) for p, _ in agents) if sampled(img)]
    if not varying:
        return None
    present = np.ones((len(codes), len(agents)), bool)
    shown = {}                  # parent path -> (t,) its computed visibility, each parent read once

    def parent_shown(prim) -> np.ndarray:
        parent = prim.GetParent()
        key = parent.GetPath()
        if key not in shown:
            img = UsdGeom.Imageable(parent)
            if not img:
                shown[key] = np.ones(len(codes), bool)
            elif img.GetVisibilityAttr().ValueMightBeTimeVarying():
                shown[key] = np.array([img.ComputeVisibility(float(t)) != UsdGeom.Tokens.invisible for t in codes])
            else:
                shown[key] = np.full(len(codes), img.ComputeVisibility(float(codes[0])) != UsdGeom.Tokens.invisible)
        return shown[key]

    for a, img in varying:
        # A token holds its value from one sample to the next: read the samples, not every frame.
        attr = img.GetVisibilityAttr()
        times = np.array(attr.GetTimeSamples(), dtype=np.float64)
        if not len(times):
            present[:, a] = [img.ComputeVisibility(float(t)) != UsdGeom.Tokens.invisible for t in codes]
            continue
        values = np.array([attr.Get(float(t)) != UsdGeom.Tokens.invisible for t in times])
        own = values[np.maximum(np.searchsorted(times, np.asarray(codes, np.float64), side="right") - 1, 0)]
        present[:, a] = own & parent_shown(img.GetPrim())
    return present


def _info(agents, codes, shot_time: model.TimeRange) -> CrowdInfo:
    from pxr import UsdGeom

    def target(prim, name):
        rel = prim.GetRelationship(name)
        t = rel.GetTargets() if rel else []
        return str(t[0]) if t else None

    return CrowdInfo(
        path=[str(p.GetPath()) for p, _ in agents],
        agent_id=np.array([p.GetAttribute("crowd:agentId").Get() or 0 for p, _ in agents], np.int32),
        visible=np.array([UsdGeom.Imageable(p).ComputeVisibility(float(codes[0])) != UsdGeom.Tokens.invisible
                          for p, _ in agents], bool),
        group=[target(p, "crowd:group") or str(p.GetParent().GetPath()) for p, _ in agents],
        height=np.array([p.GetAttribute("crowd:height").Get() or 0.0 for p, _ in agents], np.float64),
        time=model.TimeRange(float(codes[0]), float(codes[-1]), shot_time.fps), shot_time=shot_time)

