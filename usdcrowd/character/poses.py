"""Posed agents at one time code, as numpy: what renderers skin and annotators project.

Pure core (no ``pxr``, no renderer). :meth:`usdcrowd.scenario.shot_scene.ShotScene.agents`
fills :class:`AgentPoses` from a shot's skeletons.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import rig


@dataclass
class AgentPoses:
    """Every agent at one time code.

    Attributes
    ----------
    time : float
    paths : list[str]
    agent_ids : (n,) int32
        Track ids (crowd:agentId).
    visible : (n,) bool
        Rendered (not an invisible leader, not hidden).
    color : (n, 3) float32
        Linear RGB of the top (the colour an agent is known by).
    joints_world : (n, 3, 4, 4) float64
        Joint-to-world matrices (canonical), legs / torso / head.
    palette : (n, r, 3) float32
        Linear RGB of each body region (ShotScene.body.regions indexes the
        rows); None: ``color`` all over.
    """

    time: float
    paths: list[str]
    agent_ids: np.ndarray
    visible: np.ndarray
    color: np.ndarray
    joints_world: np.ndarray
    palette: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.paths)

    @property
    def skinning(self) -> np.ndarray:
        """(n, 3, 4, 4) skinning transforms, bind pose to canonical world."""
        return rig.skinning_transforms(self.joints_world)

    def keypoints(self) -> np.ndarray:
        """(n, 5, 3) world keypoints in rig.KEYPOINT_NAMES order (the ground point
        is the pelvis dropped by its rest height, which follows terrain)."""
        k = rig.keypoints(self.joints_world)
        scale = np.linalg.norm(self.joints_world[:, 0, 0, :3], axis=-1)
        k[:, 4] = self.joints_world[:, 0, 3, :3] - np.stack(
            [np.zeros_like(scale), np.zeros_like(scale), rig.PELVIS_HEIGHT * scale], -1)
        return k
