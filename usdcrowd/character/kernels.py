"""Compiled loops of the animation writer (numba).

:func:`pose` and :func:`root_motion` are, for each pose, the quaternion
products that :mod:`usdcrowd.character.animation` and
:mod:`usdcrowd.character.root` describe, written as one loop instead of
chains of numpy temporaries: a part writer animating 5,000 agents spent more
time allocating those temporaries than multiplying.

Every product is written out as numpy's form computes it (the same
operations in the same order, zero terms included, float64 throughout), so
the loops give numpy's bits; ``tests/character/test_animation_kernels.py``
compares them with the numpy forms it keeps. They run on one thread: the
part writers that call them already take a core each.

Compiled once per machine (``cache=True``, as :mod:`usdcrowd.sim.kernels`),
and again when the gait's or the rig's constants change
(:mod:`usdcrowd.compiled`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..compiled import cache_one_process_at_a_time, forget_stale_machine_code
from . import gait as A
from . import rig
from .rig import PELVIS_HEIGHT, REST_TRANSLATIONS

forget_stale_machine_code(__file__, A, rig)

_TWO_PI = 2.0 * np.pi
_IDLE = A.IDLE
_K_LO, _K_HI = A.STRIDE_SCALE_RANGE
# Per-class constants as arrays the compiled loop reads (numba freezes module arrays).
_REF_SPEED = np.asarray(A.REF_SPEED, np.float64)
_LEG_YAW, _LEG_PITCH, _LEG_ROLL = (np.asarray(x, np.float64) for x in (A.LEG_YAW, A.LEG_PITCH, A.LEG_ROLL))
_TORSO_TWIST, _TORSO_LEAN, _TORSO_SIDE = (np.asarray(x, np.float64)
                                          for x in (A.TORSO_TWIST, A.TORSO_LEAN, A.TORSO_SIDE_LEAN))
_BREATH, _NOD, _SWAY, _BOB = (np.asarray(x, np.float64) for x in (A.BREATH, A.HEAD_NOD, A.HEAD_SWAY, A.BOB))
_REST = np.asarray(REST_TRANSLATIONS, np.float64)


@njit(cache=True, nogil=True, inline="always")
def _mul(aw, ax, ay, az, bw, bx, by, bz):
    """Hamilton product, term for term as :func:`usdcrowd.character.rig.quat_multiply`."""
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


@njit(cache=True, nogil=True, inline="always")
def _about(axis, angle):
    """Rotation about a coordinate axis (0 = X, 1 = Y, 2 = Z), as ``quat_from_axis_angle`` of a unit axis."""
    half = 0.5 * angle
    s = math.sin(half)
    return (math.cos(half), s if axis == 0 else 0.0, s if axis == 1 else 0.0, s if axis == 2 else 0.0)


@njit(cache=True, nogil=True)
def _pose(cls, phase, speed, rot, tr):
    for i in range(cls.shape[0]):
        c = cls[i]
        ph = _TWO_PI * phase[i]
        if c == _IDLE:
            k = 1.0
        else:
            k = min(max(speed[i] / _REF_SPEED[c], _K_LO), _K_HI)
        s = math.sin(ph)
        s2 = math.sin(2.0 * ph)
        a = _about(2, _LEG_YAW[c] * k * s)
        b = _about(1, _LEG_PITCH[c] * k * s)
        ab = _mul(a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3])
        r = _about(0, _LEG_ROLL[c] * k * s)
        legs = _mul(ab[0], ab[1], ab[2], ab[3], r[0], r[1], r[2], r[3])
        a = _about(2, -_TORSO_TWIST[c] * k * s)
        b = _about(1, _TORSO_LEAN[c] * k + _BREATH[c] * s)
        ab = _mul(a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3])
        r = _about(0, -_TORSO_SIDE[c])
        torso = _mul(ab[0], ab[1], ab[2], ab[3], r[0], r[1], r[2], r[3])
        a = _about(2, _SWAY[c] * s)
        b = _about(1, _NOD[c] * s2 + 0.25 * _TORSO_LEAN[c] * k)
        head = _mul(a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3])
        # Conjugates as numpy's (w, x, y, z) * (1, -1, -1, -1).
        lc = (legs[0] * 1.0, legs[1] * -1.0, legs[2] * -1.0, legs[3] * -1.0)
        tc = (torso[0] * 1.0, torso[1] * -1.0, torso[2] * -1.0, torso[3] * -1.0)
        waist = _mul(lc[0], lc[1], lc[2], lc[3], torso[0], torso[1], torso[2], torso[3])
        neck = _mul(tc[0], tc[1], tc[2], tc[3], head[0], head[1], head[2], head[3])
        for q in range(4):
            rot[i, 0, q] = legs[q]
            rot[i, 1, q] = waist[q]
            rot[i, 2, q] = neck[q]
        for j in range(3):
            for d in range(3):
                tr[i, j, d] = _REST[j, d]
        zz = 1.0 - 2.0 * (legs[1] * legs[1] + legs[2] * legs[2])
        tr[i, 0, 2] = PELVIS_HEIGHT * zz + _BOB[c] * k * 0.5 * (1.0 - math.cos(2.0 * ph))


def pose(anim_class, phase, speed):
    """:func:`usdcrowd.character.animation.pose`, compiled: same arguments, same bits.

    Returns
    -------
    rotations : (..., 3, 4) float64
    translations : (..., 3, 3) float64
    """
    cls, ph, sp = np.broadcast_arrays(np.asarray(anim_class, np.int64), np.asarray(phase, np.float64),
                                      np.asarray(speed, np.float64))
    shape = cls.shape
    m = cls.size
    rot = np.empty((m, 3, 4))
    tr = np.empty((m, 3, 3))
    _pose(np.ascontiguousarray(cls).reshape(m), np.ascontiguousarray(ph).reshape(m),
          np.ascontiguousarray(sp).reshape(m), rot, tr)
    return rot.reshape(shape + (3, 4)), tr.reshape(shape + (3, 3))


@njit(cache=True, nogil=True)
def _root(rot, tr, position, heading, scale, rot_usd, tr_out):
    t_n, n = heading.shape
    for t in range(t_n):
        for i in range(n):
            half = 0.5 * heading[t, i]
            hw, hz = math.cos(half), math.sin(half)
            q = _mul(hw, 0.0, 0.0, hz, rot[t, i, 0, 0], rot[t, i, 0, 1], rot[t, i, 0, 2], rot[t, i, 0, 3])
            # USD's (x, y, z, w) order, float32, as to_usd_quat_order(rot.astype(float32)).
            rot_usd[t, i, 0, 0] = np.float32(q[1])
            rot_usd[t, i, 0, 1] = np.float32(q[2])
            rot_usd[t, i, 0, 2] = np.float32(q[3])
            rot_usd[t, i, 0, 3] = np.float32(q[0])
            for j in range(1, 3):
                rot_usd[t, i, j, 0] = np.float32(rot[t, i, j, 1])
                rot_usd[t, i, j, 1] = np.float32(rot[t, i, j, 2])
                rot_usd[t, i, j, 2] = np.float32(rot[t, i, j, 3])
                rot_usd[t, i, j, 3] = np.float32(rot[t, i, j, 0])
                for d in range(3):
                    tr_out[t, i, j, d] = np.float32(tr[t, i, j, d])
            # The root joint's offset, scaled, turned by the heading (quat_rotate's row-vector matrix of
            # (hw, 0, 0, hz): x' = x m00 + y m10 + z m20, ...), on the ground position.
            vx = tr[t, i, 0, 0] * scale[i]
            vy = tr[t, i, 0, 1] * scale[i]
            vz = tr[t, i, 0, 2] * scale[i]
            m00 = 1 - 2 * (0.0 * 0.0 + hz * hz)
            m01 = 2 * (0.0 * 0.0 - hw * hz)
            m02 = 2 * (0.0 * hz + hw * 0.0)
            m10 = 2 * (0.0 * 0.0 + hw * hz)
            m11 = 1 - 2 * (0.0 * 0.0 + hz * hz)
            m12 = 2 * (0.0 * hz - hw * 0.0)
            m20 = 2 * (0.0 * hz - hw * 0.0)
            m21 = 2 * (0.0 * hz + hw * 0.0)
            m22 = 1 - 2 * (0.0 * 0.0 + 0.0 * 0.0)
            tr_out[t, i, 0, 0] = np.float32(position[t, i, 0] + (vx * m00 + vy * m01 + vz * m02))
            tr_out[t, i, 0, 1] = np.float32(position[t, i, 1] + (vx * m10 + vy * m11 + vz * m12))
            tr_out[t, i, 0, 2] = np.float32(position[t, i, 2] + (vx * m20 + vy * m21 + vz * m22))


def root_motion(rotations, translations, position, heading, scale):
    """The pose put into the world, in USD's quaternion order (:func:`usdcrowd.character.root.apply_root_motion`
    followed by :func:`usdcrowd.character.rig.to_usd_quat_order`), in one pass.

    Parameters
    ----------
    rotations : (t, n, 3, 4) float
        Local joint rotations (w, x, y, z).
    translations : (t, n, 3, 3) float
    position : (t, n, 3) float
    heading : (t, n) float
    scale : (n,) float64
        Root scale (:func:`usdcrowd.character.root.root_scale`).

    Returns
    -------
    rot_usd : (t, n, 3, 4) float32, (x, y, z, w)
    translations : (t, n, 3, 3) float32
    """
    # Read in their own dtypes (float32 from the animator): each value is widened as numpy widens it.
    rot, tr, position = (np.ascontiguousarray(x) for x in (rotations, translations, position))
    rot_usd = np.empty(rot.shape, np.float32)
    tr_out = np.empty(tr.shape, np.float32)
    _root(rot, tr, position, np.ascontiguousarray(heading), np.ascontiguousarray(scale, np.float64), rot_usd, tr_out)
    return rot_usd, tr_out


cache_one_process_at_a_time(globals())
