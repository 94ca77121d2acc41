"""Root motion: where an agent's skeleton is in the world.

An agent's world placement is carried by the root joint (legs) of its
SkelAnimation rather than by separate transform ops on the SkelRoot: that is
two time samples per agent and frame instead of four, which is what keeps
authoring 10,000 agents x 300 frames within the benchmark target.

:func:`recover_root_motion` goes the other way, for readers of a shot: the
ground position and heading back out of the authored joints.
"""

from __future__ import annotations

import numpy as np

from .animation import BLEND_FRAMES, _ease, pose
from .gait import BREATH, LEG_PITCH, LEG_ROLL, LEG_YAW, REF_SPEED, STRIDE_SCALE_RANGE, TORSO_LEAN
from .rig import HEAD_TOP, quat_from_axis_angle, quat_multiply, quat_rotate, quat_slerp, wrap_angle


def root_scale(height) -> np.ndarray:
    """Uniform scale of the root joint for body heights in metres, (n,) float64.

    UsdSkel stores joint scales as half floats: quantising here means every
    position usdcrowd derives (ground truth included) is the stage's own.
    """
    return (np.asarray(height, dtype=np.float64) / HEAD_TOP).astype(np.float16).astype(np.float64)


def apply_root_motion(rotations: np.ndarray, translations: np.ndarray, position: np.ndarray,
                      heading: np.ndarray, height: np.ndarray):
    """Put the canonical-skeleton pose into the world.

    Parameters
    ----------
    rotations : (t, n, 3, 4) float
        Local joint rotations (w, x, y, z) of the canonical 1.75 m skeleton.
    translations : (t, n, 3, 3) float
        Local joint translations, metres.
    position : (t, n, 3) float
        Ground position of each agent, metres.
    heading : (t, n) float
        Yaw, radians.
    height : (n,) float
        Body height, metres; the skeleton is scaled uniformly by height / 1.75.

    Returns
    -------
    rotations, translations : arrays of the input shapes (float32)
        With the root joint's rotation and translation in the world.
    scale : (n,) float32
        Uniform scale of each agent's root joint.
    """
    scale = root_scale(height)
    q_heading = quat_from_axis_angle(np.array([0.0, 0.0, 1.0]), np.asarray(heading, dtype=np.float64))
    rot = np.array(rotations, dtype=np.float64, copy=True)
    trans = np.array(translations, dtype=np.float64, copy=True)
    rot[..., 0, :] = quat_multiply(q_heading, rot[..., 0, :])
    trans[..., 0, :] = position + quat_rotate(q_heading, trans[..., 0, :] * scale[None, :, None])
    return rot.astype(np.float32), trans.astype(np.float32), scale.astype(np.float32)


def frames_since_change(anim_class: np.ndarray) -> np.ndarray:
    """Frames since each agent's last animation-class change, as the blend counts them.

    Parameters
    ----------
    anim_class : (t, n) int
        Class codes from the shot's first frame on; the first row counts as
        settled, as in :func:`usdcrowd.character.animation.blend_transitions`
        without a previous chunk.

    Returns
    -------
    (t, n) int64
        0 at a change; see :func:`blend_weight`.
    """
    cls = np.asarray(anim_class)
    since = np.empty(cls.shape, dtype=np.int64)
    if len(cls):
        since[0] = BLEND_FRAMES
    for t in range(1, len(cls)):
        since[t] = np.where(cls[t] != cls[t - 1], 0, since[t - 1] + 1)
    return since


def blend_weight(since: np.ndarray) -> np.ndarray:
    """Weight of the new class's pose ``frames_since_change`` frames into a blend, (t, n) float64.

    1 where the pose is no longer a blend (as :func:`usdcrowd.character.animation.blend_transitions`).
    """
    return _ease((np.asarray(since) + 1.0) / BLEND_FRAMES)


def _zyx(q: np.ndarray):
    """Yaw, pitch, roll of ``q = Rz(yaw) Ry(pitch) Rx(roll)``, (..., 4) (w, x, y, z) -> three (...) arrays."""
    w, x, y, z = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    pitch = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    return yaw, pitch, roll


def _model(cls, k, s, key=None, w=None):
    """The animation's pre-look-at legs and torso rotations and pelvis height for cycle values (k, s).

    ``k`` is the stride scale, ``s = sin(2 pi phase)``: the legs, torso and
    pelvis of :func:`usdcrowd.character.animation.pose` depend on the phase
    only through ``s``, so any phase with that sine will do. With ``key``
    (legs, torso, pelvis height frozen at the last class change) and blend
    weights ``w`` the result is blended as
    :func:`~usdcrowd.character.animation.blend_transitions` does.
    """
    phase = np.mod(np.arcsin(np.clip(s, -1.0, 1.0)) / (2.0 * np.pi), 1.0)
    rot, tr = pose(cls, phase, k * REF_SPEED[cls])
    legs, torso, pz = rot[..., 0, :], rot[..., 1, :], tr[..., 0, 2]
    if key is not None:
        legs = quat_slerp(key[0], legs, w)
        torso = quat_slerp(key[1], torso, w)
        pz = (1.0 - w) * key[2] + w * pz
    return legs, torso, pz


def _settled_cycle(cls, legs_pitch, legs_roll, torso_pitch):
    """Stride scale k and s = sin(2 pi phase) of unblended poses, from the legs' and torso's angles.

    The legs turn by ``LEG_* [cls] * u`` with ``u = k s``; the torso pitches by
    ``TORSO_LEAN[cls] k + BREATH[cls] s`` (look-at only adds a turn about Z).
    """
    ap, ar, lean, breath = LEG_PITCH[cls], LEG_ROLL[cls], TORSO_LEAN[cls], BREATH[cls]
    u = np.where(ap != 0, legs_pitch / np.where(ap != 0, ap, 1.0),
                 np.where(ar != 0, legs_roll / np.where(ar != 0, ar, 1.0), 0.0))
    # lean k + breath s = torso_pitch with k s = u: breath s^2 - torso_pitch s + lean u = 0;
    # the other root has |s| > 1 for the animation's constants.
    disc = np.sqrt(np.maximum(torso_pitch ** 2 - 4.0 * breath * lean * u, 0.0))
    den = torso_pitch + np.where(torso_pitch < 0, -disc, disc)
    s_lean = np.where(den != 0, 2.0 * lean * u / np.where(den != 0, den, 1.0), 0.0)
    k_lean = (torso_pitch - breath * s_lean) / np.where(lean != 0, lean, 1.0)
    s_flat = torso_pitch / breath
    k_flat = np.where(np.abs(s_flat) > 1e-3, u / np.where(np.abs(s_flat) > 1e-3, s_flat, 1.0), 1.0)
    s = np.clip(np.where(lean != 0, s_lean, s_flat), -1.0, 1.0)
    k = np.clip(np.where(lean != 0, k_lean, k_flat), *STRIDE_SCALE_RANGE)
    return u, k, s


def recover_root_motion(root_rot: np.ndarray, root_trans: np.ndarray, torso_rot: np.ndarray,
                        scale: np.ndarray, anim_class: np.ndarray, since: np.ndarray, iterations: int = 20):
    """Ground position and heading from an authored skeleton: the inverse of :func:`apply_root_motion`.

    The root joint's rotation is the heading times the legs' swing (a hip
    twist about Z among it), its height the ground plus the pelvis height of
    the pose. Both are undone with the animation model: on unblended frames
    the legs' and torso's angles give the cycle in closed form; on the frames
    of a class-change blend (see :func:`frames_since_change`) heading and
    cycle are solved together by Gauss-Newton (vectorised over all the
    blended frames that share a generation of key poses), the key pose being
    the one recovered at the frame before the change. Exact to float32
    rounding of the authored values (about 1e-7 rad and 1e-7 m here).

    Parameters
    ----------
    root_rot : (t, n, 4) float
        Root joint (legs) rotations as authored, (w, x, y, z).
    root_trans : (t, n, 3) float
        Root joint translations as authored, metres.
    torso_rot : (t, n, 4) float
        Torso joint rotations as authored (local, look-at included).
    scale : (n,) float
        Root joint scale of each agent.
    anim_class : (t, n) int
        Animation class codes (crowd:state:animClass).
    since : (t, n) int
        :func:`frames_since_change`, rows matching these. An agent's frames
        are exact from its first unblended frame on; a blend whose key pose
        lies before the first row is only approximated (readers start each
        agent at an unblended frame and drop the rows before it).
    iterations : int
        Gauss-Newton steps on blended frames.

    Returns
    -------
    position : (t, n, 3) float64
        Ground contact, metres.
    heading : (t, n) float64
        Yaw in [-pi, pi), radians.
    """
    q = np.asarray(root_rot, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    trans = np.asarray(root_trans, dtype=np.float64)
    cls = np.asarray(anim_class, dtype=np.int64)
    scale = np.asarray(scale, dtype=np.float64)
    since = np.asarray(since)
    # Torso in the heading frame: its pitch and roll do not depend on look-at's turn about Z.
    yaw, pitch, roll = _zyx(q)
    _, torso_pitch, torso_roll = _zyx(quat_multiply(q, np.asarray(torso_rot, dtype=np.float64)))

    u, k, s = _settled_cycle(cls, pitch, roll, torso_pitch)
    heading = yaw - LEG_YAW[cls] * u
    legs, torso, pz = _model(cls, k, s)

    w = blend_weight(since)
    gen = _blend_generations(w < 1.0, since)
    angles = (yaw, pitch, roll, torso_pitch, torso_roll)
    for g in range(gen.max() + 1):
        tt, aa = np.nonzero(gen == g)
        _solve_blends(tt, aa, since, cls, w, angles, (heading, k, s), (legs, torso, pz), iterations)
    position = trans.copy()
    position[..., 2] -= scale * pz
    return position, wrap_angle(heading)


def _blend_generations(blend: np.ndarray, since: np.ndarray) -> np.ndarray:
    """(t, n) int64 generation of each blended frame's key pose, -1 on unblended frames: the order of solving."""
    # A blend's key is the pose of the frame before its class change. Generation 0 blends
    # key on an unblended frame, generation g on one of generation g - 1 (a change during a
    # blend). Solving by generation, then by frames since the change, every key and every
    # starting guess (the frame before) is final when needed, and each batch is vectorised.
    gen = np.full(blend.shape, -1, dtype=np.int64)
    for t in np.flatnonzero(blend.any(axis=1)):
        a = np.flatnonzero(blend[t])
        before = np.maximum(t - since[t, a] - 1, 0)        # a key before the first row: approximated
        gen[t, a] = np.where(blend[before, a] & (before < t), gen[before, a] + 1, 0)
    return gen


def _solve_blends(tt, aa, since, cls, w, angles, cycle, body, iterations: int) -> None:
    """Solve the blended entries ``(tt, aa)`` of one generation: their ``cycle`` and ``body`` rows, in place."""
    # The (t, n) arrays go in whole: keys and starting guesses are read at other frames.
    # angles: observed (yaw, pitch, roll, torso pitch, torso roll); cycle: (heading, k, s);
    # body: (legs, torso, pelvis height).
    heading, k, s = cycle
    legs, torso, pz = body
    before = np.maximum(tt - since[tt, aa] - 1, 0)
    key = (legs[before, aa], torso[before, aa], pz[before, aa])
    c, wa = cls[tt, aa], w[tt, aa]
    obs = np.stack([a[tt, aa] for a in angles], -1)
    residual = _blend_residual(c, key, wa, obs)
    # Start from the key frame, final by now: the phase runs on through a class change.
    x = np.stack([heading[before, aa], k[before, aa], s[before, aa]], -1)
    yaw = angles[0]
    x[:, 0] += wrap_angle(yaw[tt, aa] - yaw[before, aa])
    _gauss_newton(residual, x, iterations)
    heading[tt, aa], k[tt, aa], s[tt, aa] = x[:, 0], x[:, 1], x[:, 2]
    legs[tt, aa], torso[tt, aa], pz[tt, aa] = _model(c, x[:, 1], x[:, 2], key, wa)


def _blend_residual(c, key, wa, obs):
    """``residual(x, m)``: the blend model's angles minus the observed ``obs`` (k, 5), for Gauss-Newton."""

    def residual(x, m):
        """(len(m), 5) model minus observed angles of the entries ``m`` at values ``x``."""
        lg, to, _ = _model(c[m], x[:, 1], x[:, 2], (key[0][m], key[1][m], key[2][m]), wa[m])
        hz = 0.5 * x[:, 0]
        qz = np.stack([np.cos(hz), np.zeros_like(hz), np.zeros_like(hz), np.sin(hz)], -1)
        d = np.stack([*_zyx(quat_multiply(qz, lg)), *_zyx(quat_multiply(lg, to))[1:]], -1) - obs[m]
        d[:, 0] = wrap_angle(d[:, 0])
        return d

    return residual


def _gauss_newton(residual, x: np.ndarray, iterations: int) -> None:
    """Refine (heading, k, s) rows ``x`` (k, 3) in place, each until it converges, within the pose's bounds."""
    lo, hi = np.array([-np.inf, STRIDE_SCALE_RANGE[0], -1.0]), np.array([np.inf, STRIDE_SCALE_RANGE[1], 1.0])
    mid = np.array([0.0, 0.5 * sum(STRIDE_SCALE_RANGE), 0.0])
    todo = np.arange(len(x))
    for _ in range(iterations):
        xt = x[todo]
        r0 = residual(xt, todo)
        # Differences taken inward: the pose clips k, so an outward step at a bound sees no slope.
        eps = np.where(xt > mid, -1e-6, 1e-6)
        jac = np.stack([(residual(xt + eps * np.eye(3)[i], todo) - r0) / eps[:, i:i + 1] for i in range(3)], -1)
        jtj = jac.transpose(0, 2, 1) @ jac + 1e-9 * np.eye(3)   # a value the pose ignores stays put
        step = np.linalg.solve(jtj, jac.transpose(0, 2, 1) @ r0[..., None])[..., 0]
        x_new = np.clip(xt - step, lo, hi)
        dx = np.abs(x_new - xt)
        x[todo] = x_new
        # Converged where it matters: heading, and the pelvis height (bob ~ k s^2) through s and k.
        todo = todo[(dx[:, 0] > 1e-10) | (dx[:, 2] > 1e-9) | (dx[:, 1] * x_new[:, 2] ** 2 > 1e-9)]
        if not len(todo):
            break
