"""The cinematic feature estimator (seed 002, section 4): a filmed pair's features from 2D poses.

A reference that is a film clip has no stage to read: what the gating
network needs (:mod:`usdcrowd.cameras.moe`) must come from the pictures.
Per frame, the two main characters' 2D joints (:data:`JOINTS`: the head,
the neck, both shoulders, the hip centre and both hips, the paper's
selection, and the nose: seen in profile, the shoulders' left and right are
a detector's guess, the nose says which way the character faces) come from a pose detector (:mod:`usdcrowd.cameras.clip_poses`);
from a window of them (:data:`WINDOW`, the paper's 4 frames before and 3
after) a small network estimates the features the screen does not show
directly: the direction from A to the camera in the pair's frame (u), the
frame's span at A, the distance between the characters and their shoulder
angles. The heads' screen positions are read off the joints.

The network is the paper's (appendix A: two Conv1d + batch norm + ReLU +
max-pool blocks over the window, two fully connected layers), trained on
synthetic data only, as the paper trains it: the controllers' cameras
filming drawn two-character motions, the joints of :data:`BODY` projected
(``tools/train_feature_estimator.py``, PyTorch in its own venv). The
weights ship as ``feature_estimator.npz``; inference here is numpy, batch
norm folded into the convolutions.

The joints are centred on the heads' midpoint before they go in. A shift
on screen is, to within the lens's small perspective error, a rotation of
the camera, which leaves its position about the pair (theta, phi) as it
is: the paper's argument for estimating the angles from centred poses.

What a picture cannot give: how fast the pair moves and turns in the world
(a camera that follows a walking pair sees it stand still on screen; the
paper names background motion as the missing cue). Those three character
features are set to the training data's mean, the gating network's
"unknown".
"""

from __future__ import annotations

from functools import cached_property
from pathlib import Path

import numpy as np

from .moe import PAIR_MOTION

JOINTS = ("head", "neck", "shoulder_l", "shoulder_r", "hip", "hip_l", "hip_r", "nose")
HEAD = 1.625            # the rig's head point (midway between neck and head top) on the canonical body, metres
# Where the joints sit on the canonical body (usdcrowd.character.body): x forward, y to its left, z up, metres.
# Heights as the detector finds them on usdcrowd's characters (tools/calibrate_pose_joints.py: the ears' midpoint
# 1.60, shoulders 1.42, hips 0.94); widths a person's (shoulder joints 0.19 m out, hips 0.1). On usdcrowd's
# characters the detector puts the shoulders 0.08-0.12 m out (it still swaps left and right in about one
# view of a face in five) and the nose at the head's centre: the training draws the widths and the nose
# between the two (tools/train_feature_estimator.py).
BODY = np.array([[0.0, 0.0, 1.61], [0.0, 0.0, 1.42], [0.0, 0.19, 1.42], [0.0, -0.19, 1.42],
                 [0.0, 0.0, 0.94], [0.0, 0.1, 0.94], [0.0, -0.1, 0.94], [0.105, 0.0, 1.60]])
UPPER = np.array([True, True, True, True, False, False, False, True])     # the joints that turn with the shoulders
WINDOW = (4, 3)         # frames before and after the estimated one (the paper's t_c = 8)
# What the network estimates per frame: u (3), log span, dAB, sin/cos of sA, sB and sAB.
OUTPUTS = ("u_along", "u_across", "u_up", "log_span", "d_ab", "sin_sa", "cos_sa", "sin_sb", "cos_sb",
           "sin_sab", "cos_sab")
WEIGHTS = Path(__file__).with_name("feature_estimator.npz")


# ------------------------------------------------------------------------------------------ data
def body_points(heads, yaws, hip_yaws=None, body: np.ndarray = BODY) -> np.ndarray:
    """(t, 8, 3) world positions of :data:`JOINTS` of a character standing upright.

    Parameters
    ----------
    heads : (t, 3) float
        Head points, metres, Z up (the body is scaled to the head's height).
    yaws : (t,) float
        Shoulder facing, radians.
    hip_yaws : (t,) float, optional
        The hips' facing (default: the shoulders').
    body : (8, 3) float
        The joints on the canonical body (default :data:`BODY`).
    """
    heads = np.asarray(heads, dtype=np.float64)
    yaws = np.asarray(yaws, dtype=np.float64)
    hip_yaws = yaws if hip_yaws is None else np.asarray(hip_yaws, dtype=np.float64)
    scale = heads[:, 2:3, None] / HEAD                                        # (t, 1, 1)
    pts = np.asarray(body, dtype=np.float64)[None] * scale
    yaw = np.where(UPPER[None], yaws[:, None], hip_yaws[:, None])             # (t, 8)
    c, s = np.cos(yaw), np.sin(yaw)
    x, y = pts[..., 0] * c - pts[..., 1] * s, pts[..., 0] * s + pts[..., 1] * c
    ground = heads[:, None, :2]
    return np.stack([ground[..., 0] + x, ground[..., 1] + y, pts[..., 2]], -1)


def project(cam_to_world, points, fov_x: float, aspect: float) -> np.ndarray:
    """(t, k, 2) NDC of points (t, k, 3) seen by cameras (t, 4, 4) (:mod:`usdcrowd.cameras.toric`'s
    conventions: x right and y up, both in [-1, 1] across the frame)."""
    cam_to_world = np.asarray(cam_to_world, dtype=np.float64)
    rel = np.asarray(points, dtype=np.float64) - cam_to_world[:, None, 3, :3]
    c = np.einsum("tkj,tij->tki", rel, cam_to_world[:, :3, :3])
    t = np.tan(0.5 * fov_x)
    depth = np.maximum(-c[..., 2], 1e-6)             # in front of the camera (a point behind is far off screen)
    return np.stack([c[..., 0] / (depth * t), c[..., 1] * aspect / (depth * t)], -1)


def frame_inputs(joints: np.ndarray) -> np.ndarray:
    """(t, 32) network inputs per frame from both characters' joints (t, 2, 8, 2) NDC: centred on the
    heads' midpoint, A's eight joints then B's."""
    joints = np.asarray(joints, dtype=np.float64)
    centre = 0.5 * (joints[:, 0, 0] + joints[:, 1, 0])
    return (joints - centre[:, None, None]).reshape(len(joints), -1)


def windows(x: np.ndarray) -> np.ndarray:
    """(t, 32, 8) per-frame inputs (t, 32) gathered over :data:`WINDOW` (ends held)."""
    before, after = WINDOW
    idx = np.clip(np.arange(len(x))[:, None] + np.arange(-before, after + 1)[None], 0, len(x) - 1)
    return np.transpose(x[idx], (0, 2, 1))


# ------------------------------------------------------------------------------------ network
class FeatureEstimator:
    """The trained network, from a weights file (numpy arrays, float32).

    Arrays: ``conv{k}.weight`` (out, in, 3) and ``conv{k}.bias``,
    ``bn{k}.weight``, ``bias``, ``running_mean``, ``running_var`` (out,)
    for k = 1, 2; ``fc1.weight`` (128, 256), ``fc1.bias``; ``fc2.weight``
    (11, 128), ``fc2.bias``; ``in_std`` (32,), ``out_mean``, ``out_std``
    (11,) (outputs are standardised).
    """

    def __init__(self, path: str | Path = WEIGHTS):
        from .moe import load_weights

        data = load_weights(path, "the feature estimator")
        self.path = str(path)
        self.w = {k: data[k].astype(np.float64) for k in data.files if k != "about"}
        self.about = str(data["about"]) if "about" in data.files else ""

    @cached_property
    def _convs(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Each convolution with its batch norm folded in: (out, in, 3) weights and (out,) bias."""
        out = []
        for k in (1, 2):
            w = self.w
            scale = w[f"bn{k}.weight"] / np.sqrt(w[f"bn{k}.running_var"] + 1e-5)
            out.append((w[f"conv{k}.weight"] * scale[:, None, None],
                        (w[f"conv{k}.bias"] - w[f"bn{k}.running_mean"]) * scale + w[f"bn{k}.bias"]))
        return out

    def forward(self, x: np.ndarray) -> np.ndarray:
        """(b, 11) standardised outputs of (b, 32, 8) windows (already divided by ``in_std``)."""
        for weight, bias in self._convs:
            pad = np.pad(x, ((0, 0), (0, 0), (1, 1)))
            # Zero-padded convolution of width 3: the three shifted copies against the kernel's taps.
            x = sum(np.einsum("bit,oi->bot", pad[:, :, k:k + x.shape[2]], weight[:, :, k]) for k in range(3))
            x = np.maximum(x + bias[None, :, None], 0.0)
            x = np.maximum(x[:, :, 0::2], x[:, :, 1::2])                       # max-pool of 2
        x = np.maximum(x.reshape(len(x), -1) @ self.w["fc1.weight"].T + self.w["fc1.bias"], 0.0)
        return x @ self.w["fc2.weight"].T + self.w["fc2.bias"]

    def estimate(self, joints: np.ndarray) -> np.ndarray:
        """(t, 11) :data:`OUTPUTS` per frame from both characters' joints (t, 2, 8, 2) NDC."""
        x = windows(frame_inputs(joints)) / self.w["in_std"][None, :, None]
        return self.forward(x) * self.w["out_std"] + self.w["out_mean"]

    def features(self, joints: np.ndarray, char_mean: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The gating network's (t, 10) character and (t, 8) camera features (:mod:`usdcrowd.cameras.moe`)
        of a clip whose two characters' joints are ``joints`` (t, 2, 8, 2) NDC.

        ``char_mean`` (10,) fills what a picture cannot give (the pair's velocity and turn rate).
        """
        est = self.estimate(joints)
        u = est[:, 0:3] / np.maximum(np.linalg.norm(est[:, 0:3], axis=1, keepdims=True), 1e-9)
        sincos = est[:, 5:11].reshape(len(est), 3, 2)
        sincos = (sincos / np.maximum(np.linalg.norm(sincos, axis=2, keepdims=True), 1e-9)).reshape(len(est), 6)
        char = np.column_stack([np.maximum(est[:, 4], 0.05), sincos,
                                np.tile(np.asarray(char_mean, dtype=np.float64)[PAIR_MOTION], (len(est), 1))])
        heads = np.asarray(joints, dtype=np.float64)[:, :, 0]
        cam = np.column_stack([heads[:, 0], heads[:, 1], u, est[:, 3]])
        return char, cam
