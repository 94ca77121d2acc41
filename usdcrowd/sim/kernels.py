"""Compiled loops of the crowd step (numba).

The step's per-agent and per-pair work, written as one loop over the agents
each instead of chains of ``(n, k)`` numpy temporaries:

- the force on each agent (:func:`forces`: steering, time-to-impact
  avoidance of neighbours and walls, personal space, flocking, containment);
- the neighbour table (:func:`nearest_within`, a grid of cells, and
  :func:`moved_beyond`, when to build it again);
- integration and the constraints (:func:`preferred_speeds`,
  :func:`speed_limits`, :func:`integrate`, :func:`overlap_corrections`,
  :func:`limit_moves`, :func:`push_out_of_walls`, :func:`clip_to_bounds`,
  :func:`settle_velocities`);
- headings turned toward the velocity (:func:`turn_headings`), blasts' damage,
  its wounds and the flight from it (:func:`radial_falloff`,
  :func:`worsen_health`, :func:`within_reach`, :func:`flee_blast`) and
  reactions blended into the intent (:func:`blend_rows`);
- grid queries (:func:`cells`, :func:`clearance`, :func:`line_of_sight`);
- members' memory of their leader and their way after it
  (:func:`remember_leaders`, :func:`group_spread`, :func:`follow_leaders`)
  and walking by sight (:func:`sight_rounds`, :func:`choose_ways`).

Each follows a numpy form: the package's building blocks where they remain
(:func:`.collision.agent_avoidance`, :func:`.steering.separation`,
:func:`.groups.flocking`, :func:`.collision.wall_avoidance`,
:func:`.steering.containment`, :func:`.steering.clip_norm`), the former
vectorised code otherwise, kept in ``tests/sim/test_kernels.py``, which
compares the two.

All arithmetic is float32 where the numpy form's is (module constants are
``np.float32``: a Python float literal would make numba compute in float64).
Every loop but the forces gives the numpy form's bits exactly; the forces sum
each agent's neighbours in order, where numpy's ``einsum`` and ``sum``
group them differently, so they agree to float32 rounding, not bit for bit.
Each agent's result depends on its own loop alone, so spreading the agents
over the cores (``prange``) changes nothing: a seed gives the same bytes run
to run.

Compiled once per machine (``cache=True`` keeps the machine code beside
this file, or in numba's user cache where that is read-only); built again
when :mod:`usdcrowd.sim.params` changes (:mod:`usdcrowd.compiled`).
"""

from __future__ import annotations

import functools
import os
import types

import numpy as np
from numba import njit, prange

from ..compiled import cache_one_process_at_a_time, forget_stale_machine_code
from . import params as P

forget_stale_machine_code(__file__, P)

# Items (agents, points, segments) from which a loop is spread over the cores. Starting the threads
# costs about a microsecond (2 cores): below a few dozen items even the heavy loops lose by it.
PARALLEL_MIN = 64
_threads_started = False    # this process's loops have started threads
_threads_allowed = True     # False in a child forked after that


def _after_fork_in_child() -> None:
    global _threads_allowed
    _threads_allowed = _threads_allowed and not _threads_started


os.register_at_fork(after_in_child=_after_fork_in_child)


def _may_use_threads() -> bool:
    """False in a process forked from one whose loops ran on threads: numba's usual threading layer on
    Linux (GNU OpenMP) cannot start threads again there, and would end the process. (A hook at fork
    sets it: asking the process's id on every loop cost ~10 us a step.)"""
    global _threads_started
    _threads_started = True
    return _threads_allowed


def _loop(size):
    """Compile a loop over items (``prange``) twice, as one thread and spread over the cores, and run
    the second when ``size(*args)`` items reach PARALLEL_MIN (and threads may be used). Each item's
    result depends on its own iteration alone, so both give the same bytes. The two have their own
    entries in numba's cache (the second's name ends ``_on_threads``)."""
    def wrap(fn):
        serial = njit(cache=True, nogil=True)(fn)
        twin = types.FunctionType(fn.__code__, fn.__globals__, fn.__name__, fn.__defaults__, fn.__closure__)
        twin.__qualname__ = f"{fn.__qualname__}_on_threads"
        parallel = njit(cache=True, nogil=True, parallel=True)(twin)

        @functools.wraps(fn)
        def run(*args):
            if size(*args) >= PARALLEL_MIN and _may_use_threads():
                return parallel(*args)
            return serial(*args)

        run.serial, run.parallel = serial, parallel
        return run
    return wrap

_F0 = np.float32(0.0)
_F1 = np.float32(1.0)
_TWO = np.float32(2.0)
_EPS = np.float32(1e-6)
_CLOSING = np.float32(1e-3)
_GAP_MIN = np.float32(0.02)
_AVOID_EXP = np.float32(-0.5 / (P.AGENT_AVOID_TAU * P.AGENT_AVOID_TAU))
_AVOID_GAIN = np.float32(P.AGENT_AVOID_GAIN)
_HORIZON = np.float32(P.AVOID_HORIZON)
_BIAS = np.float32(P.PASS_RIGHT_BIAS)
_PERSONAL = np.float32(P.PERSONAL_GAP)
_SEP_SCALE = np.float32(P.SEPARATION_GAIN / P.PERSONAL_GAP)
_FLOCK_RADIUS = np.float32(P.FLOCK_RADIUS)
_COHESION = np.float32(P.COHESION_GAIN)
_ALIGN = np.float32(P.ALIGN_GAIN)
# Successive pairs turn by the golden angle: coincident clones fan out evenly.
GOLDEN_ANGLE = np.pi * (3.0 - np.sqrt(5.0))
_INF32 = np.float32(np.inf)
_TINY2 = np.float32(1e-12)
_A_MIN = np.float32(1e-9)
_WALL_APPROACH = np.float32(0.05)  # nearer a wall than now by this much is getting nearer, m
_WALL_EXP = np.float32(-0.5 / (P.WALL_AVOID_TAU * P.WALL_AVOID_TAU))
_WALL_GAIN = np.float32(P.WALL_AVOID_GAIN)
_CONTACT_GAP = np.float32(P.WALL_CONTACT_GAP)
_CONTACT_GAIN = np.float32(P.WALL_CONTACT_GAIN)
_SLIDE = np.float32(P.WALL_SLIDE)
_LOOKAHEAD = np.float32(P.CONTAIN_LOOKAHEAD)
_CONTAIN = np.float32(-P.CONTAIN_GAIN)
_COUNTERFLOW = np.float32(P.COUNTERFLOW_SPEED)
_SIDE_WALL = np.float32(0.02)  # m: a clearance this small is the far wall
_SIDEWAYS_MOVING = np.float32(0.1)  # m/s: slower, one looks only where one stands
_HALF = np.float32(0.5)
_MIN_SPEED2 = np.float32(P.HEADING_MIN_SPEED ** 2)
_PI = np.float32(np.pi)
_TWO_PI = np.float32(2 * np.pi)
_MEANS_TO_MOVE = np.float32(1e-3)  # m/s
_QUEUE_SPEED2 = np.float32(P.QUEUE_SPEED ** 2)
_QUEUE_AFTER = np.float32(P.QUEUE_AFTER)
_SIGHT_MARGIN = 1.5  # cells: sqrt(2) and room for rounding


@njit(cache=True, nogil=True)
def _pair_terms(i, pos, vel, radius, idx, mates):
    """Agent ``i``'s time-to-impact avoidance of its neighbours, personal space, and flocking, each (x, y)."""
    n, k = idx.shape
    px, py = pos[0, i], pos[1, i]
    vx, vy = vel[0, i], vel[1, i]
    ri = radius[i]
    sp = np.sqrt(vx * vx + vy * vy)
    inv_v = _BIAS / max(sp, _CLOSING)
    rx = vy * inv_v
    ry = -vx * inv_v
    ax = ay = sx_sep = sy_sep = cx = cy = mvx = mvy = count = _F0
    for c in range(k):
        j = idx[i, c]
        if j == n:  # the ghost: far away, never a mate
            continue
        dx = px - pos[0, j]
        dy = py - pos[1, j]
        dvx = vx - vel[0, j]
        dvy = vy - vel[1, j]
        dist = np.sqrt(dx * dx + dy * dy)
        gap = dist - (ri + radius[j])
        # Seed 003's E_C against a moving obstacle (collision.agent_avoidance).
        closing = -(dx * dvx + dy * dvy) * (_F1 / max(dist, _EPS))
        if closing > _CLOSING:
            t = max(gap, _GAP_MIN) / closing
            mag = np.exp(_AVOID_EXP * t * t) * _AVOID_GAIN
            tc = min(t, _HORIZON)
            sx = dx + dvx * tc
            sy = dy + dvy * tc
            inv_s = _F1 / max(np.sqrt(sx * sx + sy * sy), _EPS)
            ax += (sx * inv_s + rx) * mag
            ay += (sy * inv_s + ry) * mag
        # Personal space (steering.separation).
        w = max((_PERSONAL - gap) * _SEP_SCALE, _F0) / max(dist, _EPS)
        sx_sep += dx * w
        sy_sep += dy * w
        # E_F + E_V with visible group-mates (groups.flocking).
        if dist < _FLOCK_RADIUS:
            m = mates[i, c]
            count += m
            cx += dx * m
            cy += dy * m
            mvx += dvx * m
            mvy += dvy * m
    cnt = max(count, _F1)
    return (ax, ay, sx_sep, sy_sep, cx * (-_COHESION / cnt) + mvx * (-_ALIGN / cnt),
            cy * (-_COHESION / cnt) + mvy * (-_ALIGN / cnt))


@njit(cache=True, nogil=True)
def _wall_terms(px, py, vx, vy, r, sdf, nx, ny):
    """Time-to-impact avoidance of the wall whose clearance ``sdf`` and normal ``n`` the agent's cell
    holds, plus the contact push and the slide along it (collision.wall_avoidance)."""
    clear = sdf - r
    approach = -(vx * nx + vy * ny)
    avoid = _F0
    if approach > _CLOSING:
        t = max(clear, _GAP_MIN) / approach
        avoid = np.exp(_WALL_EXP * t * t) * _WALL_GAIN
    mag = avoid + min(max((_CONTACT_GAP - clear) / _CONTACT_GAP, _F0), _F1) * _CONTACT_GAIN
    tx, ty = -ny, nx
    side = _SLIDE if vx * tx + vy * ty >= _F0 else -_SLIDE
    return nx * mag + tx * side * avoid, ny * mag + ty * side * avoid


@_loop(lambda pos, vel, v_des, *rest: v_des.shape[1])
def forces(pos, vel, v_des, steer, radius, idx, mates, walls, ox, oy, inv_cell, w, h, sdf, nx, ny, near, polys,
           sizes, lo, hi):
    """The force on each agent (m/s^2, before its clip): steering toward the desired velocity, then
    avoidance of the neighbours, personal space, flocking, avoidance of walls and containment in the
    bounds, added in that order.

    Parameters
    ----------
    pos, vel : (2, n + 1) float32
        Positions and velocities, ghost last.
    v_des : (2, n) float32
        Desired velocities.
    steer : (n,) float32
        Each agent's steering gain, 1 / its relaxation time (1/s).
    radius : (n + 1,) float32
    idx : (n, k) int32
        Neighbour table (``n``: none).
    mates : (n, k) float32
        Group-mate (and line-of-sight) mask.
    walls : bool
        Whether the grid (``ox`` ... ``sizes``: WalkGrid.lookup, flat_sdf, flat_nx, flat_ny and exact) has
        walls to avoid.
    lo, hi : (2,) float32
        Walkable bounds.

    Returns
    -------
    (2, n) float32
    """
    n = idx.shape[0]
    out = np.empty((2, n), np.float32)
    for i in prange(n):
        px, py = pos[0, i], pos[1, i]
        vx, vy = vel[0, i], vel[1, i]
        fx = (v_des[0, i] - vx) * steer[i]
        fy = (v_des[1, i] - vy) * steer[i]
        ax, ay, sx, sy, gx, gy = _pair_terms(i, pos, vel, radius, idx, mates)
        fx = ((fx + ax) + sx) + gx
        fy = ((fy + ay) + sy) + gy
        if walls:
            clear, ux, uy = _wall_at(px, py, ox, oy, inv_cell, w, h, sdf, nx, ny, near, polys, sizes)
            wx, wy = _wall_terms(px, py, vx, vy, radius[i], clear, ux, uy)
            fx += wx
            fy += wy
        # Steering back in when the position a lookahead ahead leaves the bounds (steering.containment).
        ahx = px + vx * _LOOKAHEAD
        ahy = py + vy * _LOOKAHEAD
        fx += (min(ahx - lo[0], _F0) + max(ahx - hi[0], _F0)) * _CONTAIN
        fy += (min(ahy - lo[1], _F0) + max(ahy - hi[1], _F0)) * _CONTAIN
        out[0, i] = fx
        out[1, i] = fy
    return out


@njit(cache=True, nogil=True)
def _bins(x, y, reach):
    """Points (m,) sorted into square cells (a counting sort) about one point each, at most ``reach``
    wide: the cell side, the grid's corner, width and height in cells, each cell's first slot in
    ``order``, and the points in cell order."""
    m = x.shape[0]
    x0, x1, y0, y1 = x.min(), x.max(), y.min(), y.max()
    side = min(reach, max(np.sqrt((x1 - x0) * (y1 - y0) / m), 1e-3))
    side = max(side, np.sqrt((x1 - x0 + side) * (y1 - y0 + side) / (4.0 * m + 64.0)))  # cells <= 4 per point
    nx = np.int64((x1 - x0) / side) + 1
    ny = np.int64((y1 - y0) / side) + 1
    cell = np.empty(m, np.int64)
    start = np.zeros(nx * ny + 1, np.int64)
    for i in range(m):
        cell[i] = np.int64((y[i] - y0) / side) * nx + np.int64((x[i] - x0) / side)
        start[cell[i] + 1] += 1
    for c in range(nx * ny):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(m, np.int64)
    for i in range(m):
        order[fill[cell[i]]] = i
        fill[cell[i]] += 1
    return side, x0, y0, nx, ny, start, order


@_loop(lambda x, *rest: x.shape[0])
def nearest_within(x, y, k, reach):
    """The ``k`` nearest other points within ``reach`` of each point, nearest first, through a grid of
    cells searched ring by ring outward until no nearer point can remain.

    Parameters
    ----------
    x, y : (m,) float64
    k : int
    reach : float

    Returns
    -------
    (m, k) int64
        Indices into the points, -1 where fewer than ``k`` are within reach.
    """
    m = x.shape[0]
    out = np.full((m, k), -1, np.int64)
    if m == 0:
        return out
    side, x0, y0, nx, ny, start, order = _bins(x, y, reach)
    best = np.full((m, k), np.inf)
    r2 = reach * reach
    rings = np.int64(reach / side) + 2
    for i in prange(m):
        cx = np.int64((x[i] - x0) / side)
        cy = np.int64((y[i] - y0) / side)
        for ring in range(rings):
            # Points in this ring's cells are at least (ring - 1) cells away.
            near = max(ring - 1, 0) * side
            if near * near > min(best[i, k - 1], r2):
                break
            for gy in range(cy - ring, cy + ring + 1):
                if gy < 0 or gy >= ny:
                    continue
                edge = gy == cy - ring or gy == cy + ring
                for gx in range(cx - ring, cx + ring + 1, 1 if edge else 2 * ring):
                    if gx < 0 or gx >= nx:
                        continue
                    c = gy * nx + gx
                    for s in range(start[c], start[c + 1]):
                        j = order[s]
                        d2 = (x[j] - x[i]) * (x[j] - x[i]) + (y[j] - y[i]) * (y[j] - y[i])
                        if j == i or d2 > r2 or d2 >= best[i, k - 1]:
                            continue
                        q = k - 1
                        while q > 0 and best[i, q - 1] > d2:
                            best[i, q] = best[i, q - 1]
                            out[i, q] = out[i, q - 1]
                            q -= 1
                        best[i, q] = d2
                        out[i, q] = j
    return out


@njit(cache=True, nogil=True)
def moved_beyond(pos, rows, ref, limit2):
    """Whether any agent of ``rows`` stands ``limit2`` (float64, squared metres) or more from its
    place in ``ref`` (2, m) (float32 differences and squares, as on whole arrays); NaN counts as moved."""
    for q in range(rows.shape[0]):
        dx = pos[0, rows[q]] - ref[0, q]
        dy = pos[1, rows[q]] - ref[1, q]
        if not np.float64(dx * dx + dy * dy) < limit2:
            return True
    return False


@_loop(lambda pos, idx, *rest: idx.shape[0])
def overlap_corrections(pos, idx, radius, movable, half_relax, out):
    """One Jacobi pass of overlap corrections (collision.resolve_overlaps), into ``out`` (2, n).

    Coincident pairs are pushed apart along a direction of their own, opposite for the two (the
    golden-angle turn of the reference).
    """
    n, k = idx.shape
    for i in prange(n):
        px, py = pos[0, i], pos[1, i]
        ri = radius[i]
        sx = _F0
        sy = _F0
        for c in range(k):
            j = idx[i, c]
            if j == n:
                continue
            dx = px - pos[0, j]
            dy = py - pos[1, j]
            dist = np.sqrt(dx * dx + dy * dy)
            over = ri + radius[j] - dist
            if dist < _EPS:
                angle = ((i + j) * GOLDEN_ANGLE) % (2.0 * np.pi)
                side = 1.0 if i > j else -1.0
                dx = np.float32(side * np.cos(angle))
                dy = np.float32(side * np.sin(angle))
                w = half_relax * over
            elif over > _F0:
                w = over * half_relax / max(dist, _EPS)
            else:
                continue
            sx += dx * w
            sy += dy * w
        out[0, i] = sx * movable[i]
        out[1, i] = sy * movable[i]


@njit(cache=True, nogil=True)
def _clip2(x, y, limit):
    # steering.clip_norm for one vector: scaled down to `limit` in length, in its float32 operations.
    n2 = x * x + y * y
    if n2 > limit * limit:
        s = limit / np.sqrt(max(n2, _TINY2))
        return x * s, y * s
    return x, y


@_loop(lambda pos, vel, F, *rest: F.shape[1])
def integrate(pos, vel, F, alive, max_accel, vmax, dt):
    """Seed 003's step for each agent, in place: the force clipped to its maximum (none for the dead),
    ``x += v dt + F dt^2 / 2``, ``v += F dt``, the speed clipped to ``vmax``.

    Parameters
    ----------
    pos, vel : (2, n + 1) float32
    F : (2, n) float32
    alive : (n,) bool
    max_accel, vmax : (n,) float32
    dt : float32
    """
    n = F.shape[1]
    half_dt2 = np.float32(0.5) * dt * dt
    for i in prange(n):
        fx, fy = _clip2(F[0, i], F[1, i], max_accel[i])
        if not alive[i]:
            fx = fy = _F0
        vx, vy = vel[0, i], vel[1, i]
        pos[0, i] += vx * dt + fx * half_dt2
        pos[1, i] += vy * dt + fy * half_dt2
        vel[0, i], vel[1, i] = _clip2(vx + fx * dt, vy + fy * dt, vmax[i])


@njit(cache=True, nogil=True)
def preferred_speeds(pref, health, wounded, factor):
    """(n,) float32 speeds the agents want to walk at: ``pref`` (n,), times ``factor`` for the wounded."""
    out = np.empty_like(pref)
    for i in range(pref.shape[0]):
        out[i] = pref[i] * factor if health[i] == wounded else pref[i]
    return out


@njit(cache=True, nogil=True)
def speed_limits(behavior, pref, speed_cap, health, run, rest, dead, run_factor, walk_factor, rest_max, out):
    """Each agent's top speed this step (m/s) into ``out`` (n,) float32: its preferred speed times
    ``run_factor`` running, else ``walk_factor``; at rest at most ``rest_max`` (it may be jostled, not
    walk); never over its kind's cap; zero for the dead. (One loop: the numpy form's eight calls cost
    about 30 us a step at 1,000 agents.)"""
    for i in range(out.shape[0]):
        v = pref[i] * (run_factor if behavior[i] == run else walk_factor)
        if behavior[i] == rest:
            v = min(v, rest_max)
        out[i] = _F0 if health[i] == dead else min(v, speed_cap[i])
    return out


@njit(cache=True, nogil=True)
def clip_to_bounds(pos, radius, lo, hi):
    """Keep each body ((2, n + 1) positions, the ghost last and left alone; ``radius`` (n,)) inside the
    box ``lo``-``hi`` (2,), in place."""
    for c in range(2):
        for i in range(radius.shape[0]):
            pos[c, i] = min(max(pos[c, i], lo[c] + radius[i]), hi[c] - radius[i])


@_loop(lambda pos, old, vmax, dt: vmax.shape[0])
def limit_moves(pos, old, vmax, dt):
    """Shorten each agent's move since ``old`` (2, n + 1) to at most ``vmax * dt``, in place."""
    n = vmax.shape[0]
    for i in prange(n):
        mx, my = _clip2(pos[0, i] - old[0, i], pos[1, i] - old[1, i], vmax[i] * dt)
        pos[0, i] = old[0, i] + mx
        pos[1, i] = old[1, i] + my


@_loop(lambda pos, vel, integrated, inv_dt, vmax: vmax.shape[0])
def settle_velocities(pos, vel, integrated, inv_dt, vmax):
    """Constraint displacements (``pos`` less ``integrated`` (2, n)) count as velocity, clipped to
    ``vmax`` (position-based dynamics), in place."""
    n = vmax.shape[0]
    for i in prange(n):
        vx = vel[0, i] + (pos[0, i] - integrated[0, i]) * inv_dt
        vy = vel[1, i] + (pos[1, i] - integrated[1, i]) * inv_dt
        vel[0, i], vel[1, i] = _clip2(vx, vy, max(vmax[i], _F0))


@njit(cache=True, nogil=True)
def turn_headings(heading, want, vel, face, turn_rate, dt):
    """Turn each heading toward ``want`` by at most ``turn_rate * dt``, in place, for agents moving
    faster than HEADING_MIN_SPEED or facing something; every heading wrapped to [-pi, pi) as
    ``np.mod(h + pi, 2 pi) - pi`` gives it.

    Parameters
    ----------
    heading, want : (n,) float32
        Radians; ``want`` as numpy's ``arctan2`` gives it (numba's differs in the last bits).
    vel : (2, n + 1) float32
    face : (n,) bool
    turn_rate : (n,) float32, rad/s
    dt : float32
    """
    n = heading.shape[0]
    far = np.zeros(n, np.bool_)
    for i in range(n):
        out = _turn(heading[i], want[i], vel[0, i], vel[1, i], face[i], turn_rate[i] * dt, False)
        if np.isnan(out):
            far[i] = True
        else:
            heading[i] = out
    # Angles a full turn or more out of range (a heading authored as 7 rad): numpy's mod in full. Its own
    # loop, so that the compiler does not compute the costly remainder for every agent on the off chance.
    if far.any():
        for i in range(n):
            if far[i]:
                heading[i] = _turn(heading[i], want[i], vel[0, i], vel[1, i], face[i], turn_rate[i] * dt, True)


@njit(cache=True, nogil=True)
def _turn(h, want, vx, vy, face, lim, full):
    # One heading turned and wrapped; NaN where a wrap needs the full remainder and `full` is off.
    if vx * vx + vy * vy > _MIN_SPEED2 or face:
        x = want - h + _PI
        if not full and not _near_turn(x):
            return np.float32(np.nan)
        delta = (np.mod(x, _TWO_PI) if full else _wrap_near(x)) - _PI
        h = h + np.minimum(np.maximum(delta, -lim), lim)
    x = h + _PI
    if full:
        return np.mod(x, _TWO_PI) - _PI
    return _wrap_near(x) - _PI if _near_turn(x) else np.float32(np.nan)


@njit(cache=True, nogil=True)
def _near_turn(x):
    return x >= -_TWO_PI and x < _TWO_PI + _TWO_PI


@njit(cache=True, nogil=True)
def _wrap_near(x):
    # np.mod(x, 2 pi) for x in [-2 pi, 4 pi), float32: fmod is x itself or x - 2 pi (exact), and numpy
    # then adds 2 pi to a negative remainder and makes a zero one +0.
    if x > _F0:
        return x if x < _TWO_PI else x - _TWO_PI
    if x < _F0:
        return x + _TWO_PI
    return _F0


@njit(cache=True, nogil=True)
def _cell(x, y, ox, oy, inv_cell, w, h):
    # Flat index of the cell under (x, y): float64 offsets, truncated, clamped to the grid.
    ix = min(max(np.int64((np.float64(x) - ox) * inv_cell), 0), w - 1)
    iy = min(max(np.int64((np.float64(y) - oy) * inv_cell), 0), h - 1)
    return iy * w + ix


@njit(cache=True, nogil=True)
def _polygon_distance(x, y, polys, sizes, k):
    # Signed distance of (x, y) to convex CCW polygon k (grid.polygon_signed_distance's), negative inside,
    # and the unit direction away from it (0, 0 on its boundary). Its own sizes[k] vertices only: the
    # table pads every polygon to the longest's, with edges of no length.
    best = np.inf
    bx = by = 0.0
    inside = True
    n = sizes[k]
    for j in range(n):
        ax, ay = polys[k, j, 0], polys[k, j, 1]
        ex = polys[k, (j + 1) % n, 0] - ax
        ey = polys[k, (j + 1) % n, 1] - ay
        ll = ex * ex + ey * ey
        if ll <= 1e-18:
            continue
        px = np.float64(x) - ax
        py = np.float64(y) - ay
        t = min(max((px * ex + py * ey) / ll, 0.0), 1.0)
        dx = px - ex * t
        dy = py - ey * t
        d2 = dx * dx + dy * dy
        if d2 < best:
            best, bx, by = d2, dx, dy
        if ex * py - ey * px < 0.0:
            inside = False
    d = np.sqrt(best)
    if d <= 1e-12:
        return 0.0, 0.0, 0.0
    return (-d, -bx / d, -by / d) if inside else (d, bx / d, by / d)


@njit(cache=True, nogil=True)
def _wall_at(x, y, ox, oy, inv_cell, w, h, sdf, nx, ny, near, polys, sizes):
    # The clearance at (x, y) and the unit direction away from the nearest wall, float32. Where the four
    # nearest cell centres each have an obstacle whose exact distance is their clearance (grid.near),
    # the exact distance to those obstacles and its direction: blending the centres' values cuts the
    # ridge between two walls (a 0.8 m door's middle read 0.275 m for 0.40), and the grid's slope turns
    # round a corner a cell early. Elsewhere bilinear between the centres (a wall between two is where
    # it stands) and the nearest cell's slope.
    fx = (np.float64(x) - ox) * inv_cell - 0.5
    fy = (np.float64(y) - oy) * inv_cell - 0.5
    ix = min(max(np.int64(np.floor(fx)), 0), w - 2)
    iy = min(max(np.int64(np.floor(fy)), 0), h - 2)
    f = iy * w + ix
    a, b, c, d = near[f], near[f + 1], near[f + w], near[f + w + 1]
    if a >= 0 and b >= 0 and c >= 0 and d >= 0:
        s, ux, uy = _polygon_distance(x, y, polys, sizes, a)
        for k, earlier in ((b, a == b), (c, c == a or c == b), (d, d == a or d == b or d == c)):
            if not earlier:                  # corner cells often share their obstacle: measure it once
                t, vx, vy = _polygon_distance(x, y, polys, sizes, k)
                if t < s:
                    s, ux, uy = t, vx, vy
        if ux == 0.0 and uy == 0.0:          # on a wall's boundary: no direction of its own
            g = _cell(x, y, ox, oy, inv_cell, w, h)
            return np.float32(s), nx[g], ny[g]
        return np.float32(s), np.float32(ux), np.float32(uy)
    g = _cell(x, y, ox, oy, inv_cell, w, h)
    tx = min(max(fx - ix, 0.0), 1.0)
    ty = min(max(fy - iy, 0.0), 1.0)
    return (np.float32((sdf[f] * (1.0 - tx) + sdf[f + 1] * tx) * (1.0 - ty)
                       + (sdf[f + w] * (1.0 - tx) + sdf[f + w + 1] * tx) * ty), nx[g], ny[g])


@njit(cache=True, nogil=True)
def _sdf_at(x, y, ox, oy, inv_cell, w, h, sdf, near, polys, sizes):
    # The clearance alone (_wall_at's; the flat sdf stands in for the slope it does not return).
    return _wall_at(x, y, ox, oy, inv_cell, w, h, sdf, sdf, sdf, near, polys, sizes)[0]


@njit(cache=True, nogil=True)
def cells(x, y, ox, oy, inv_cell, w, h):
    """(m,) int64 flat cell index of points, clamped to the grid (WalkGrid.flat_index)."""
    out = np.empty(x.shape[0], np.int64)
    for i in range(x.shape[0]):
        out[i] = _cell(x[i], y[i], ox, oy, inv_cell, w, h)
    return out


@_loop(lambda x, *rest: x.shape[0])
def clearance(x, y, ox, oy, inv_cell, w, h, sdf, nx, ny, near, polys, sizes):
    """Clearance and the direction away from the nearest wall at points (:func:`_wall_at`, WalkGrid.clearance).

    Returns
    -------
    (m,) float32 sdf, nx, ny
    """
    m = x.shape[0]
    s = np.empty(m, np.float32)
    ux = np.empty(m, np.float32)
    uy = np.empty(m, np.float32)
    for i in prange(m):
        s[i], ux[i], uy[i] = _wall_at(x[i], y[i], ox, oy, inv_cell, w, h, sdf, nx, ny, near, polys, sizes)
    return s, ux, uy


@njit(cache=True, nogil=True)
def _visible(ax, ay, bx, by, per_metre, max_samples, ox, oy, inv_cell, w, h, solid, sdf):
    # One segment of line_of_sight: its own sample count, stopping at the first solid sample.
    dx = bx - ax
    dy = by - ay
    length = np.sqrt(np.float64(dx) * dx + np.float64(dy) * dy)
    # Every sample's cell centre lies within length + sqrt(2) cells of a's (clamping to the grid only
    # brings points nearer), and sdf is the distance from a's centre to the nearest solid centre less
    # half a cell: clear by more than that, no sample can be solid (the answer sampling would give).
    if sdf[_cell(ax, ay, ox, oy, inv_cell, w, h)] > length + _SIGHT_MARGIN / inv_cell:
        return True
    samples = min(max_samples, max(2, np.int64(np.ceil(length * per_metre)) + 1))
    s32 = np.float32(samples)
    for q in range(samples):
        t = (np.float32(q) + np.float32(0.5)) / s32
        if solid[_cell(ax + dx * t, ay + dy * t, ox, oy, inv_cell, w, h)]:
            return False
    return True


@_loop(lambda ax, *rest: ax.shape[0])
def line_of_sight(ax, ay, bx, by, per_metre, max_samples, ox, oy, inv_cell, w, h, solid, sdf):
    """Whether segments a->b cross no solid cell (WalkGrid.line_of_sight).

    Segment ``i`` is sampled at ``s = min(max_samples, max(2, ceil(length * per_metre) + 1))``
    points ``a + (b - a) (q + 0.5) / s`` (float32 fractions), and stops at its first solid one;
    one that starts farther from every solid cell (``sdf``, the grid's clearance) than it is long
    is clear without sampling.

    Returns
    -------
    (m,) bool
    """
    m = ax.shape[0]
    out = np.empty(m, np.bool_)
    for i in prange(m):
        out[i] = _visible(ax[i], ay[i], bx[i], by[i], per_metre, max_samples, ox, oy, inv_cell, w, h, solid, sdf)
    return out


@njit(cache=True, nogil=True)
def group_spread(pos, followers, leader_of, slot, groups):
    """(groups,) float64 sum over each group's followers of their distance to their leader, added in
    follower order (as numpy's bincount adds its weights)."""
    out = np.zeros(groups)
    for f in range(followers.shape[0]):
        dx = pos[0, followers[f]] - pos[0, leader_of[f]]
        dy = pos[1, followers[f]] - pos[1, leader_of[f]]
        out[slot[f]] += np.float64(np.sqrt(dx * dx + dy * dy))
    return out


@_loop(lambda pos, sub, *rest: sub.shape[0])
def remember_leaders(pos, sub, followers, leader_of, slot, trail, probes, range2, memory, walls, per_metre,
                     max_samples, ox, oy, inv_cell, w, h, solid, sdf):
    """Seed 003's x_hat_l, in place: for the followers ``sub`` (indices into ``followers``), the
    position of their leader if in range and in sight, else of the first breadcrumb in ``probes``
    (columns of ``trail`` (2, l, T), newest first) that is; unchanged where none is. Without
    ``walls`` only the leader is tried, and range alone decides (groups.Groups.update_memory)."""
    for q in prange(sub.shape[0]):
        f = sub[q]
        me = followers[f]
        mx, my = pos[0, me], pos[1, me]
        lead = leader_of[f]
        for c in range(probes.shape[0] + 1 if walls else 1):
            if c == 0:
                cx, cy = pos[0, lead], pos[1, lead]
            else:
                cx, cy = trail[0, slot[f], probes[c - 1]], trail[1, slot[f], probes[c - 1]]
            dx, dy = cx - mx, cy - my
            if not dx * dx + dy * dy < range2:
                continue
            if walls and not _visible(mx, my, cx, cy, per_metre, max_samples, ox, oy, inv_cell, w, h, solid,
                                      sdf):
                continue
            memory[0, f] = cx
            memory[1, f] = cy
            break


@njit(cache=True, nogil=True)
def _out_of_convex(px, py, poly, r):
    """Where a body of radius ``r`` at ``p`` (float64) stands once pushed out of the convex CCW polygon
    ``poly`` (K, 2) (padded with repeated vertices); ``p`` itself when already clear
    (grid.polygon_signed_distance and the push made from it)."""
    K = poly.shape[0]
    best = np.inf
    kb = 0
    cbx = cby = 0.0
    inside = True
    for k in range(K):
        ax, ay = poly[k, 0], poly[k, 1]
        ex, ey = poly[(k + 1) % K, 0] - ax, poly[(k + 1) % K, 1] - ay
        apx, apy = px - ax, py - ay
        ll = ex * ex + ey * ey
        if ll <= 1e-18:                 # a padding edge
            continue
        if ex * apy - ey * apx < 0.0:
            inside = False
        t = min(max((apx * ex + apy * ey) / ll, 0.0), 1.0)
        cx, cy = ax + ex * t, ay + ey * t
        d2 = (px - cx) * (px - cx) + (py - cy) * (py - cy)
        if d2 < best:
            best, kb, cbx, cby = d2, k, cx, cy
    dist = np.sqrt(best)
    sd = -dist if inside else dist
    if not sd < r:
        return px, py
    ex, ey = poly[(kb + 1) % K, 0] - poly[kb, 0], poly[(kb + 1) % K, 1] - poly[kb, 1]
    ln = max(np.sqrt(ex * ex + ey * ey), 1e-12)
    dx, dy = px - cbx, py - cby
    dn = np.sqrt(dx * dx + dy * dy)
    # Outside a vertex region the push is radial from the nearest point; inside (or exactly on an edge)
    # along the nearest edge's normal.
    if sd > 1e-9 and dn > 1e-9:
        ux, uy = dx / max(dn, 1e-12), dy / max(dn, 1e-12)
    else:
        ux, uy = ey / ln, -ex / ln
    # A hair beyond r so float32 storage doesn't round back inside.
    return cbx + ux * (r + 1e-4), cby + uy * (r + 1e-4)


@_loop(lambda pos, *rest: pos.shape[1])
def push_out_of_walls(pos, radius, passes, margin, polys, ox, oy, inv_cell, w, h, sdf, nx, ny, label):
    """Push bodies out of obstacle polygons (exact) and forbidden cells (along the clearance gradient),
    in place (collision.project_out_of_walls).

    Parameters
    ----------
    pos : (2, n + 1) float32
        Rows ``:n`` are moved.
    radius : (n + 1,) float32
    passes : int
        Repetitions, for bodies squeezed between two obstacles.
    margin : float
        Bodies whose cell is farther than radius + margin from every wall are left alone.
    polys : (o, K, 2) float64
        Obstacle polygons; ``label`` (cells) names the nearest, -1 for forbidden areas.
    """
    n = pos.shape[1] - 1
    for i in prange(n):
        r = radius[i]
        for _ in range(passes):
            f = _cell(pos[0, i], pos[1, i], ox, oy, inv_cell, w, h)
            if not sdf[f] < r + margin:
                break
            lab = label[f]
            if lab < 0:
                depth = max(r - sdf[f], _F0)
                pos[0, i] += nx[f] * depth
                pos[1, i] += ny[f] * depth
            elif polys.shape[0] > 0:
                qx, qy = _out_of_convex(np.float64(pos[0, i]), np.float64(pos[1, i]), polys[lab], np.float64(r))
                pos[0, i] = qx
                pos[1, i] = qy


@njit(cache=True, nogil=True)
def _ray(ox, oy, ux, uy, speed, rvx, rvy, reach):
    # Distance walked along u at `speed` before touching a disc of radius `reach` at relative position o
    # moving at rv: inf where never, 0 where touching and closing in (float32, the reference's order).
    wx = rvx - speed * ux
    wy = rvy - speed * uy
    a = wx * wx + wy * wy
    b = ox * wx + oy * wy
    c = ox * ox + oy * oy - reach * reach
    if c <= _F0:
        return _F0 if b < _F0 else _INF32
    disc = b * b - a * c
    if disc > _F0 and b < _F0 and a > _A_MIN:
        t = (-b - np.sqrt(max(disc, _F0))) / max(a, _A_MIN)
        return max(t, _F0) * speed
    return _INF32


@njit(cache=True, nogil=True)
def _first_ahead(pos, vel, radius, nb, r, ux, uy, gx, gy, reach):
    # Walker r's distance to the first body standing in direction u (a person, else whatever nearer
    # than `reach`: a wall, the horizon), and whether it stands in line there: that person is not coming
    # toward it and no neighbour walks against its goal's way g faster than COUNTERFLOW_SPEED.
    gap = _INF32
    ahead = -1
    against = False
    for c in range(nb.shape[0]):
        j = nb[c]
        g = _ray(pos[0, j] - pos[0, r], pos[1, j] - pos[1, r], ux, uy, _F1, _F0, _F0, radius[r] + radius[j])
        if g < gap:
            gap, ahead = g, j
        against |= vel[0, j] * gx + vel[1, j] * gy < -_COUNTERFLOW
    in_line = gap < reach and not against and vel[0, ahead] * ux + vel[1, ahead] * uy >= _F0
    return min(gap, reach), in_line


@njit(cache=True, nogil=True)
def radial_falloff(x, y, ox, oy, radius):
    """(n,) float32 ``clip(1 - r / radius, 0, 1)``, ``r`` each point's float64 distance from (ox, oy):
    a blast's damage (behavior_maps.MapLayer.sample)."""
    out = np.empty(x.shape[0], np.float32)
    for i in range(x.shape[0]):
        r = np.hypot(np.float64(x[i]) - ox, np.float64(y[i]) - oy)
        out[i] = np.float32(np.minimum(np.maximum(1.0 - r / radius, 0.0), 1.0))
    return out


@njit(cache=True, nogil=True)
def within_reach(pos, rows, ox, oy, reach):
    """Those of ``rows`` nearer than ``reach`` metres to (ox, oy), (a,) int64, and their float64 distances."""
    m = rows.shape[0]
    near = np.empty(m, np.int64)
    dist = np.empty(m, np.float64)
    a = 0
    for q in range(m):
        d = np.hypot(np.float64(pos[0, rows[q]]) - ox, np.float64(pos[1, rows[q]]) - oy)
        if d < reach:
            near[a] = rows[q]
            dist[a] = d
            a += 1
    return near[:a], dist[:a]


@njit(cache=True, nogil=True)
def flee_blast(pos, rows, dist, ox, oy, safe, dirs, ox_grid, oy_grid, inv_cell, w, h, speed, panic_factor, freeze,
               run, walk, rest):
    """Civilians' flight from a blast at (ox, oy) (behavior_maps.Reactions._civilians): ``rows``, ``dist``
    metres from it, walk away down its distance map (``dirs`` (2, h * w) toward it, flat cell order;
    radially where the map has no way), running at ``panic_factor`` (float32) times their ``speed``
    inside ``safe`` metres; those who ``freeze`` stand.

    Returns
    -------
    v : (2, m) float32
        Desired velocities.
    behavior : (m,) int8
        ``run``, ``walk`` or ``rest`` (codes).
    """
    m = rows.shape[0]
    v = np.empty((2, m), np.float32)
    beh = np.empty(m, np.int8)
    for q in range(m):
        r = rows[q]
        f = _cell(pos[0, r], pos[1, r], ox_grid, oy_grid, inv_cell, w, h)
        ax, ay = -dirs[0, f], -dirs[1, f]
        if ax == 0 and ay == 0:
            ax, ay, _ = _unit(np.float32(np.float64(pos[0, r]) - ox), np.float32(np.float64(pos[1, r]) - oy))
        panic = dist[q] < safe
        pace = speed[r] * panic_factor if panic else speed[r]
        v[0, q] = ax * pace
        v[1, q] = ay * pace
        beh[q] = run if panic else walk
        if freeze[r]:
            v[0, q] = v[1, q] = _F0
            beh[q] = rest
    return v, beh


@njit(cache=True, nogil=True)
def blend_rows(v, behavior, rows, weight, v_rows, behavior_rows):
    """Behavior-map reactions blended into the intent, in place: for each of the agents ``rows`` (m,)
    (no row twice) the desired velocity ``v`` (2, n) moves to ``v_rows`` (2, m) by its map influence
    ``weight`` (n,) float32, and its ``behavior`` (n,) becomes ``behavior_rows`` (m,) where that is
    over a half."""
    for q in range(rows.shape[0]):
        r = rows[q]
        w = weight[r]
        v[0, r] = v[0, r] * (_F1 - w) + v_rows[0, q] * w
        v[1, r] = v[1, r] * (_F1 - w) + v_rows[1, q] * w
        if w > np.float32(0.5):
            behavior[r] = behavior_rows[q]


@njit(cache=True, nogil=True)
def worsen_health(health, damage, wound_at, dead_at, wounded, dead):
    """Wound (``wounded``) or kill (``dead``) where ``damage`` (n,) reaches each agent's ``wound_at`` or
    ``dead_at``; health (n,) int8 only worsens, in place."""
    for i in range(health.shape[0]):
        if damage[i] >= dead_at[i]:
            health[i] = max(health[i], dead)
        elif damage[i] >= wound_at[i]:
            health[i] = max(health[i], wounded)


@njit(cache=True, nogil=True)
def _unit(dx, dy):
    # steering.unit for one vector: (x, y) / max(norm, 1e-6), and the norm.
    norm = np.sqrt(dx * dx + dy * dy)
    s = np.maximum(norm, _EPS)
    return dx / s, dy / s, norm


@njit(cache=True, nogil=True)
def goal_directions(pos, goal, rows, goal_id, goal_dirs, ox, oy, inv_cell, w, h):
    """Simulation._goal_direction: each walker's way to its goal, down the goal's distance map where it has
    one (``goal_id`` >= 0, a non-zero direction in the walker's cell of ``goal_dirs``), else straight.

    Parameters
    ----------
    pos, goal : (2, N) float32
    rows : (m,) int
    goal_id : (N,) int64
        Row of each agent's goal in ``goal_dirs``, -1 for none.
    goal_dirs : (g, 2, h * w) float32
        Unit directions down each goal's distance map, flat cell order (g may be 0).

    Returns
    -------
    u : (2, m) float32
        Unit directions.
    dist : (m,) float32
        Straight-line distances to the goals.
    """
    m = rows.shape[0]
    u = np.empty((2, m), np.float32)
    dist = np.empty(m, np.float32)
    for q in range(m):
        r = rows[q]
        ux, uy, dist[q] = _unit(goal[0, r] - pos[0, r], goal[1, r] - pos[1, r])
        g = goal_id[r]
        if g >= 0 and goal_dirs.shape[0]:
            f = _cell(pos[0, r], pos[1, r], ox, oy, inv_cell, w, h)
            if goal_dirs[g, 0, f] != 0 or goal_dirs[g, 1, f] != 0:
                ux, uy = goal_dirs[g, 0, f], goal_dirs[g, 1, f]
        u[0, q] = ux
        u[1, q] = uy
    return u, dist


@njit(cache=True, nogil=True)
def _arrive(px, py, tx, ty, speed, slow_radius, stop_radius):
    # steering.arrive for one agent: (vx, vy).
    ux, uy, d = _unit(tx - px, ty - py)
    pace = speed * np.minimum(np.maximum((d - stop_radius) / slow_radius, _F0), _F1)
    return ux * pace, uy * pace


@njit(cache=True, nogil=True)
def follow_leaders(pos, followers, memory, speed, factor, slow_radius, stop_radius, leader_of, was, run, v,
                   behavior):
    """Group members' intent (seed 003's E_L), in place: each follower's desired velocity in ``v`` (2, n)
    arrives at its remembered leader position ``memory`` (2, f) at ``factor`` of its preferred speed
    ``speed`` (n,), slowing inside ``slow_radius`` to a stop at ``stop_radius`` (f,); it runs in
    ``behavior`` (n,) when its leader ran (``was``, last step's behaviors). ``followers``, ``leader_of``:
    (f,) rows."""
    for q in range(followers.shape[0]):
        r = followers[q]
        v[0, r], v[1, r] = _arrive(pos[0, r], pos[1, r], memory[0, q], memory[1, q], speed[r] * factor,
                                   slow_radius, stop_radius[q])
        if was[leader_of[q]] == run:
            behavior[r] = run


@njit(cache=True, nogil=True)
def sight_rounds(v, behavior, walk, ctype, human, vel, follows, waited, queued_until, sight, time, dt, steps,
                 every):
    """The bookkeeping of walking by sight for one step: who walks by sight, who waits their turn, and
    whose look is due (Simulation._walk_by_sight).

    A walker is a human whose behavior is ``walk`` and who means to move (desired speed over 1 mm/s); the
    others forget their last look (``sight`` NaN). A walker in line (``follows``, as last seen) moving
    slower than QUEUE_SPEED adds ``dt`` to ``waited`` (anyone else starts again from 0); after QUEUE_AFTER
    seconds of it they wait their turn until ``time`` + QUEUE_HOLD (``queued_until``). A walker looks
    again every ``every`` steps (in turn: when ``steps`` + its row is a multiple), or at once when it has
    no last look.

    Parameters
    ----------
    v : (2, n) float32
        Desired velocities.
    behavior, ctype : (n,) int8
    walk, human : int
        The codes of the walking behavior and of people.
    vel : (2, n + 1) float32
    follows : (n,) bool
    waited, queued_until : (n,) float32, float64, seconds (in place)
    sight : (2, n) float32 (in place)
    time : float, seconds
    dt : float32, seconds
    steps, every : int

    Returns
    -------
    speed : (n,) float32
        Desired speeds.
    rows, due : (w,), (d,) int64
        The walkers, and those whose look is due.
    """
    n = behavior.shape[0]
    speed = np.empty(n, np.float32)
    rows = np.empty(n, np.int64)
    due = np.empty(n, np.int64)
    w = d = 0
    for i in range(n):
        s = np.sqrt(v[0, i] * v[0, i] + v[1, i] * v[1, i])
        speed[i] = s
        walking = behavior[i] == walk and ctype[i] == human and s > _MEANS_TO_MOVE
        if not walking:
            sight[0, i] = sight[1, i] = np.nan
        if walking and follows[i] and vel[0, i] * vel[0, i] + vel[1, i] * vel[1, i] < _QUEUE_SPEED2:
            waited[i] += dt
        else:
            waited[i] = _F0
        if waited[i] >= _QUEUE_AFTER:
            queued_until[i] = time + P.QUEUE_HOLD
        if walking:
            rows[w] = i
            w += 1
            if (steps + i) % every == 0 or not np.isfinite(sight[0, i]):
                due[d] = i
                d += 1
    return speed, rows[:w], due[:d]


@njit(cache=True, nogil=True)
def _wall_along(px, py, ux, uy, steps, limit, horizon, ox, oy, inv_cell, w, h, sdf, near, polys, sizes):
    # How far one can walk from p along u before the clearance falls under `limit`, sampled at `steps`
    # and taken as a quarter metre before (`horizon` where it never does). Interpolated only near the
    # limit: a distance differs from the nearest cell centre's by less than two cells.
    for s in range(steps.shape[0]):
        x = px + ux * steps[s]
        y = py + uy * steps[s]
        if sdf[_cell(x, y, ox, oy, inv_cell, w, h)] < limit + _TWO / inv_cell and \
                _sdf_at(x, y, ox, oy, inv_cell, w, h, sdf, near, polys, sizes) < limit:
            return steps[s] - np.float32(0.25)
    return horizon


@_loop(lambda pos, vel, radius, nb, rows, *rest: rows.shape[0])
def choose_ways(pos, vel, radius, nb, rows, ux, uy, speed, cos_offsets, horizon, tau, queued, queue_tau, ghost,
                walls, steps, ox, oy, inv_cell, w, h, sdf, near, polys, sizes):
    """Moussaid, Helbing and Theraulaz's two heuristics for each walker (vision.heuristic_velocity): the
    direction that brings it nearest its goal, given how far it can walk each way before touching
    someone (or a wall), and a speed that keeps the time gap ``tau`` to whoever stands that way.

    Parameters
    ----------
    pos, vel : (2, N) float32
    radius : (N,) float
    nb : (m, k) int
        The walkers' neighbours.
    rows : (m,) int
        The walkers.
    ux, uy : (m, d) float32
        Unit directions tried, the goal's in the middle.
    speed : (m,) float32
        Desired speeds.
    cos_offsets : (1, d) float32
        Cosines of the directions' angles from the goal's.
    horizon, tau : float32
    queued : (m,) bool
        Waiting their turn: they keep ``queue_tau`` (float32) instead of ``tau`` to someone ahead who is
        not coming toward them.
    ghost : int
        The row padding ``nb`` (-1 for none): a body standing a thousand kilometres away, which no way
        reaches within the horizon, so it is not looked at along each way.
    walls : bool
        Whether to look for walls too, at ``steps`` (s,) float32 metres along each direction, in the
        grid's clearance (``ox`` ... ``sizes``: WalkGrid.lookup, flat_sdf and exact).

    Returns
    -------
    velocity : (2, m) float32
    free : (m,) bool
        Straight toward the goal at the desired speed.
    follows : (m,) bool
        In line: the first body that way is a person not coming toward the walker (standing, or walking
        on), and no neighbour walks against the walker's way faster than COUNTERFLOW_SPEED.
    """
    m, d = ux.shape
    k = nb.shape[1]
    out = np.empty((2, m), np.float32)
    free = np.empty(m, np.bool_)
    follows = np.empty(m, np.bool_)
    wall = np.full((m, d), horizon, np.float32)
    for i in prange(m):
        r = rows[i]
        # One already near a wall is stopped only where it would get nearer still.
        here = _sdf_at(pos[0, r], pos[1, r], ox, oy, inv_cell, w, h, sdf, near, polys, sizes)
        limit = min(radius[r], here - _WALL_APPROACH)
        best_q = 0
        best_left = _INF32
        for q in range(d):
            f = _INF32
            for c in range(k):
                j = nb[i, c]
                if j == ghost:
                    continue
                f = min(f, _ray(pos[0, j] - pos[0, r], pos[1, j] - pos[1, r], ux[i, q], uy[i, q], speed[i],
                                vel[0, j], vel[1, j], radius[r] + radius[j]))
            f = min(f, horizon)
            if walls:
                wall[i, q] = _wall_along(pos[0, r], pos[1, r], ux[i, q], uy[i, q], steps, limit, horizon, ox, oy,
                                         inv_cell, w, h, sdf, near, polys, sizes)
                f = min(f, wall[i, q])
            # Distance left to the goal (at the horizon) after walking f this way, less horizon^2.
            left = f * f - (np.float32(2.0) * horizon) * f * cos_offsets[0, q]
            if left < best_left:
                best_left, best_q = left, q
        gap, follows[i] = _first_ahead(pos, vel, radius, nb[i], r, ux[i, best_q], uy[i, best_q], ux[i, d // 2],
                                       uy[i, d // 2], min(horizon, wall[i, best_q]))
        v = min(speed[i], max(gap, _F0) / (queue_tau if queued[i] and follows[i] else tau))
        out[0, i] = ux[i, best_q] * v
        out[1, i] = uy[i, best_q] * v
        free[i] = best_q == d // 2 and v >= speed[i]
    return out, free, follows


@njit(cache=True, nogil=True)
def _narrow_at(px, py, width, ox, oy, inv_cell, w, h, sdf, nx, ny, near, polys, sizes):
    # Whether p stands in a passage narrower than `width`: from the nearest wall, across p, the next wall
    # comes within it (marched in 5 cm steps). The cell centre's clearance, within two cells of the
    # exact one, rules most points out first.
    if sdf[_cell(px, py, ox, oy, inv_cell, w, h)] >= width / _TWO + _TWO / inv_cell:
        return False
    here, ux, uy = _wall_at(px, py, ox, oy, inv_cell, w, h, sdf, nx, ny, near, polys, sizes)
    if here >= width / _TWO or here <= _F0:
        return False
    for t in range(1, 41):
        d = np.float32(0.05 * t)
        if here + d >= width:
            return False
        if _sdf_at(px + ux * d, py + uy * d, ox, oy, inv_cell, w, h, sdf, near, polys, sizes) < _SIDE_WALL:
            return True
    return False


@_loop(lambda pos, vel, n, *rest: n)
def turned_sideways(pos, vel, n, width, ahead, ox, oy, inv_cell, w, h, sdf, nx, ny, near, polys, sizes):
    """(n,) bool: who stands in a passage narrower than ``width`` metres, or walks into one within
    ``ahead`` metres (looked for every half metre along its velocity): they turn their shoulders
    (params.SIDEWAYS_RADIUS)."""
    out = np.zeros(n, np.bool_)
    for i in prange(n):
        px, py = pos[0, i], pos[1, i]
        if sdf[_cell(px, py, ox, oy, inv_cell, w, h)] >= ahead + width + _TWO / inv_cell:
            continue                                      # no wall near enough to make a passage
        vx, vy, speed = _unit(vel[0, i], vel[1, i])
        steps = int(ahead / _HALF) if speed >= _SIDEWAYS_MOVING else 0
        for k in range(steps + 1):
            d = _HALF * np.float32(k)
            if _narrow_at(px + vx * d, py + vy * d, width, ox, oy, inv_cell, w, h, sdf, nx, ny, near, polys, sizes):
                out[i] = True
                break
    return out


cache_one_process_at_a_time(globals())
