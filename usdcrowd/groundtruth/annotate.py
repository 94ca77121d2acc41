"""Per-frame annotations from the id and depth passes and the posed meshes.

For every agent the camera could see at a frame (at least one pixel centre
covered by its body when every other surface is removed):

- ``bbox_visible``: the tight box of its pixels in the id pass;
- ``bbox_amodal``: the box of its skinned mesh projected with
  ``CameraView.project`` (the full body, occluded or not; not clipped to the
  image, as MOTChallenge boxes);
- ``visibility = visible_pixels / alone_pixels``: pixels of the id pass
  with its id, over the pixels its body covers rendered alone (same pixel
  centres, so 0 <= visibility <= 1 exactly);
- ``keypoints``: skeleton keypoints (``rig.KEYPOINT_NAMES``) projected, with
  COCO's flag: 0 outside the image or behind the camera, 1 occluded, 2
  visible. A keypoint is visible when the id pass shows the agent itself at
  its pixel, or when the depth pass there is not nearer than the keypoint
  by more than :data:`KEYPOINT_TOLERANCE` (joints sit inside the body);
- 3D ground position and heading; group, leader, role, behaviour and the
  time-sampled state (``crowd:state:*``), and the events it takes part in.

Boxes are ``[x, y, width, height]`` in pixels, x right, y down, the image's
top-left corner at (0, 0) (pixel centres at +0.5).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..cameras.features import frame_intent
from ..core.model import EVENT_KINDS, EventTable
from ..core.shading import is_agent_id
from ..core.view import camera_record
from . import rle

# Joints are inside the body: a surface up to this much nearer still counts as the body itself.
KEYPOINT_TOLERANCE = 0.3


@dataclass
class AgentMetadata:
    """What the stage says about each agent (static part), read once.

    Attributes
    ----------
    by_path : dict[str, dict]
        Prim path -> {"group", "leader", "role", "behavior", "character_type"}.
    state_queries : dict[str, dict[str, Usd.AttributeQuery]]
        Prim path -> state name -> query of ``crowd:state:<name>``.
    events : EventTable
        Every CrowdEvent, its members as rows of ``rows``.
    rows : dict[str, int]
        Agent prim path -> row (the ShotScene's agent order).
    """

    by_path: dict
    state_queries: dict
    events: EventTable
    rows: dict = field(default_factory=dict)
    _per_time: dict = field(default_factory=dict, repr=False)

    @classmethod
    def from_shot(cls, shot) -> "AgentMetadata":
        """Read groups, leaders, roles, behaviours and events from a ShotScene's stage."""
        from pxr import Usd

        from .. import schema
        from ..scenario.events import read_events
        from ..scenario.stageio import time_range

        stage = shot.stage
        ids = dict(zip(shot.agent_paths, (int(i) for i in shot._agent_static[1])))
        by_path, queries = {}, {}
        for path in shot.agent_paths:
            prim = stage.GetPrimAtPath(path)

            def token(name, default=None):
                v = schema.crowd_value(prim, name)      # also where a DCC tool's export keeps it
                return str(v) if v is not None else default

            def target(name):
                r = prim.GetRelationship(name)
                t = r.GetTargets() if r else []
                return str(t[0]) if t else None

            leader = target("crowd:leader")
            by_path[path] = {"group": schema.agent_group(prim),
                             "leader": ids.get(leader) if leader else None, "leader_path": leader,
                             "role": token("role", "member"), "behavior": token("behavior"),
                             "character_type": token("characterType", "human")}
            queries[path] = {name: Usd.AttributeQuery(attr) for name, attr in _state_attributes(prim)}
        rows = {p: i for i, p in enumerate(shot.agent_paths)}
        events = read_events(stage, rows, time_range(stage), agent_ids=shot._agent_static[1])
        return cls(by_path, queries, events, rows)

    def at(self, path: str, time: float) -> dict:
        """Static fields plus state and the events the agent takes part in at ``time``."""
        d = dict(self.by_path.get(path, {}))
        d["state"] = {k: (str(v) if (v := q.Get(time)) is not None else None)
                      for k, q in self.state_queries.get(path, {}).items()}
        if time not in self._per_time:          # every agent of a frame asks for the same time
            self._per_time.clear()
            self._per_time[time] = self.events.agent_events(time, len(self.rows))
        row = self.rows.get(path)
        mine = self._per_time[time][row] if row is not None else []
        d["events"] = [{"path": self.events[i].path, "kind": EVENT_KINDS[self.events[i].kind]} for i in mine]
        return d


def _state_attributes(prim) -> list[tuple[str, object]]:
    """(name, attribute) of an agent's ``crowd:state:*`` tokens that say its state at each frame.

    A shot back from a DCC tool keeps them as custom properties holding one
    value (the state where the tool read them), which is not the agent's state
    at the other frames: those are left out (``validate`` warns of it).
    """
    from .. import schema

    out = []
    for name in ("behavior", "animClass", "health"):
        attr = prim.GetAttribute(f"crowd:state:{name}")
        if attr and (schema.is_agent(prim) or attr.GetNumTimeSamples()):
            out.append((name, attr))
    return out


def _box(x0, y0, x1, y1) -> list[float]:
    return [float(x0), float(y0), float(x1 - x0), float(y1 - y0)]


def _visible_pixels(ids: np.ndarray) -> dict[int, np.ndarray]:
    """Flat pixel indices of each agent id in the id pass, ascending, in one pass over the image."""
    flat = ids.ravel()
    agent_px = np.flatnonzero(is_agent_id(flat))
    order = np.argsort(flat[agent_px], kind="stable")
    agent_px = agent_px[order]
    px_ids = flat[agent_px]
    uniq, first, counts = np.unique(px_ids, return_index=True, return_counts=True)
    return {int(i): agent_px[s:s + c] for i, s, c in zip(uniq, first, counts)}


def _amodal_box(cam, vertices: np.ndarray, w: int, h: int) -> list[float] | None:
    """Box of the mesh's vertices in front of the camera, unclipped; None if none is."""
    uv, z = cam.project(vertices, w, h)
    front = z > cam.near
    if not front.any():
        return None
    lo, hi = uv[front].min(0), uv[front].max(0)
    return _box(lo[0], lo[1], hi[0], hi[1])


def _keypoints(cam, points: np.ndarray, gt, aid: int, w: int, h: int):
    """``[u, v, flag]`` per keypoint (COCO: 0 not in image, 1 occluded, 2 visible) and its camera depth."""
    kuv, kz = cam.project(points, w, h)
    kps = []
    for (u, v), zk in zip(kuv, kz):
        flag = 0
        if zk > cam.near and 0 <= u < w and 0 <= v < h:
            col, row = int(u), int(v)
            seen = gt.ids[row, col] == aid or gt.depth_z[row, col] >= zk - KEYPOINT_TOLERANCE
            flag = 2 if seen else 1
        kps.append([float(u), float(v), flag] if np.isfinite(u) and np.isfinite(v) else [0.0, 0.0, 0])
    return kps, kz


def annotate_frame(result, metadata: AgentMetadata | None = None, keypoint_names=None) -> dict:
    """The JSON-ready record of one rendered frame.

    Parameters
    ----------
    result : FrameResult
        With ground truth (``result.gt`` not None).
    metadata : AgentMetadata, optional
        Stage attributes; without it the agent entries carry geometry only.
    keypoint_names : sequence of str, optional
        Defaults to ``rig.KEYPOINT_NAMES``.

    Returns
    -------
    dict
        ``time``, ``width``, ``height``, ``camera`` (see
        :func:`~usdcrowd.render.final.camera.camera_record`), ``id_table``
        (id -> prim path), ``agents`` (list, sorted by track id).
    """
    from ..character import rig

    gt = result.gt
    if gt is None:
        raise ValueError("annotate_frame needs a frame rendered with ground truth")
    h, w = gt.ids.shape
    cam, poses = result.camera, result.poses
    names = tuple(keypoint_names or rig.KEYPOINT_NAMES)

    visible = _visible_pixels(gt.ids)
    keypoints = poses.keypoints() if len(poses) else np.zeros((0, len(names), 3))
    agents = []
    for i, path in enumerate(poses.paths):
        aid = int(poses.agent_ids[i])
        alone = int(gt.alone_pixels.get(aid, 0))
        if not poses.visible[i] or alone == 0:
            continue
        px = visible.get(aid, np.zeros(0, np.int64))
        ys, xs = np.divmod(px, w)
        bbox_visible = _box(xs.min(), ys.min(), xs.max() + 1, ys.max() + 1) if px.size else None
        bbox_amodal = _amodal_box(cam, result.vertices[i], w, h)
        kps, kz = _keypoints(cam, keypoints[i], gt, aid, w, h)
        joints = poses.joints_world[i]
        heading = float(np.arctan2(joints[0, 0, 1], joints[0, 0, 0]))      # legs joint's +X, the facing
        entry = {
            "track_id": aid, "path": path,
            "bbox_visible": bbox_visible, "bbox_amodal": bbox_amodal,
            "visible_pixels": int(px.size), "alone_pixels": alone,
            "visibility": float(px.size / alone),
            "segmentation": rle.encode_pixels(xs * h + ys, h, w),
            "keypoints": kps, "keypoint_depth": [float(v) for v in kz],
            "position_3d": keypoints[i][names.index("ground")].tolist() if "ground" in names else None,
            "heading": heading,
        }
        if metadata is not None:
            entry.update(metadata.at(path, result.time))
        agents.append(entry)
    agents.sort(key=lambda a: a["track_id"])
    return {"time": result.time, "width": int(w), "height": int(h), "camera": camera_record(cam, w, h),
            "camera_intent": frame_intent(cam, poses, w, h),
            "keypoint_names": list(names), "id_table": {str(k): v for k, v in sorted(result.id_paths.items())},
            "agents": agents}
