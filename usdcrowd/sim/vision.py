"""Walking by sight: Moussaïd, Helbing and Theraulaz's two heuristics (PNAS 2011).

A walker heading for a goal looks over its field of view and

1. takes the direction that brings it nearest its goal, given how far it
   can walk each way before it would bump into someone (others walking on as
   they do now): it goes round a slower walker ahead when there is room
   beside them, and follows when there is not;
2. walks no faster than keeps a time gap ``tau`` to the first person in that
   direction: ``v = min(v0, d_h / tau)``, which gives the crowd its
   speed-density relation (the fundamental diagram) without it being put in.

One addition for queues (a door, a bottleneck): a walker who has waited its
turn (held below ``QUEUE_SPEED`` behind someone who is not coming toward it,
see :func:`.kernels.sight_rounds`) keeps the shorter ``QUEUE_TAU`` to the person
ahead while it stands in line, so it steps into the space as it opens; with
people walking against it nearby it is in a standoff, not a queue.

Here the people seen are the neighbour list's (``NEIGHBOR_K`` nearest within
``NEIGHBOR_RADIUS``); walls are seen along each direction by sampling the
walkable grid's distance to them at a few points (a wall begins a quarter metre
before the first point nearer it than the walker's radius), and the wall forces
and constraints still keep bodies out of them. The loops over walkers,
directions and neighbours are compiled (:func:`.kernels.choose_ways`).
"""

from __future__ import annotations

import functools

import numpy as np

from . import params as P
from .kernels import choose_ways


# Distances along a direction at which walls are looked for, metres (to the horizon).
_WALL_SAMPLES = np.array([0.25, 0.5, 1.0, 2.0, 4.0], np.float32)
# A grid lookup for walkers with no walls to look for (never read).
_NO_WALLS = (0.0, 0.0, 1.0, 1, 1, np.ones(1, np.float32), np.full(1, -1, np.int32), np.zeros((0, 3, 2)),
             np.zeros(0, np.int64))


@functools.lru_cache(maxsize=16)
def _directions(fov_deg: float, directions: int):
    """(1, d) float32 offsets of the directions tried from the goal's, radians, and their cosines."""
    offsets = np.radians(np.linspace(-fov_deg, fov_deg, directions)).astype(np.float32)[None, :]
    offsets.flags.writeable = False
    cos = np.cos(offsets)
    cos.flags.writeable = False
    return offsets, cos


def heuristic_velocity(pos: np.ndarray, vel: np.ndarray, goal_dir: np.ndarray, v0: np.ndarray,
                       idx: np.ndarray, radius: np.ndarray, rows: np.ndarray, fov_deg: float | None = None,
                       directions: int | None = None, horizon: float | None = None,
                       tau: float | None = None, grid=None, queued: np.ndarray | None = None,
                       ghost: int = -1) -> tuple:
    """The heuristics' desired velocity of the walkers ``rows``.

    Parameters
    ----------
    pos, vel : (2, N) float32
        Everyone's positions and velocities.
    goal_dir : (2, m) float
        Unit direction toward each walker's goal.
    v0 : (m,) float
        Their desired speeds, m/s.
    idx : (n, k) int
        Neighbour list (ghost rows beyond the agents are far away).
    radius : (N,) float
        Body radii, m.
    rows : (m,) int
        The walkers.
    grid : WalkGrid, optional
        Where the walls are (its clearance, looked at along each direction).
    queued : (m,) bool, optional
        Walkers waiting their turn: they keep ``QUEUE_TAU`` to someone ahead who is not coming toward
        them (none by default).
    ghost : int, optional
        The far-away row that pads ``idx`` (``GHOST_POSITION``, standing), if any: skipped.

    Returns
    -------
    velocity : (2, m) float32
        Desired velocity.
    free : (m,) bool
        Nothing in the way: straight toward the goal at the desired speed.
    follows : (m,) bool
        In line: the first body in the chosen direction is a person not coming toward the walker, and no
        neighbour walks against the walker's goal direction faster than ``COUNTERFLOW_SPEED``.
    """
    fov_deg = P.VISION_FIELD_DEG if fov_deg is None else fov_deg
    directions = P.VISION_DIRECTIONS if directions is None else directions
    horizon = P.VISION_HORIZON if horizon is None else horizon
    tau = P.VISION_TAU if tau is None else tau
    m = len(rows)
    if m == 0:
        return np.zeros((2, 0), np.float32), np.zeros(0, bool), np.zeros(0, bool)
    queued = np.zeros(m, bool) if queued is None else np.asarray(queued, bool)
    nb = idx[rows]                                            # (m, k)
    base = np.arctan2(goal_dir[1], goal_dir[0]).astype(np.float32)[:, None]
    offsets, cos_offsets = _directions(float(fov_deg), int(directions))
    ang = base + offsets                                       # (m, d)
    ux, uy = np.cos(ang), np.sin(ang)                          # (m, d)
    steps = _WALL_SAMPLES[_WALL_SAMPLES <= horizon]
    where = (grid.lookup + (grid.flat_sdf,) + grid.exact) if grid is not None else _NO_WALLS
    return choose_ways(pos, vel, radius, nb, rows, ux, uy, np.asarray(v0, np.float32), cos_offsets,
                       np.float32(horizon), np.float32(tau), queued, np.float32(P.QUEUE_TAU), ghost,
                       grid is not None, steps, *where)
