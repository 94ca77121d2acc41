"""Root motion: where an agent's skeleton is in the world.

An agent's world placement is carried by the root joint (legs) of its
SkelAnimation rather than by separate transform ops on the SkelRoot: that is
two time samples per agent and frame instead of four, which is what keeps
authoring 10,000 agents x 300 frames within the benchmark target.
"""

from __future__ import annotations

import numpy as np

from .rig import HEAD_TOP, quat_from_axis_angle, quat_multiply, quat_rotate


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
