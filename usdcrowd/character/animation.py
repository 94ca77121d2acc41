"""Procedural animation classes, transitions and look-at (seed 003).

The renderer picks an animation class from each character's velocity and
heading (run, walk, stride left, stride right, plus idle), plays a cyclic
pose of the three joints, smooths class changes with temporary key frames,
and lets the head and torso turn toward a point of interest.

Everything is vectorised over ``(t, n)`` (frames, agents); only recurrences
(blending, look-at smoothing) loop over frames. Poses are LOCAL joint
rotations (w, x, y, z) and translations in the canonical 1.75 m skeleton
space (facing +X, Z up, Y to the left); the agent's position, heading and
height belong to the SkelRoot transform.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.model import CrowdFrames
from .gait import (IDLE, IDLE_FREQUENCY, REF_SPEED, RUN, STRIDE_LEFT, STRIDE_LENGTH, STRIDE_RIGHT,
                   STRIDE_SCALE_RANGE, WALK)
from .rig import (EYE_HEIGHT, HEAD_TOP, quat_conjugate,
                  quat_from_axis_angle, quat_multiply, quat_rotate, quat_slerp, wrap_angle)

# Below this speed feet stop cycling: sim jitter around a standstill would
# otherwise flicker between walk and idle.
IDLE_SPEED = 0.15  # m/s
# Walk-to-run transition of adult humans is around 2 m/s; a little above so
# that brisk walkers keep walking.
RUN_SPEED = 2.4  # m/s
# Frames over which a class change is blended (0.25 s at 24 fps).
BLEND_FRAMES = 6
# Head turning speed when a look-at target appears, changes or goes away.
LOOK_TURN_RATE = np.radians(240.0)  # rad/s
# Look-at split and limits, relative to the body (the SkelRoot's heading).
TORSO_SHARE = 0.4
TORSO_YAW_LIMIT = np.radians(35.0)
HEAD_YAW_LIMIT = np.radians(70.0)  # head yaw in the body frame, torso included
HEAD_PITCH_LIMIT = np.radians(40.0)

_X, _Y, _Z = np.eye(3)


def classify(velocity: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """Animation class from planar velocity and facing.

    Parameters
    ----------
    velocity : (t, n, 2) float
        Planar velocity, m/s.
    heading : (t, n) float
        Facing yaw, radians, 0 = +X.

    Returns
    -------
    (t, n) int8
        Codes into ``ANIM_CLASSES``.
    """
    velocity = np.asarray(velocity, dtype=np.float64)
    c, s = np.cos(heading), np.sin(heading)
    forward = velocity[..., 0] * c + velocity[..., 1] * s
    lateral = -velocity[..., 0] * s + velocity[..., 1] * c  # + = to the left
    speed = np.hypot(velocity[..., 0], velocity[..., 1])
    cls = np.where(speed > RUN_SPEED, RUN, WALK)
    cls = np.where(np.abs(lateral) > np.abs(forward),
                   np.where(lateral > 0, STRIDE_LEFT, STRIDE_RIGHT), cls)
    return np.where(speed < IDLE_SPEED, IDLE, cls).astype(np.int8)


def _stride_scale(speed, cls):
    """Amplitude / stride-length scale: longer, bigger steps when faster."""
    return np.clip(np.asarray(speed) / REF_SPEED[cls], *STRIDE_SCALE_RANGE)


def advance_phase(speed: np.ndarray, anim_class: np.ndarray, dt: float,
                  phase0: np.ndarray | None = None) -> np.ndarray:
    """Integrate the cycle phase over frames.

    Parameters
    ----------
    speed : (t, n) float
        Planar speed, m/s.
    anim_class : (t, n) int
        Class codes.
    dt : float
        Seconds per frame.
    phase0 : (n,) float, optional
        Phase at the first frame; 0 if None.

    Returns
    -------
    (t, n) float32
        Phase in [0, 1); frame ``k`` is ``phase0`` plus the cycles run over
        frames ``0..k-1``, so the phase never decreases (modulo 1).
    """
    speed = np.asarray(speed, dtype=np.float64)
    cls = np.asarray(anim_class, dtype=np.int64)
    # Cadence grows slower than speed: stride length scales by sqrt.
    length = STRIDE_LENGTH[cls] * np.sqrt(_stride_scale(speed, cls))
    freq = np.where(cls == IDLE, IDLE_FREQUENCY, speed / np.where(cls == IDLE, 1.0, length))
    start = np.zeros(speed.shape[1:]) if phase0 is None else np.asarray(phase0, np.float64)
    steps = np.concatenate([np.zeros((1,) + speed.shape[1:]), freq[:-1] * dt])
    phase = np.mod(start + np.cumsum(steps, axis=0), 1.0).astype(np.float32)
    return np.where(phase >= 1.0, np.float32(0.0), phase)  # float32 rounding up to 1


def pose(anim_class: np.ndarray, phase: np.ndarray, speed: np.ndarray):
    """Local joint pose of each class at a cycle phase.

    Parameters
    ----------
    anim_class : (...) int
        Class codes.
    phase : (...) float
        Cycle phase in [0, 1).
    speed : (...) float
        Planar speed, m/s (scales the amplitudes).

    Returns
    -------
    rotations : (..., 3, 4) float64
        Local joint quaternions (w, x, y, z), joints in ``JOINTS`` order.
    translations : (..., 3, 3) float64
        Local joint translations, metres; the legs joint carries the pelvis
        height and bob.

    Notes
    -----
    With ``s = sin(2 pi phase)`` and the stride scale ``k`` (1 when idle),
    the legs turn by ``Rz(LEG_YAW k s) Ry(LEG_PITCH k s) Rx(LEG_ROLL k s)``,
    the torso by ``Rz(-TORSO_TWIST k s) Ry(TORSO_LEAN k + BREATH s)
    Rx(-TORSO_SIDE_LEAN)`` and the head by ``Rz(HEAD_SWAY s) Ry(HEAD_NOD
    sin(4 pi phase) + TORSO_LEAN k / 4)``, all in skeleton space (each joint's
    local rotation is its parent's inverse times its own, so the torso and
    head counter-rotate whatever the legs do); the pelvis is lifted by the
    legs' tilt so the feet stay on the ground, and bobs twice per cycle by
    ``BOB k``. Computed per pose in one compiled loop
    (:func:`usdcrowd.character.kernels.pose`).
    """
    from .kernels import pose as compiled

    return compiled(anim_class, phase, speed)


def _ease(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


@dataclass
class BlendState:
    """What a blend needs from the frame before a chunk (see :class:`Animator`).

    Attributes
    ----------
    cls : (n,) int
        Class at the last frame.
    rot, tr : (n, 3, 4), (n, 3, 3) float
        Output (blended) pose at the last frame.
    key_rot, key_tr : (n, 3, 4), (n, 3, 3) float
        Pose frozen at the last class change.
    since : (n,) int
        Frames since that change.
    """

    cls: np.ndarray
    rot: np.ndarray
    tr: np.ndarray
    key_rot: np.ndarray
    key_tr: np.ndarray
    since: np.ndarray


def blend_transitions(anim_class: np.ndarray, rotations: np.ndarray, translations: np.ndarray,
                      frames: int = BLEND_FRAMES, state: BlendState | None = None):
    """Smooth class changes with a temporary key frame (seed 003, Figure 6).

    When an agent's class changes, the pose it had just before is frozen and
    the output eases (smoothstep) from it to the new class's pose over
    ``frames`` frames; a change during a blend restarts from the blended pose.

    Parameters
    ----------
    anim_class : (t, n) int
        Class codes.
    rotations : (t, n, 3, 4) float
        Local quaternions (w, x, y, z) of the unblended poses.
    translations : (t, n, 3, 3) float
        Local translations of the unblended poses.
    frames : int
        Blend length; 0 disables blending.
    state : BlendState, optional
        The frame before ``rotations[0]`` (a previous chunk): a change at
        the chunk's first frame is blended and blends under way continue.
        Updated in place to this chunk's last frame. None: the first frame
        starts settled.

    Returns
    -------
    rotations : (t, n, 3, 4) float64
    translations : (t, n, 3, 3) float64
    """
    rot = np.array(rotations, dtype=np.float64)
    tr = np.array(translations, dtype=np.float64)
    cls = np.asarray(anim_class)
    if frames <= 0 or len(rot) == 0:
        return rot, tr
    if state is None or state.cls is None:
        first = 1
        prev_cls, prev_rot, prev_tr = cls[0], rot[0], tr[0]
        key_rot, key_tr = rot[0].copy(), tr[0].copy()
        since = np.full(cls.shape[1], frames, dtype=np.int64)  # frames since last change
    else:
        first = 0
        prev_cls, prev_rot, prev_tr = state.cls, state.rot, state.tr
        key_rot, key_tr, since = state.key_rot.copy(), state.key_tr.copy(), state.since.copy()
    for t in range(first, len(rot)):
        changed = cls[t] != prev_cls
        key_rot[changed], key_tr[changed] = prev_rot[changed], prev_tr[changed]
        since = np.where(changed, 0, since + 1)
        w = _ease((since + 1) / frames)
        active = w < 1.0
        if active.any():
            rot[t][active] = quat_slerp(key_rot[active], rot[t][active],
                                        np.broadcast_to(w[active, None], (active.sum(), 3)))
            wa = w[active, None, None]
            tr[t][active] = (1.0 - wa) * key_tr[active] + wa * tr[t][active]
        prev_cls, prev_rot, prev_tr = cls[t], rot[t], tr[t]
    if state is not None:
        state.cls, state.rot, state.tr = np.array(cls[-1]), rot[-1].copy(), tr[-1].copy()
        state.key_rot, state.key_tr, state.since = key_rot, key_tr, since
    return rot, tr


@dataclass
class LookState:
    """Head-turn angles and weight at the frame before a chunk, (n,) float each."""

    yaw: np.ndarray
    pitch: np.ndarray
    weight: np.ndarray


def apply_look_at(rotations: np.ndarray, position: np.ndarray, heading: np.ndarray,
                  height: np.ndarray, target: np.ndarray, max_step: float | None = None,
                  state: LookState | None = None):
    """Turn torso and head toward a target (seed 003, Figure 5).

    The torso takes ``TORSO_SHARE`` of the yaw (limited to
    ``TORSO_YAW_LIMIT``), the head the rest, up to ``HEAD_YAW_LIMIT`` in all
    and ``HEAD_PITCH_LIMIT`` up or down. Within the limits the head's +X axis
    points from the eyes to the target (its animated nod is replaced); the
    legs are untouched.

    Parameters
    ----------
    rotations : (t, n, 3, 4) float
        Local joint quaternions (w, x, y, z).
    position : (t, n, 3) float
        Ground position of the SkelRoot, world metres.
    heading : (t, n) float
        Body yaw, radians (the SkelRoot's rotation).
    height : (t, n) or (n,) float
        Body height, metres (the SkelRoot scales the canonical 1.75 m).
    target : (t, n, 3) float
        World point to look at; NaN rows where there is none.
    max_step : float, optional
        Most the look angles may change per frame, radians, so that targets
        appearing, switching or vanishing turn the head smoothly; None turns
        instantly.
    state : LookState, optional
        With ``max_step``: the angles of the frame before this chunk, so the
        rate limit carries across chunks; updated in place to the last frame.

    Returns
    -------
    (t, n, 3, 4) float64
        Local joint quaternions.
    """
    rot = np.array(rotations, dtype=np.float64)
    if rot.ndim == 4:
        # Agents with nothing to look at in the chunk and no head still turned keep their pose and hold
        # their angles: the work runs on the others alone (usually few of a crowd).
        looking = np.isfinite(np.asarray(target)).all(axis=-1).any(axis=0)
        if state is not None and state.weight is not None:
            looking |= state.weight > 0.0
        if not looking.all():
            return _look_at_some(rot, looking, position, heading, height, target, max_step, state)
    yaw, pitch, has = _look_angles(position, heading, height, target)
    weight = has.astype(np.float64)
    if max_step is not None:
        _rate_limit_look(yaw, pitch, weight, has, max_step, state)
    # Only agents looking at something (or still turning back) change; most
    # of a crowd usually does not, so the quaternion work runs on those alone.
    on = weight > 0.0
    if not on.any():
        return rot
    rot[on] = _turn_torso_and_head(rot[on], yaw[on], pitch[on], weight[on])
    return rot


def _look_at_some(rot, looking, position, heading, height, target, max_step, state):
    """:func:`apply_look_at` of the agents ``looking`` ((n,) bool); the others' angles held, weights 0."""
    cols = np.flatnonzero(looking)
    carried = state is not None and state.yaw is not None
    sub = None if state is None else LookState(*((x[cols] if carried else None)
                                                 for x in (state.yaw, state.pitch, state.weight)))
    height = np.broadcast_to(np.asarray(height, dtype=np.float64), np.shape(heading))
    if cols.size:
        rot[:, cols] = apply_look_at(rot[:, cols], np.asarray(position)[:, cols], np.asarray(heading)[:, cols],
                                     height[:, cols], np.asarray(target)[:, cols], max_step, sub)
    if state is not None and max_step is not None and len(rot):
        n = rot.shape[1]
        yaw, pitch = (state.yaw.copy(), state.pitch.copy()) if carried else (np.zeros(n), np.zeros(n))
        weight = np.zeros(n)
        if cols.size:
            yaw[cols], pitch[cols], weight[cols] = sub.yaw, sub.pitch, sub.weight
        state.yaw, state.pitch, state.weight = yaw, pitch, weight
    return rot


def _look_angles(position, heading, height, target):
    """Body-relative yaw and pitch from eyes to target within the head's limits, and where a target is."""
    position = np.asarray(position, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    height = np.broadcast_to(np.asarray(height, dtype=np.float64), np.shape(heading))
    eye = position + (EYE_HEIGHT / HEAD_TOP) * height[..., None] * _Z
    d = target - eye
    has = np.all(np.isfinite(d), axis=-1)
    yaw = np.where(has, wrap_angle(np.arctan2(d[..., 1], d[..., 0]) - heading), 0.0)
    pitch = np.where(has, np.arctan2(d[..., 2], np.hypot(d[..., 0], d[..., 1])), 0.0)
    yaw = np.clip(yaw, -HEAD_YAW_LIMIT, HEAD_YAW_LIMIT)
    pitch = np.clip(pitch, -HEAD_PITCH_LIMIT, HEAD_PITCH_LIMIT)
    return yaw, pitch, has


def _rate_limit_look(yaw, pitch, weight, has, max_step, state):
    """Rate-limit angles and on/off weight alike, in place, carrying ``state`` across chunks."""
    # Fading in or out takes as long as sweeping the head over its range.
    w_step = max_step / HEAD_YAW_LIMIT
    before = None if state is None or state.yaw is None else (state.yaw, state.pitch, state.weight)
    for t in range(len(yaw)):
        if t == 0 and before is None:
            continue
        p_yaw, p_pitch, p_weight = before if t == 0 else (yaw[t - 1], pitch[t - 1], weight[t - 1])
        yaw[t] = p_yaw + np.clip(yaw[t] - p_yaw, -max_step, max_step)
        pitch[t] = p_pitch + np.clip(pitch[t] - p_pitch, -max_step, max_step)
        weight[t] = p_weight + np.clip(weight[t] - p_weight, -w_step, w_step)
        # Where there is no target, the angles hold while the weight fades.
        yaw[t] = np.where(has[t], yaw[t], p_yaw)
        pitch[t] = np.where(has[t], pitch[t], p_pitch)
    if state is not None and len(yaw):
        state.yaw, state.pitch, state.weight = yaw[-1].copy(), pitch[-1].copy(), weight[-1].copy()


def _turn_torso_and_head(r, yaw, pitch, weight):
    """``r`` (m, 3, 4) with torso and head turned by the look angles, eased in by ``weight``; legs kept."""
    torso_yaw = np.clip(TORSO_SHARE * yaw, -TORSO_YAW_LIMIT, TORSO_YAW_LIMIT)
    legs = r[:, 0, :]
    torso = quat_multiply(legs, r[:, 1, :])
    head = quat_multiply(torso, r[:, 2, :])
    torso_new = quat_multiply(quat_from_axis_angle(_Z, torso_yaw), torso)
    # Looking up turns +X toward +Z: a negative rotation about +Y.
    aim = quat_multiply(quat_from_axis_angle(_Z, yaw), quat_from_axis_angle(_Y, -pitch))
    head_new = quat_slerp(head, aim, weight)
    torso_new = quat_slerp(torso, torso_new, weight)
    r[:, 1, :] = quat_multiply(quat_conjugate(legs), torso_new)
    r[:, 2, :] = quat_multiply(quat_conjugate(torso_new), head_new)
    return r


def head_forward(rotations: np.ndarray) -> np.ndarray:
    """Skeleton-space +X axis of the head, (..., 3), from local rotations (..., 3, 4)."""
    r = np.asarray(rotations, dtype=np.float64)
    q = quat_multiply(quat_multiply(r[..., 0, :], r[..., 1, :]), r[..., 2, :])
    return quat_rotate(q, np.broadcast_to(_X, q.shape[:-1] + (3,)))


class Animator:
    """Joint animation of one set of agents, chunk after consecutive chunk.

    Blends between classes and rate-limited head turns carry over from one
    chunk to the next, so the result does not depend on how a shot is cut
    into chunks.

    Parameters
    ----------
    dt : float
        Seconds per frame.
    height : (n,) float
        Body heights, metres.
    """

    def __init__(self, dt: float, height: np.ndarray):
        self.dt = float(dt)
        self.height = np.asarray(height, dtype=np.float64)
        self.blend = BlendState(None, None, None, None, None, None)
        self.look = LookState(None, None, None)

    def __call__(self, frames: CrowdFrames):
        """The next chunk: ``rotations (t, n, 3, 4)``, ``translations (t, n, 3, 3)``, float32.

        Rotations are local joint quaternions (w, x, y, z); reorder with
        :func:`usdcrowd.character.rig.to_usd_quat_order` for
        ``Vt.QuatfArray``. Translations are canonical metres.
        """
        speed = np.hypot(frames.velocity[..., 0], frames.velocity[..., 1])
        rot, tr = pose(frames.anim_class, frames.anim_phase, speed)
        rot, tr = blend_transitions(frames.anim_class, rot, tr, state=self.blend)
        rot = apply_look_at(rot, frames.position, frames.heading, self.height, frames.look_at,
                            max_step=LOOK_TURN_RATE * self.dt, state=self.look)
        return rot.astype(np.float32), tr.astype(np.float32)


def animate(frames: CrowdFrames, dt: float, height: np.ndarray):
    """Joint animation of a whole simulated crowd in one go (see :class:`Animator`).

    Parameters
    ----------
    frames : CrowdFrames
        Uses ``anim_class``, ``anim_phase``, ``velocity``, ``position``,
        ``heading`` and ``look_at``.
    dt : float
        Seconds per frame.
    height : (n,) float
        Body heights, metres.

    Returns
    -------
    rotations : (t, n, 3, 4) float32
    translations : (t, n, 3, 3) float32
    """
    return Animator(dt, height)(frames)
