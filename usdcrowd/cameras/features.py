"""Cinematic features of a camera filming two characters (seed 002, section 4.1, appendix B).

Per frame, for characters A and B and a camera:

- ``pA``, ``pB``: on-screen positions of their heads (normalised device
  coordinates, as :mod:`usdcrowd.cameras.toric`);
- ``theta``, ``phi``: the camera's toric angles about the two heads;
- ``dAB``: the distance between the two characters on the ground, metres;
- ``sA``, ``sB``: the yaw of each character's shoulders relative to the
  camera's view direction, radians in [-pi, pi) (0: the character faces
  away from the camera, looking where it looks; pi: it faces the camera);
- ``sAB``: the yaw of B's shoulders relative to A's (sB - sA, wrapped);
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

NAMES = ("pA_x", "pA_y", "pB_x", "pB_y", "theta", "phi", "dAB", "sA", "sB", "sAB")


@dataclass
class CinematicFeatures:
    """Features of ``t`` frames (see the module); NaN where the toric angles are undefined."""

    times: np.ndarray        # (t,) float
    p_a: np.ndarray          # (t, 2)
    p_b: np.ndarray          # (t, 2)
    theta: np.ndarray        # (t,)
    phi: np.ndarray          # (t,)
    d_ab: np.ndarray         # (t,)
    s_a: np.ndarray          # (t,)
    s_b: np.ndarray          # (t,)
    s_ab: np.ndarray         # (t,)
    main: int                # 0: A, 1: B

    def rows(self) -> list[dict]:
        """One dict per frame (for CSV and JSON)."""
        cols = np.column_stack([self.p_a, self.p_b, self.theta, self.phi, self.d_ab, self.s_a, self.s_b, self.s_ab])
        return [{"time": float(t), **{n: (None if np.isnan(v) else float(v)) for n, v in zip(NAMES, row)},
                 "M": "A" if self.main == 0 else "B"} for t, row in zip(self.times, cols)]


def head_and_facing(joints_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Head point (n, 3) and shoulder yaw (n,) of posed agents (joint-to-world matrices (n, 3, 4, 4))."""
    from ..character import rig

    k = rig.keypoints(joints_world)
    neck, top = k[:, rig.KEYPOINT_NAMES.index("neck")], k[:, rig.KEYPOINT_NAMES.index("headTop")]
    forward = joints_world[:, 1, 0, :3]               # the torso's +X in the world
    return 0.5 * (neck + top), np.arctan2(forward[:, 1], forward[:, 0])


def cinematic_features(times, heads_a, heads_b, yaw_a, yaw_b, ground_a, ground_b, boxes_a, boxes_b,
                       cam_to_world, fov_x: float, aspect: float) -> CinematicFeatures:
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
    fov_x, aspect : float
        Horizontal field of view (radians) and width / height.
    """
    t = len(times)
    p_a, p_b = np.full((t, 2), np.nan), np.full((t, 2), np.nan)
    theta, phi = np.full(t, np.nan), np.full(t, np.nan)
    for k in range(t):
        try:
            p_a[k], p_b[k], theta[k], phi[k] = pose_to_toric(cam_to_world[k], heads_a[k], heads_b[k], fov_x, aspect)
        except ToricError:
            pass                # a head behind the camera, or the two heads on one vertical
    back = np.asarray(cam_to_world)[:, 2, :2]         # the camera's back axis, on the ground
    view_yaw = np.arctan2(-back[:, 1], -back[:, 0])
    s_a, s_b = wrap_angle(np.asarray(yaw_a) - view_yaw), wrap_angle(np.asarray(yaw_b) - view_yaw)
    d_ab = np.linalg.norm((np.asarray(ground_b) - np.asarray(ground_a))[:, :2], axis=1)
    main = int(np.nanmean(boxes_b) > np.nanmean(boxes_a))
    return CinematicFeatures(np.asarray(times, dtype=np.float64), p_a, p_b, theta, phi, d_ab, s_a, s_b,
                             wrap_angle(s_b - s_a), main)


def write_features(features: CinematicFeatures, csv_path, json_path=None, **about) -> list[str]:
    """Write the features as CSV (and JSON, with ``about``: camera, characters...) atomically."""
    from ..atomic import atomic_path

    rows = features.rows()
    written = []
    with atomic_path(csv_path) as tmp:
        with open(tmp, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=["time", *NAMES, "M"])
            w.writeheader()
            w.writerows(rows)
    written.append(os.fspath(csv_path))
    if json_path is not None:
        with atomic_path(json_path) as tmp:
            tmp.write_text(json.dumps({**about, "main": "AB"[features.main], "frames": rows}, indent=1))
        written.append(os.fspath(json_path))
    return written


def shot_features(shot, camera: str | None, agent_a: str, agent_b: str, times=None,
                  width: int = 1920, height: int = 1080) -> tuple[CinematicFeatures, dict]:
    """Cinematic features of a shot's camera filming two of its agents.

    Parameters
    ----------
    shot : path-like or ShotScene
    camera : str or None
        Camera prim path (None: the first camera).
    agent_a, agent_b : str
        Agent prim paths, or their last path component when it is unique.
    times : sequence of float, optional
        Time codes (default: every frame of the shot).
    width, height : int
        Image size the screen boxes are measured in (its aspect is the framing's).

    Returns
    -------
    features : CinematicFeatures
    about : dict
        Camera and agent paths, field of view and aspect (for the JSON).
    """
    from ..errors import StageError
    from ..render.scene import ShotScene

    scene = shot if isinstance(shot, ShotScene) else ShotScene(shot)
    paths = scene.agent_paths

    def row(name):
        hits = [i for i, p in enumerate(paths) if p == name or p.rsplit("/", 1)[-1] == name]
        if len(hits) != 1:
            raise StageError(f"{'no' if not hits else 'more than one'} agent named {name!r} "
                             f"(give its prim path)", file=scene.path, prim=name)
        return hits[0]

    ia, ib = row(agent_a), row(agent_b)
    times = np.asarray(scene.time_codes if times is None else times, dtype=np.float64)
    scene.check_times(times)
    heads, yaws, grounds, boxes, mats = [], [], [], [], []
    view = None
    for t in times:
        view = scene.camera(camera, t)
        poses = scene.agents(t)
        head, yaw = head_and_facing(poses.joints_world[[ia, ib]])
        key = poses.keypoints()[[ia, ib]]
        uv, z = view.project(key, width, height)
        size = np.where((z > 0).all(axis=1), np.ptp(uv[..., 0], axis=1) * np.ptp(uv[..., 1], axis=1), 0.0)
        heads.append(head)
        yaws.append(yaw)
        grounds.append(key[:, -1])
        boxes.append(size)
        mats.append(view.cam_to_world)
    heads, yaws, grounds, boxes = (np.array(v) for v in (heads, yaws, grounds, boxes))
    fov_x, aspect = np.radians(view.fov_x()), width / height
    features = cinematic_features(times, heads[:, 0], heads[:, 1], yaws[:, 0], yaws[:, 1], grounds[:, 0],
                                  grounds[:, 1], boxes[:, 0], boxes[:, 1], np.array(mats), fov_x, aspect)
    about = {"shot": scene.path, "camera": view.path, "A": paths[ia], "B": paths[ib],
             "fov_x_deg": float(np.degrees(fov_x)), "aspect": aspect}
    return features, about
