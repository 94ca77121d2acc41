"""The animation writer's compiled loops give the numpy forms' bits.

The numpy form of the pose kept here is the one the compiled loop replaced; the
root motion is compared with :func:`usdcrowd.character.root.apply_root_motion`
(numpy, still used by readers and tests), and the look-at that skips agents
with nothing to look at with the whole-crowd computation it shortens.
"""

import numpy as np
import pytest

from usdcrowd.character import animation as A
from usdcrowd.character import gait as G
from usdcrowd.character import kernels as K
from usdcrowd.character.rig import (PELVIS_HEIGHT, REST_TRANSLATIONS, quat_conjugate, quat_from_axis_angle,
                                    quat_multiply, to_usd_quat_order)
from usdcrowd.character.root import apply_root_motion, root_scale

_X, _Y, _Z = np.eye(3)


def numpy_pose(anim_class, phase, speed):
    """The pose as chains of numpy arrays (the form before compilation)."""
    cls = np.asarray(anim_class, dtype=np.int64)
    ph = 2.0 * np.pi * np.asarray(phase, dtype=np.float64)
    k = np.where(cls == A.IDLE, 1.0, A._stride_scale(speed, cls))
    s, s2 = np.sin(ph), np.sin(2.0 * ph)
    legs = quat_multiply(quat_multiply(quat_from_axis_angle(_Z, G.LEG_YAW[cls] * k * s),
                                       quat_from_axis_angle(_Y, G.LEG_PITCH[cls] * k * s)),
                         quat_from_axis_angle(_X, G.LEG_ROLL[cls] * k * s))
    torso = quat_multiply(quat_multiply(quat_from_axis_angle(_Z, -G.TORSO_TWIST[cls] * k * s),
                                        quat_from_axis_angle(_Y, G.TORSO_LEAN[cls] * k + G.BREATH[cls] * s)),
                          quat_from_axis_angle(_X, -G.TORSO_SIDE_LEAN[cls]))
    head = quat_multiply(quat_from_axis_angle(_Z, G.HEAD_SWAY[cls] * s),
                         quat_from_axis_angle(_Y, G.HEAD_NOD[cls] * s2 + 0.25 * G.TORSO_LEAN[cls] * k))
    rotations = np.stack([legs, quat_multiply(quat_conjugate(legs), torso),
                          quat_multiply(quat_conjugate(torso), head)], axis=-2)
    translations = np.broadcast_to(REST_TRANSLATIONS, cls.shape + (3, 3)).copy()
    zz = 1.0 - 2.0 * (legs[..., 1] ** 2 + legs[..., 2] ** 2)
    translations[..., 0, 2] = PELVIS_HEIGHT * zz + G.BOB[cls] * k * 0.5 * (1.0 - np.cos(2.0 * ph))
    return rotations, translations


def numpy_look_at(rotations, position, heading, height, target, max_step, state):
    """The look-at computed for every agent (the form before agents without a target were skipped)."""
    rot = np.array(rotations, dtype=np.float64)
    yaw, pitch, has = A._look_angles(position, heading, height, target)
    weight = has.astype(np.float64)
    A._rate_limit_look(yaw, pitch, weight, has, max_step, state)
    on = weight > 0.0
    if on.any():
        rot[on] = A._turn_torso_and_head(rot[on], yaw[on], pitch[on], weight[on])
    return rot


@pytest.fixture
def random_cycles():
    """Class codes, phases and speeds of 40 frames x 500 agents, float32 as the simulation hands them."""
    rng = np.random.default_rng(3)
    shape = (40, 500)
    return (rng.integers(0, len(G.ANIM_CLASSES), shape).astype(np.int8),
            rng.random(shape).astype(np.float32), (rng.random(shape) * 4.0).astype(np.float32))


def test_compiled_pose_gives_the_numpy_forms_bits(random_cycles):
    for args in (random_cycles, tuple(np.asarray(a, np.float64) for a in random_cycles),
                 tuple(a[0, :7] for a in random_cycles)):
        rot, tr = A.pose(*args)
        ref_rot, ref_tr = numpy_pose(*args)
        assert rot.shape == ref_rot.shape and tr.shape == ref_tr.shape
        np.testing.assert_array_equal(rot, ref_rot)
        np.testing.assert_array_equal(tr, ref_tr)


def test_compiled_root_motion_gives_apply_root_motion_in_usd_order(random_cycles):
    rng = np.random.default_rng(4)
    rot, tr = (x.astype(np.float32) for x in A.pose(*random_cycles))
    t, n = rot.shape[:2]
    tr += rng.normal(0.0, 0.1, tr.shape).astype(np.float32)     # any offset, not only straight up
    position = (rng.random((t, n, 3)) * 60.0 - 30.0).astype(np.float32)
    heading = (rng.random((t, n)) * 7.0 - 3.5).astype(np.float32)
    height = rng.uniform(1.5, 1.95, n)
    ref_rot, ref_tr, _ = apply_root_motion(rot, tr, position, heading, height)
    got_rot, got_tr = K.root_motion(rot, tr, position, heading, root_scale(height))
    assert got_rot.dtype == got_tr.dtype == np.float32
    np.testing.assert_array_equal(got_rot, to_usd_quat_order(ref_rot))
    np.testing.assert_array_equal(got_tr, ref_tr)


def test_look_at_of_the_few_with_a_target_equals_the_whole_crowds(random_cycles):
    """Over three chunks, agents gain and lose targets; the rate-limited angles carry over in both forms."""
    rng = np.random.default_rng(5)
    rot, _ = A.pose(*random_cycles)
    t, n = rot.shape[:2]
    position = rng.random((t, n, 3)) * 20.0
    position[..., 2] = 0.0
    heading = rng.random((t, n)) * 6.0 - 3.0
    height = rng.uniform(1.5, 1.95, n)
    target = np.full((t, n, 3), np.nan)
    some = rng.random(n) < 0.1
    frames = rng.integers(0, t, n)
    for j in np.flatnonzero(some):          # each from a frame on, a few for a stretch in the middle only
        stop = t if j % 3 else min(t, frames[j] + 5)
        target[frames[j]:stop, j] = position[frames[j], j] + rng.normal(0.0, 4.0, 3)
    fast, slow = A.LookState(None, None, None), A.LookState(None, None, None)
    step = A.LOOK_TURN_RATE / 24.0
    for cut in (slice(0, 12), slice(12, 25), slice(25, t)):
        args = (rot[cut], position[cut], heading[cut], height, target[cut], step)
        got = A.apply_look_at(*args, state=fast)
        ref = numpy_look_at(*args, state=slow)
        np.testing.assert_array_equal(got, ref)
        for name in ("yaw", "pitch", "weight"):
            np.testing.assert_array_equal(getattr(fast, name), getattr(slow, name))
    assert (slow.weight > 0).any() and (slow.weight == 0).any()
    turned = np.any(got != rot[25:], axis=(0, 2, 3))
    assert 0 < turned.sum() < n
