"""Characters: the three-joint skeleton, the skinned body and its animation.

Pure numpy (and trimesh for the body); :mod:`usdcrowd.usd` turns these arrays
into UsdSkel prims.
"""

from ..core.model import ANIM_CLASSES
from .animation import (BLEND_FRAMES, IDLE_SPEED, RUN_SPEED, advance_phase, animate,
                        apply_look_at, blend_transitions, classify, head_forward, pose)
from .body import Body, build_body
from .rig import (BIND_SKEL, JOINTS, KEYPOINT_NAMES, PARENT, REST_LOCAL, compose_local,
                  joint_positions, keypoints, local_to_skel, quat_angle, quat_from_axis_angle,
                  quat_multiply, quat_slerp, quat_to_matrix, skin_points, skinning_transforms,
                  to_usd_quat_order)

__all__ = [
    "ANIM_CLASSES", "BLEND_FRAMES", "IDLE_SPEED", "RUN_SPEED", "advance_phase", "animate",
    "apply_look_at", "blend_transitions", "classify", "head_forward", "pose",
    "Body", "build_body",
    "BIND_SKEL", "JOINTS", "KEYPOINT_NAMES", "PARENT", "REST_LOCAL", "compose_local",
    "joint_positions", "keypoints", "local_to_skel", "quat_angle", "quat_from_axis_angle",
    "quat_multiply", "quat_slerp", "quat_to_matrix", "skin_points", "skinning_transforms",
    "to_usd_quat_order",
]
