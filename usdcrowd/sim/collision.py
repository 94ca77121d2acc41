"""Collision avoidance from expected time to impact, and the hard constraints.

Seed 003's collision field: ``grad E_C = -sigma(t_o) n_o`` with ``t_o`` the
expected time to impact and ``sigma`` a positive decreasing function (a
Gaussian, its Figure 8). It uses velocity as well as position, so

- an agent walking away from a wall or another agent feels nothing, however
  close (``t_o`` is infinite when the gap is not closing);
- two agents walking the same way (small relative velocity) may stay close;
- two agents walking toward each other start to swerve seconds in advance.

Here ``t_o = max(gap, GAP_MIN) / closing_speed`` uses the gap between the two
bodies (centre distance minus both radii) rather than the centre distance of
the seed's formula, so large and small characters behave alike. Against
another agent the push points along the predicted relative position at
``min(t_o, horizon)`` (a side-step rather than a brake), with a slight
pass-on-the-right bias that breaks the symmetry of exact head-on encounters.

Hard constraints applied after each integration step (so tests can bound
them): a position-based overlap correction between neighbours, and an
*exact* projection out of obstacle polygons for agents near them.

The step evaluates these formulas in compiled loops
(:func:`.kernels.forces`, :func:`.kernels.overlap_corrections`,
:func:`.kernels.push_out_of_walls`); the array forms here are their
readable statement, which the tests compare the loops with.
"""

from __future__ import annotations

import numpy as np

from . import params as P
from .grid import WalkGrid
from .kernels import GOLDEN_ANGLE, overlap_corrections, push_out_of_walls

_GAP_MIN = np.float32(0.02)  # m, floor of the gap in t_o (contact)


def agent_avoidance(dx, dv, dist, gap, vel_i, gain=P.AGENT_AVOID_GAIN, tau=P.AGENT_AVOID_TAU,
                    horizon=P.AVOID_HORIZON):
    """Time-to-impact avoidance force from neighbours (seed 003, E_C dynamic).

    Parameters
    ----------
    dx, dv : (2, n, k) float32
        Own position / velocity minus each neighbour's.
    dist, gap : (n, k) float32
        Centre distance, and the same minus both radii, metres.
    vel_i : (2, n) float32
        Own velocity (for the pass-on-the-right bias).

    Returns
    -------
    (2, n) float32 force, m/s^2
    """
    dot = dx[0] * dv[0] + dx[1] * dv[1]
    inv_d = 1.0 / np.maximum(dist, 1e-6)
    closing = -dot * inv_d  # m/s, > 0 when the gap shrinks
    approaching = closing > 1e-3
    t = np.maximum(gap, _GAP_MIN) / np.where(approaching, closing, 1.0)
    mag = np.where(approaching, np.exp((-0.5 / (tau * tau)) * t * t), 0.0).astype(np.float32) * np.float32(gain)
    tc = np.minimum(t, np.float32(horizon))
    sx = dx[0] + dv[0] * tc
    sy = dx[1] + dv[1] * tc
    inv_s = 1.0 / np.maximum(np.sqrt(sx * sx + sy * sy), 1e-6)
    # Right of the own velocity: (vy, -vx) / |v|.
    sp = np.sqrt(vel_i[0] * vel_i[0] + vel_i[1] * vel_i[1])
    inv_v = np.float32(P.PASS_RIGHT_BIAS) / np.maximum(sp, 1e-3)
    rx = (vel_i[1] * inv_v)[:, None]
    ry = (-vel_i[0] * inv_v)[:, None]
    fx = (sx * inv_s + rx) * mag
    fy = (sy * inv_s + ry) * mag
    return np.stack([fx.sum(axis=1), fy.sum(axis=1)])


def wall_avoidance(grid: WalkGrid, pos, vel, radius, gain=P.WALL_AVOID_GAIN, tau=P.WALL_AVOID_TAU):
    """Time-to-impact avoidance of static obstacles (seed 003, E_C static).

    Only agents walking toward a wall are repelled (``t_o`` infinite
    otherwise), plus a contact push below :data:`params.WALL_CONTACT_GAP`.

    Parameters
    ----------
    grid : WalkGrid
    pos, vel : (2, n) float32
    radius : (n,) float32

    Returns
    -------
    (2, n) float32 force
    """
    sdf, nx, ny = grid.clearance(pos[0], pos[1])
    clear = sdf - radius
    approach = -(vel[0] * nx + vel[1] * ny)
    toward = approach > 1e-3
    t = np.maximum(clear, _GAP_MIN) / np.where(toward, approach, 1.0)
    avoid = (np.where(toward, np.exp((-0.5 / (tau * tau)) * t * t), 0.0) * gain).astype(np.float32)
    mag = avoid + np.minimum(np.maximum((P.WALL_CONTACT_GAP - clear) / P.WALL_CONTACT_GAP, 0.0), 1.0) * P.WALL_CONTACT_GAIN
    mag = mag.astype(np.float32)
    # Slide along the wall on the side the agent already leans to (or its
    # left when square on), so that a pillar straight ahead is walked around
    # rather than pushed against.
    tx, ty = -ny, nx
    side = np.where(vel[0] * tx + vel[1] * ty >= 0, 1.0, -1.0).astype(np.float32) * np.float32(P.WALL_SLIDE)
    return np.stack([nx * mag + tx * side * avoid, ny * mag + ty * side * avoid])


def resolve_overlaps(pos, idx, radius, movable, relax=P.OVERLAP_RELAX):
    """Position-based correction of body overlaps (one Jacobi pass, in place).

    Parameters
    ----------
    pos : (2, n + 1) float32
        Positions, ghost last; rows ``:n`` are corrected.
    idx : (n, k) int32
        Neighbour table.
    radius : (n + 1,) float32
    movable : (n,) float32
        1 for agents that may be pushed, 0 to pin (dead bodies stay put).
    """
    n = idx.shape[0]
    corr = np.empty((2, n), np.float32)
    overlap_corrections(pos, idx, radius, movable, np.float32(0.5 * relax), corr)
    pos[:, :n] += corr


# The k-th body of a pile is set sqrt(k) times this many body widths from its centre.
SPIRAL_SPACING = 0.6


def separate_spawns(neighbors, grid: WalkGrid, pos, radius, movable, passes: int = P.SPAWN_SEPARATION_PASSES,
                    tolerance: float = P.SPAWN_OVERLAP_TOLERANCE) -> int:
    """Push apart bodies that start overlapping (clones spawned on one spot), before the first frame.

    Left to the steps, the overlap corrections would fling them apart faster
    than anyone walks (100 agents spawned on one point jumped 2 m in a frame).

    Parameters
    ----------
    neighbors : NeighborList
    grid : WalkGrid
    pos : (2, n + 1) float32
        Positions, ghost last; corrected in place.
    radius : (n + 1,) float32
    movable : (n,) float32
        1 for agents that may be pushed.

    Returns
    -------
    int
        The passes taken (``passes`` when overlaps deeper than ``tolerance`` metres remain).
    """
    n = movable.size
    _spread_coincident(pos, radius, movable)
    best, stalled = np.inf, 0
    for done in range(passes):
        neighbors._build(pos)
        idx = neighbors.idx
        dx = pos[:, :n, None] - pos[:, idx]
        dist = np.sqrt(dx[0] * dx[0] + dx[1] * dx[1])
        over = (radius[:n, None] + radius[idx] - dist) * (idx < n) * movable[:, None]
        worst = float(over.max(initial=0.0))
        if worst <= tolerance:
            return done
        # A spawn disc too small for its clones never gets there: stop when the overlap stops shrinking.
        stalled = stalled + 1 if worst > 0.99 * best else 0
        best = min(best, worst)
        if stalled >= P.SPAWN_STALL_PASSES:
            return done
        resolve_overlaps(pos, idx, radius, movable, relax=1.0)
        project_out_of_walls(grid, pos, radius)
    return passes


def room_for_piles(start, radius) -> np.ndarray | None:
    """(2, 2) bounds [min, max] that agents spawned on one point need once set out on their spiral
    (:func:`_spread_coincident`), with the usual margin; None when no two start on one point.

    Parameters
    ----------
    start : (2, n) float
    radius : (n,) float
    """
    points, counts = np.unique(start.T, axis=0, return_counts=True)
    piles = counts > 1
    if not piles.any():
        return None
    reach = SPIRAL_SPACING * 2.0 * float(radius.max()) * np.sqrt(counts[piles]) + P.BOUNDS_PAD
    return np.array([(points[piles] - reach[:, None]).min(0), (points[piles] + reach[:, None]).max(0)])


def _spread_coincident(pos, radius, movable) -> None:
    """Bodies on exactly one point, set out on a sunflower spiral around it (Vogel's: the k-th at
    ``sqrt(k)`` body widths, turned by the golden angle), in place. A neighbour search cannot tell
    identical points apart, and thousands of them in one cell make it quadratic."""
    n = movable.size
    _, inverse, counts = np.unique(pos[:, :n].T, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    shared = (counts[inverse] > 1) & (movable > 0)
    if not shared.any():
        return
    order = np.argsort(inverse, kind="stable")
    first = np.cumsum(counts) - counts
    rank = np.empty(n, dtype=np.int64)
    rank[order] = np.arange(n) - first[inverse[order]]
    # About one body's square of area each.
    r = SPIRAL_SPACING * 2.0 * radius[:n].astype(np.float64) * np.sqrt(rank)
    angle = rank * GOLDEN_ANGLE
    pos[0, :n] += np.where(shared, r * np.cos(angle), 0.0).astype(pos.dtype)
    pos[1, :n] += np.where(shared, r * np.sin(angle), 0.0).astype(pos.dtype)


def project_out_of_walls(grid: WalkGrid, pos, radius, passes: int = 2):
    """Push agents out of obstacle polygons (exact) and forbidden cells (grid), in place.

    Parameters
    ----------
    grid : WalkGrid
    pos : (2, n + 1) float32
    radius : (n + 1,) float32
    passes : int
        Repetitions, for agents squeezed between two obstacles.
    """
    if not grid.has_solid:
        return
    push_out_of_walls(pos, radius, passes, np.float32(P.WALL_PROJECT_MARGIN), grid.polygons, *grid.lookup, grid.flat_sdf,
                      grid.flat_nx, grid.flat_ny, grid.flat_label)
