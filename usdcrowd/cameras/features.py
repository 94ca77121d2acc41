"""Cinematic features of a camera filming two characters (seed 002, section 4.1, appendix B).

Per frame, for characters A and B and a camera:

- ``pA``, ``pB``: on-screen positions of their heads (normalised device
  coordinates, as :mod:`usdcrowd.cameras.toric`);
- ``theta``, ``phi``: the camera's toric angles about the two heads;
- ``dAB``: the distance between the two characters on the ground, metres;
- ``sA``, ``sB``: the angle between the line AB and each character's
  shoulders' front, radians in [-pi, pi) (written in degrees, like every
  angle :func:`write_features` writes), positive counter-clockwise seen
  from above (0: A faces B, and B faces A; pi: it turns its back on the
  other). Like the paper's, they do not depend on the camera;
- ``sAB``: the yaw of B's shoulders relative to A's, wrapped;
- ``M``: the main character over the sequence, 0 for A and 1 for B: the one
  with the larger mean on-screen box (width x height of its projected
  keypoints), Hitchcock's rule as appendix B applies it.

The heads and shoulders come from the three-bone rig: the head is midway
between the neck and the head top, the shoulders face along the torso
joint's +X (the rig's forward).
"""

from __future__ import annotations

import csv
import json
import os
from dataclasses import dataclass

import numpy as np

from ..character.rig import wrap_angle
from .toric import ToricError, pose_to_toric

# The features as written (CSV header, JSON keys): each with its unit. Angles in degrees, as the USD attributes
# (crowd:toric:theta) and the renderer's camera_intent have them; screen positions in NDC.
COLUMNS = ("pA_x_ndc", "pA_y_ndc", "pB_x_ndc", "pB_y_ndc", "theta_deg", "phi_deg", "dAB_m", "sA_deg", "sB_deg",
           "sAB_deg")


@dataclass
class CinematicFeatures:
    """Features of ``t`` frames (see the module); NaN where the toric angles are undefined.

    Angles are radians here; :meth:`rows` (what is written) gives them in degrees.
    """

    times: np.ndarray        # (t,) float
    p_a: np.ndarray          # (t, 2)
    p_b: np.ndarray          # (t, 2)
    theta: np.ndarray        # (t,) radians
    phi: np.ndarray          # (t,) radians
    d_ab: np.ndarray         # (t,) metres
    s_a: np.ndarray          # (t,) radians
    s_b: np.ndarray          # (t,) radians
    s_ab: np.ndarray         # (t,) radians
    main: int                # 0: A, 1: B

    def rows(self) -> list[dict]:
        """One dict per frame (for CSV and JSON), keyed by :data:`COLUMNS`: angles in degrees."""
        deg = np.degrees
        cols = np.column_stack([self.p_a, self.p_b, deg(self.theta), deg(self.phi), self.d_ab, deg(self.s_a),
                                deg(self.s_b), deg(self.s_ab)])
        return [{"time_code": float(t), **{n: (None if np.isnan(v) else float(v)) for n, v in zip(COLUMNS, row)},
                 "M": "A" if self.main == 0 else "B"} for t, row in zip(self.times, cols)]


def head_and_facing(joints_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Head point (n, 3) and shoulder yaw (n,) of posed agents (joint-to-world matrices (n, 3, 4, 4))."""
    from ..character import rig

    k = rig.keypoints(joints_world)
    neck, top = k[:, rig.KEYPOINT_NAMES.index("neck")], k[:, rig.KEYPOINT_NAMES.index("headTop")]
    forward = joints_world[:, 1, 0, :3]               # the torso's +X in the world
    return 0.5 * (neck + top), np.arctan2(forward[:, 1], forward[:, 0])


def cinematic_features(times, heads_a, heads_b, yaw_a, yaw_b, ground_a, ground_b, boxes_a, boxes_b,
                       cam_to_world, fov_x, aspect: float) -> CinematicFeatures:
    """Features of a camera filming A and B.

    Parameters
    ----------
    times : (t,) float
    heads_a, heads_b : (t, 3) float
        Head points, metres.
    yaw_a, yaw_b : (t,) float
        Shoulder yaw in the world, radians.
    ground_a, ground_b : (t, 3) float
        Ground points, metres.
    boxes_a, boxes_b : (t,) float
        On-screen box areas (any unit; only their means are compared).
    cam_to_world : (t, 4, 4) float
        Row-vector camera-to-world matrices.
    fov_x : float or (t,) float
        Horizontal field of view, radians (per frame for a zooming camera).
    aspect : float
        Width / height.
    """
    t = len(times)
    fovs = np.broadcast_to(np.asarray(fov_x, dtype=np.float64), (t,))
    p_a, p_b = np.full((t, 2), np.nan), np.full((t, 2), np.nan)
    theta, phi = np.full(t, np.nan), np.full(t, np.nan)
    for k in range(t):
        try:
            p_a[k], p_b[k], theta[k], phi[k] = pose_to_toric(cam_to_world[k], heads_a[k], heads_b[k], fovs[k], aspect)
        except ToricError:
            pass                # a head behind the camera, or the two heads on one vertical
    d_ab, s_a, s_b, s_ab = pair_orientation(ground_a, ground_b, yaw_a, yaw_b)
    main = int(np.nanmean(boxes_b) > np.nanmean(boxes_a))
    return CinematicFeatures(np.asarray(times, dtype=np.float64), p_a, p_b, theta, phi, d_ab, s_a, s_b, s_ab, main)


def pair_orientation(ground_a, ground_b, yaw_a, yaw_b):
    """dAB (m), sA, sB and sAB (radians) of two characters (see the module), one per row.

    Parameters
    ----------
    ground_a, ground_b : (t, 3) or (t, 2) float
        Where they stand, metres.
    yaw_a, yaw_b : (t,) float
        Their shoulders' facing in the world, radians.
    """
    ab = (np.asarray(ground_b, dtype=np.float64) - np.asarray(ground_a, dtype=np.float64))[:, :2]
    toward_b = np.arctan2(ab[:, 1], ab[:, 0])
    yaw_a, yaw_b = np.asarray(yaw_a, dtype=np.float64), np.asarray(yaw_b, dtype=np.float64)
    return (np.linalg.norm(ab, axis=1), wrap_angle(yaw_a - toward_b), wrap_angle(yaw_b - toward_b - np.pi),
            wrap_angle(yaw_b - yaw_a))


def write_features(features: CinematicFeatures, csv_path, json_path=None, **about) -> list[str]:
    """Write the features as CSV (and JSON, with ``about``: camera, characters...) atomically.

    Both name each value with its unit (:data:`COLUMNS`: ``theta_deg``, ``dAB_m``...): angles in
    degrees, distances in metres, screen positions in normalised device coordinates, ``time`` in
    time codes (frames).
    """
    from ..atomic import atomic_path

    rows = features.rows()
    written = []
    with atomic_path(csv_path) as tmp:
        with open(tmp, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=["time_code", *COLUMNS, "M"])
            w.writeheader()
            w.writerows(rows)
    written.append(os.fspath(csv_path))
    if json_path is not None:
        with atomic_path(json_path) as tmp:
            tmp.write_text(json.dumps({**about, "main": "AB"[features.main], "frames": rows}, indent=1))
        written.append(os.fspath(json_path))
    return written


def frame_intent(view, poses, width: int, height: int) -> dict | None:
    """Camera-intent ground truth of one rendered frame of a toric camera, or None for other cameras.

    The features are measured on the frame as rendered (the camera's pose,
    the characters' posed rigs), beside the authored intent
    (``view.toric``): a smoothed or edited camera differs from what was
    asked, and this says by how much.

    Parameters
    ----------
    view : CameraView
    poses : AgentPoses
        The frame's posed agents (must include the two targets).
    width, height : int
        Image size (its aspect is the framing's).

    Returns
    -------
    dict or None
        ``behavior``, ``shot_size``, ``targets`` [A, B], ``pA``, ``pB``
        (NDC), ``theta``, ``phi`` (degrees; None where a head is behind the
        camera), ``dAB`` (m), ``sA``, ``sB``, ``sAB`` (degrees),
        ``main_height`` (A's on-screen height over the image's, from its
        keypoints), and ``authored`` (the camera's own values).
    """
    intent = view.toric
    if intent is None:
        return None
    rows = {p: i for i, p in enumerate(poses.paths)}
    a, b = intent["target_a"], intent["target_b"]
    out = {"behavior": intent["behavior"], "shot_size": intent["shot_size"], "targets": [a, b],
           "authored": {k: intent[k] for k in ("p_a", "p_b", "theta", "phi")}}
    if a not in rows or b not in rows:
        return {**out, "pA": None, "pB": None, "theta": None, "phi": None}
    idx = [rows[a], rows[b]]
    head, yaw = head_and_facing(poses.joints_world[idx])
    key = poses.keypoints()[idx]
    fov_x, aspect = np.radians(view.fov_x()), width / height
    try:
        p_a, p_b, theta, phi = pose_to_toric(view.cam_to_world, head[0], head[1], fov_x, aspect)
        toric = {"pA": [float(v) for v in p_a], "pB": [float(v) for v in p_b],
                 "theta": float(np.degrees(theta)), "phi": float(np.degrees(phi))}
    except ToricError:
        toric = {"pA": None, "pB": None, "theta": None, "phi": None}
    d_ab, s_a, s_b, s_ab = (float(v[0]) for v in pair_orientation(key[:1, -1], key[1:, -1], yaw[:1], yaw[1:]))
    uv, z = view.project(key[0], width, height)
    main_height = float(np.ptp(uv[:, 1]) / height) if (z > 0).all() else None
    return {**out, **toric, "dAB": d_ab, "sA": float(np.degrees(s_a)), "sB": float(np.degrees(s_b)),
            "sAB": float(np.degrees(s_ab)), "main_height": main_height}
