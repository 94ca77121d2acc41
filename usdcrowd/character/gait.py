"""The walk cycle's parameters, per animation class (seed 003).

How far and how fast each class steps and how much each joint swings:
:mod:`usdcrowd.character.animation` poses the skeleton from them, and
:mod:`usdcrowd.character.kernels` compiles the same pose.
"""

from __future__ import annotations

import numpy as np

from ..core.model import ANIM_CLASSES

IDLE, WALK, RUN, STRIDE_LEFT, STRIDE_RIGHT = range(len(ANIM_CLASSES))


# Per-class cycle parameters, indexed by class code (idle, walk, run,
# strideLeft, strideRight). Stride length = distance covered per full cycle
# (two steps); idle "cycles" are breaths at a fixed rate.
STRIDE_LENGTH = np.array([np.nan, 1.4, 2.2, 1.0, 1.0])  # m per cycle
REF_SPEED = np.array([1.0, 1.3, 3.5, 1.0, 1.0])  # m/s at which amplitudes are nominal
IDLE_FREQUENCY = 0.25  # Hz, a slow breath
_D = np.radians
LEG_PITCH = _D(np.array([0.0, 12.0, 20.0, 3.0, 3.0]))  # legs swing about Y
LEG_YAW = _D(np.array([0.0, 6.0, 8.0, 0.0, 0.0]))  # hip twist about Z
LEG_ROLL = _D(np.array([0.0, 0.0, 0.0, 10.0, 10.0]))  # sideways swing about X
TORSO_TWIST = _D(np.array([0.0, 4.0, 6.0, 0.0, 0.0]))  # shoulders against hips
TORSO_LEAN = _D(np.array([0.0, 3.0, 12.0, 0.0, 0.0]))  # forward lean, pitch
TORSO_SIDE_LEAN = _D(np.array([0.0, 0.0, 0.0, 6.0, -6.0]))  # toward the stride side
BREATH = _D(np.array([1.5, 0.5, 0.8, 0.5, 0.5]))  # torso pitch oscillation
HEAD_NOD = _D(np.array([0.0, 1.5, 2.5, 1.0, 1.0]))  # residual head bob, twice per cycle
HEAD_SWAY = _D(np.array([3.0, 0.0, 0.0, 0.0, 0.0]))  # idle glance left/right
BOB = np.array([0.003, 0.025, 0.05, 0.015, 0.015])  # pelvis rise, metres
STRIDE_SCALE_RANGE = (0.6, 1.25)  # amplitude scale of slow and fast strides, relative to REF_SPEED
