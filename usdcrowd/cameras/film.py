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
    held = _Held(positions)
    for k in range(t):
        pos, here = held(k)
        if here is not None:                    # a replay: who is in the scene changes frame by frame
            agents.show(vis & here)
        shown = pos[vis if here is None else vis & here]
        if len(shown) or k == 0:            # with nobody in the scene the crowd stays where it was last seen
            centre, radius = crowd_extent(shown)
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


class _Held:
    """Frame ``k`` of the crowd for the cameras, and who is in the scene then.

    NaN positions (people who have not come yet or have gone, in a replay)
    hold the nearest position the person has, so every velocity a camera
    estimates stays finite; they are hidden from the cameras by ``here``.
    """

    def __init__(self, positions):
        self.positions = positions
        self.last = None
        self.first = None
        self.previous = None        # the last frame while everyone was there (frames come in order)

    def __call__(self, k: int) -> tuple[np.ndarray, np.ndarray | None]:
        pos = np.asarray(self.positions[k], dtype=np.float64)
        here = np.isfinite(pos[:, 0])
        if self.first is None and here.all():
            self.previous = pos
            return pos, None
        if self.first is None:
            self.first = _first_positions(self.positions)
            # Someone leaving after a stretch with everyone there is held where they were last, not where
            # they started.
            self.last = self.first.copy() if self.previous is None else self.previous.copy()
        self.last[here] = pos[here]
        return np.where(here[:, None], pos, self.last), here


def _first_positions(positions) -> np.ndarray:
    """(n, 3) each person's first finite position over the shot (zeros for one never there)."""
    from ..core.framestore import frame_blocks

    first = np.full(positions.shape[1:], np.nan)
    for block in frame_blocks(positions):
        todo = ~np.isfinite(first[:, 0])
        if not todo.any():
            break
        block = np.asarray(block, dtype=np.float64)[:, todo]
        seen = np.isfinite(block[..., 0])
        k = np.argmax(seen, axis=0)
        got = seen.any(axis=0)
        rows = np.flatnonzero(todo)[got]
        first[rows] = block[k[got], np.flatnonzero(got)]
    return np.nan_to_num(first)
