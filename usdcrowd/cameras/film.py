"""Film a simulated crowd with camera agents: frames in, camera tracks out."""

from __future__ import annotations

import numpy as np

from ..core import model
from .params import CameraParams
from .placement import crowd_extent
from .steering import CameraAgents


def film(positions: np.ndarray, times: np.ndarray, fps: float, cameras: model.CameraAgentTable,
         events: model.EventTable, obstacles: model.Obstacles | None = None,
         agent_rows: dict[str, int] | None = None, visible: np.ndarray | None = None,
         params: CameraParams | None = None, seed: int = 0, progress=None,
         bounds: np.ndarray | None = None, overhead: model.Obstacles | None = None) -> list[model.CameraTrack]:
    """Run the camera agents through a shot.

    Parameters
    ----------
    positions : (t, n, 3) float
        Every agent's ground position per frame, metres.
    times : (t,) float
        Time codes.
    fps : float
        Frames per second.
    cameras : CameraAgentTable
    events : EventTable
    obstacles : Obstacles, optional
    agent_rows : dict[str, int], optional
        For cameras whose target is an agent.
    visible : (n,) bool, optional
        Agents that are rendered (containment looks at these).
    progress : callable(int), optional
        Called with the number of frames done.
    bounds : (2, 2) float, optional
        Area the cameras stay inside (the scenario's walkable bounds).
    overhead : Obstacles, optional
        Raised scenery that hides people from cameras above it.

    Returns
    -------
    list[CameraTrack]
        One per camera, with per-frame mode and tracked event.
    """
    params = params or CameraParams()
    t, n = positions.shape[:2]
    c = len(cameras)
    vis = np.ones(n, bool) if visible is None or not np.any(visible) else np.asarray(visible, bool)
    agents = CameraAgents(cameras, events, obstacles or model.Obstacles.empty(), agent_rows, params, seed, bounds,
                          vis, fps, overhead=overhead)
    mats = np.zeros((t, c, 4, 4))
    state = np.zeros((t, c), np.int8)
    tracked = []
    dt = 1.0 / (fps * params.substeps)
    for k in range(t):
        pos = np.asarray(positions[k], dtype=np.float64)
        centre, radius = crowd_extent(pos[vis])
        agents.update_modes(float(times[k]), pos)
        if k > 0:               # the first frame shows the authored pose (levelled)
            for _ in range(params.substeps):
                agents.step(float(times[k]), pos, centre, radius, dt)
        mats[k] = agents.cam_to_world()
        state[k] = agents.mode
        tracked.append(agents.tracked_paths())
        if progress is not None:
            progress(1)
    out = []
    for j in range(c):
        row = {name: (getattr(cameras, name)[j]) for name in (
            "max_speed", "max_force", "max_angular_speed", "arrival_distance", "aim_threshold",
            "separation_distance", "view_angle", "elevation", "target", "mode")}
        out.append(model.CameraTrack(cameras.path[j], np.asarray(times, dtype=np.float64), mats[:, j],
                                     np.full(t, cameras.focal_length[j]), float(cameras.horizontal_aperture[j]),
                                     float(cameras.vertical_aperture[j]), float(cameras.near[j]),
                                     float(cameras.far[j]), state[:, j], [tr[j] for tr in tracked], row))
    return out
