"""The compiled loops of the crowd step (usdcrowd.sim.kernels) against the numpy formulas they replace.

The grid and vision kernels must give the reference's bits; the pair forces and overlap corrections
sum neighbours in another order, so they must agree to float32 rounding. The references here are the
vectorised numpy forms (the package's own building blocks where they remain, the step's former code
otherwise).
"""

from __future__ import annotations

import numpy as np
import pytest

from tests.helpers import scenarios as S
from tests.helpers.tools import load_tool
from usdcrowd.sim import SimSettings, Simulation
from usdcrowd.sim import kernels as K
from usdcrowd.sim import params as P
from usdcrowd.sim.collision import (GOLDEN_ANGLE, agent_avoidance, project_out_of_walls, resolve_overlaps,
                                   wall_avoidance)
from usdcrowd.sim.grid import WalkGrid, polygon_signed_distance
from usdcrowd.sim.groups import flocking, mate_mask
from usdcrowd.sim.neighbors import NeighborList
from usdcrowd.sim.steering import arrive, clip_norm, containment, separation, unit
from usdcrowd.sim.vision import heuristic_velocity


@pytest.fixture
def packed_crowd():
    """600 people walking every way in a 12 m square (many touching, some coincident pairs), in groups
    of 6, with their neighbour table: (pos, vel, radius, idx, mates)."""
    rng = np.random.default_rng(7)
    n = 600
    pos = np.empty((2, n + 1), np.float32)
    pos[:, :n] = rng.uniform(-6.0, 6.0, (2, n))
    pos[:, 50:53] = pos[:, 40:43]                     # three people on top of three others
    pos[:, n] = P.GHOST_POSITION
    vel = np.zeros((2, n + 1), np.float32)
    vel[:, :n] = rng.normal(0.0, 1.0, (2, n))
    radius = np.append(rng.uniform(0.2, 0.3, n), 0.0).astype(np.float32)
    nl = NeighborList(n, np.arange(n))
    nl.update(pos)
    group = np.append(np.arange(n) // 6, -1).astype(np.int32)
    mates = mate_mask(group, nl.idx, np.zeros(n, bool))
    return pos, vel, radius, nl.idx, mates


def _reference_forces(pos, vel, v_des, gain, radius, idx, mates, grid, lo, hi):
    """The force terms as (n, k) numpy arrays, added in the step's order (``gain``: each agent's 1 / tau)."""
    n = idx.shape[0]
    dx = pos[:, :n, None] - pos[:, idx]
    dv = vel[:, :n, None] - vel[:, idx]
    dist = np.sqrt(dx[0] * dx[0] + dx[1] * dx[1])
    gap = dist - (radius[:n, None] + radius[idx])
    F = (v_des - vel[:, :n]) * gain
    F += agent_avoidance(dx, dv, dist, gap, vel[:, :n])
    F += separation(dx, dist, gap)
    F += flocking(dx, dv, dist, mates)
    if grid is not None:
        F += wall_avoidance(grid, pos[:, :n], vel[:, :n], radius[:n])
    F += containment(pos[:, :n], vel[:, :n], lo, hi)
    return F


def _reference_overlaps(pos, idx, radius, movable, relax=P.OVERLAP_RELAX):
    """The Jacobi pass as numpy arrays (the step's former code)."""
    n = idx.shape[0]
    dx = pos[:, :n, None] - pos[:, idx]
    dist = np.sqrt(dx[0] * dx[0] + dx[1] * dx[1])
    over = radius[:n, None] + radius[idx] - dist
    w = np.where(over > 0, over * np.float32(0.5 * relax) / np.maximum(dist, 1e-6), 0.0).astype(np.float32)
    same = dist < 1e-6
    i, k = np.nonzero(same)
    j = idx[i, k].astype(np.int64)
    angle = ((i + j) * GOLDEN_ANGLE) % (2.0 * np.pi)
    side = np.where(i > j, 1.0, -1.0)
    dx[0][i, k] = side * np.cos(angle)
    dx[1][i, k] = side * np.sin(angle)
    w[same] = np.float32(0.5 * relax) * over[same]
    out = pos.copy()
    out[:, :n] += np.einsum("cnk,nk->cn", dx, w) * movable
    return out


def _reference_ray_hit(ox, oy, ux, uy, speed, rel_vx, rel_vy, reach):
    """vision's time-to-touch of discs as broadcast numpy arrays (its former form)."""
    wx, wy = rel_vx - speed * ux, rel_vy - speed * uy
    a = wx * wx + wy * wy
    b = ox * wx + oy * wy
    c = ox * ox + oy * oy - reach * reach
    disc = b * b - a * c
    t = (-b - np.sqrt(np.maximum(disc, 0.0))) / np.maximum(a, np.float32(1e-9))
    dist = np.where((disc > 0.0) & (b < 0.0) & (a > 1e-9), np.maximum(t, 0.0) * speed, np.float32(np.inf))
    return np.where(c <= 0.0, np.where(b < 0.0, np.float32(0.0), np.float32(np.inf)), dist)


@pytest.mark.parametrize("walls", [False, True], ids=["open", "walls"])
def test_the_force_is_its_terms_summed(packed_crowd, pillars_among_the_crowd, walls):
    pos, vel, radius, idx, mates = packed_crowd
    grid = pillars_among_the_crowd
    n = idx.shape[0]
    v_des = np.random.default_rng(1).normal(0.0, 1.0, (2, n)).astype(np.float32)
    lo, hi = np.array([-5.0, -5.0], np.float32), np.array([5.0, 5.0], np.float32)   # some walk out
    # Walkers by sight relax faster toward their desired velocity than the others.
    gain = np.where(np.arange(n) % 3 == 0, 1.0 / P.SIGHT_RELAX, 1.0 / P.TAU_RELAX).astype(np.float32)
    want = _reference_forces(pos, vel, v_des, gain, radius, idx, mates, grid if walls else None, lo, hi)
    got = K.forces(pos, vel, v_des, gain, radius, idx, mates, walls, *grid.lookup, grid.flat_sdf, grid.flat_nx,
                   grid.flat_ny, *grid.exact, lo, hi)
    steering = (v_des - vel[:, :n]) * gain
    assert (np.hypot(*(want - steering)) > 10.0).sum() > 50       # the terms are not negligible here
    if walls:
        assert (np.hypot(*wall_avoidance(grid, pos[:, :n], vel[:, :n], radius[:n])) > 1.0).sum() > 20
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=2e-5)


def test_overlap_corrections_push_apart_as_the_jacobi_pass_did(packed_crowd):
    pos, _, radius, idx, _ = packed_crowd
    n = idx.shape[0]
    movable = np.ones(n, np.float32)
    movable[::7] = 0.0                                   # pinned bodies stay put
    want = _reference_overlaps(pos, idx, radius, movable)
    got = pos.copy()
    resolve_overlaps(got, idx, radius, movable)
    assert np.abs(want - pos).max() > 0.05
    np.testing.assert_allclose(got, want, rtol=0, atol=2e-6)
    np.testing.assert_array_equal(got[:, :n:7], pos[:, :n:7])
    # The coincident pairs go opposite ways.
    d = got[:, 50:53] - got[:, 40:43]
    assert (np.hypot(d[0], d[1]) > 0.05).all()


@pytest.fixture
def walled_grid():
    """The crowd-step benchmark's square with its four walls, as a walkable grid."""
    return WalkGrid(load_tool("bench_sim").scene(50))


def _reference_cells(g, x, y):
    ix = np.clip(((x - g.origin[0]) * (1.0 / g.cell)).astype(np.int64), 0, g.w - 1)
    iy = np.clip(((y - g.origin[1]) * (1.0 / g.cell)).astype(np.int64), 0, g.h - 1)
    return iy * g.w + ix


@pytest.mark.parametrize("which", ["bench square", "pillars"])
def test_grid_lookups_give_the_reference_bits(walled_grid, pillars_among_the_crowd, which):
    g, span = (walled_grid, 104.0) if which == "bench square" else (pillars_among_the_crowd, 9.0)
    rng = np.random.default_rng(3)
    for dtype in (np.float32, np.float64):
        x, y = rng.uniform(-span, span, (2, 5000)).astype(dtype)
        f = _reference_cells(g, x, y)
        np.testing.assert_array_equal(g.flat_index(x, y), f)
        far = np.array([-1e4, 1e4], dtype)                     # beyond the grid: clamped to its corners
        np.testing.assert_array_equal(g.flat_index(far, far), [0, g.w * g.h - 1])
        sdf, nx, ny = g.clearance(x, y)
        want, normal = _reference_clearance(g, x, y)
        assert (want < 1.0).sum() > 20                       # some near walls
        np.testing.assert_allclose(sdf, want, rtol=0, atol=1e-5)
        np.testing.assert_allclose(np.stack([nx, ny], axis=1), normal, rtol=0, atol=1e-5)
        bx, by = rng.uniform(-span, span, (2, 5000)).astype(dtype)
        bx[:2500], by[:2500] = x[:2500] + (bx[:2500] - x[:2500]) * 0.02, y[:2500] + (by[:2500] - y[:2500]) * 0.02
        want = _reference_sight(g, x, y, bx, by)
        got = g.line_of_sight(x, y, bx, by)
        assert 0 < want.sum() < len(want)
        np.testing.assert_array_equal(got, want)


def _reference_clearance(g, x, y):
    """Between four cell centres that each have an obstacle whose distance is their clearance, the
    least exact distance to those obstacles and the direction away from it; elsewhere bilinear between
    the centres and the nearest cell's slope, in float64."""
    fx = (x.astype(np.float64) - g.origin[0]) / g.cell - 0.5
    fy = (y.astype(np.float64) - g.origin[1]) / g.cell - 0.5
    ix = np.clip(np.floor(fx).astype(int), 0, g.w - 2)
    iy = np.clip(np.floor(fy).astype(int), 0, g.h - 2)
    tx, ty = np.clip(fx - ix, 0.0, 1.0), np.clip(fy - iy, 0.0, 1.0)
    s = g.sdf.astype(np.float64)
    out = ((s[iy, ix] * (1 - tx) + s[iy, ix + 1] * tx) * (1 - ty)
           + (s[iy + 1, ix] * (1 - tx) + s[iy + 1, ix + 1] * tx) * ty)
    f = _reference_cells(g, x, y)
    normal = np.stack([g.flat_nx[f], g.flat_ny[f]], axis=1).astype(np.float64)
    near = np.stack([g.near[iy, ix], g.near[iy, ix + 1], g.near[iy + 1, ix], g.near[iy + 1, ix + 1]], axis=1)
    p = np.stack([x, y], axis=1).astype(np.float64)
    for i in np.flatnonzero((near >= 0).all(axis=1)):
        k = np.unique(near[i])
        d, c, _ = polygon_signed_distance(np.repeat(p[i:i + 1], len(k), 0), g.polygons[k])
        j = np.argmin(d)
        out[i] = d[j]
        if abs(d[j]) > 1e-9:
            normal[i] = (p[i] - c[j]) / d[j]
    return out, normal


def test_a_passage_between_two_walls_is_as_wide_between_cell_centres_as_it_stands():
    """A 0.8 m door whose walls fall between cell centres: its middle is 0.40 m from both (blending the
    centres' clearances read 0.275 m there), and every point in and around it is as far from the walls
    as the two boxes say."""
    walls = [(0.0, -2.4, 0.5, 2.0), (0.0, 2.4, 0.5, 2.0)]            # the gap: y from -0.4 to 0.4
    g = WalkGrid(S.scenario(S.agents(np.zeros((1, 2))), S.groups([[5.0, 0.0, 0.0]]),
                            obstacles=[S.box(*b) for b in walls], bounds=((-10, -10), (10, 10))))
    middle = np.linspace(-0.5, 0.5, 21)
    np.testing.assert_allclose(g.clearance(middle, np.zeros(21))[0], 0.4, atol=1e-6)
    x, y = np.random.default_rng(4).uniform([-1.5, -0.4], [1.5, 0.4], (4000, 2)).T
    want = np.min([np.hypot(np.maximum(np.abs(x - cx) - hx, 0.0), np.maximum(np.abs(y - cy) - hy, 0.0))
                   for cx, cy, hx, hy in walls], axis=0)
    np.testing.assert_allclose(g.clearance(x, y)[0], want, atol=1e-5)


def _door_grid(width):
    """Two walls across x = 0 leaving a door ``width`` metres wide around y = 0."""
    half = width / 2.0
    walls = [S.box(0.0, -half - 2.0, 0.5, 2.0), S.box(0.0, half + 2.0, 0.5, 2.0)]
    return WalkGrid(S.scenario(S.agents(np.zeros((1, 2))), S.groups([[5.0, 0.0, 0.0]]), obstacles=walls,
                               bounds=((-10, -10), (10, 10))))


def _sideways(g, xy, v):
    pos = np.asarray(xy, np.float32).T.copy()
    vel = np.asarray(v, np.float32).T.copy()
    return K.turned_sideways(pos, vel, pos.shape[1], np.float32(P.SIDEWAYS_WIDTH), np.float32(P.SIDEWAYS_AHEAD),
                             *g.lookup, g.flat_sdf, g.flat_nx, g.flat_ny, *g.exact)


def test_people_turn_sideways_in_and_on_the_way_into_a_passage_narrower_than_two_bodies():
    """In a 0.8 m door, off its middle too, and walking into it from up to SIDEWAYS_AHEAD away: turned.
    Standing still before it, walking away from it, in a 1.2 m door or in the open: not."""
    narrow, wide = _door_grid(0.8), _door_grid(1.2)
    walk = [1.2, 0.0]
    xy = [[0.0, 0.0], [0.0, 0.2], [-1.5, 0.0], [-1.5, 0.0], [-1.5, 0.0], [-3.0, 0.0], [5.0, 5.0]]
    v = [[0.0, 0.0], walk, walk, [0.0, 0.0], [-1.2, 0.0], walk, walk]
    assert _sideways(narrow, xy, v).tolist() == [True, True, True, False, False, False, False]
    assert not _sideways(wide, xy, v).any()


def _reference_sight(g, x, y, bx, by):
    """Every segment sampled at its own spacing, every sample's cell looked at."""
    length = np.hypot((bx - x).astype(np.float64), (by - y).astype(np.float64))
    want = np.empty(len(x), bool)
    for i in range(len(x)):
        s = int(min(96, max(2, np.ceil(length[i] / (0.7 * g.cell)) + 1)))
        t = (np.arange(s, dtype=np.float32) + np.float32(0.5)) / np.float32(s)
        px, py = x[i] + (bx[i] - x[i]) * t, y[i] + (by[i] - y[i]) * t
        want[i] = not g.flat_solid[_reference_cells(g, px, py)].any()
    return want


@pytest.mark.parametrize("where", ["bench square", "pillars"])
def test_sight_lines_clear_of_walls_by_their_length_need_no_sampling(walled_grid, pillars_among_the_crowd, where):
    """Lines a wall's clearance long, give or take two cells, every way from points all over the grid
    (some outside it): the answer without sampling where the start is clear by the length is the one
    sampling gives."""
    g = walled_grid if where == "bench square" else pillars_among_the_crowd
    rng = np.random.default_rng(8)
    lo, hi = g.origin, g.origin + g.cell * np.array([g.w, g.h])
    x, y = rng.uniform(lo - 1.0, hi + 1.0, (6000, 2)).T.astype(np.float32)
    sdf = g.clearance(x, y)[0].astype(np.float64)
    length = np.maximum(sdf + rng.uniform(-2.0, 2.0, len(x)) * g.cell, 0.0)
    a = rng.uniform(0.0, 2 * np.pi, len(x))
    bx, by = (x + length * np.cos(a)).astype(np.float32), (y + length * np.sin(a)).astype(np.float32)
    want = _reference_sight(g, x, y, bx, by)
    unsampled = sdf > length + 1.5 * g.cell
    assert unsampled.sum() > 500 and (~unsampled & want).sum() > 500 and (~want).sum() > 150
    np.testing.assert_array_equal(g.line_of_sight(x, y, bx, by), want)


@pytest.fixture
def pillars_among_the_crowd():
    """A walkable grid with two pillars, a wall and a painted forbidden patch inside packed_crowd's square."""
    obstacles = [S.box(1.0, 1.0, 0.5, 2.0), S.box(-3.0, -2.0, 1.0, 0.5), S.box(0.0, 5.5, 6.0, 0.3)]
    img = np.zeros((16, 16), np.float32)
    img[2:5, 10:14] = 1.0                                 # x 2-6 m, y -6 to -3 m (rows from the top)
    water = S.field("forbidden", values=img, extent=((-8, -8), (8, 8)))
    return WalkGrid(S.scenario(S.agents(np.zeros((1, 2))), S.groups([[0, 0, 0]]), obstacles=obstacles,
                               fields=[water], bounds=((-8, -8), (8, 8))))


def _reference_projection(grid, pos, radius, passes=2):
    """Bodies pushed out of walls as numpy arrays, all near ones together each pass (the former code)."""
    pos = pos.copy()
    n = pos.shape[1] - 1
    rows = np.arange(n)
    for _ in range(passes):
        cell = grid.flat_index(pos[0, rows], pos[1, rows])           # the cell's own clearance, not between
        sdf, nx, ny = grid.flat_sdf[cell], grid.flat_nx[cell], grid.flat_ny[cell]
        near = sdf < radius[rows] + P.WALL_PROJECT_MARGIN
        if not near.any():
            break
        sel = rows[near]
        lab = grid.nearest_label(pos[0, sel], pos[1, sel])
        fb = lab < 0
        s = sel[fb]
        depth = np.maximum(radius[s] - sdf[near][fb], 0.0)
        pos[0, s] += nx[near][fb] * depth
        pos[1, s] += ny[near][fb] * depth
        s = sel[~fb]
        p = np.stack([pos[0, s], pos[1, s]], axis=1).astype(np.float64)
        r = radius[s].astype(np.float64)
        sd, c, nrm = polygon_signed_distance(p, grid.polygons[lab[~fb]])
        d = p - c
        dn = np.linalg.norm(d, axis=1)
        direction = np.where(((sd > 1e-9) & (dn > 1e-9))[:, None], d / np.maximum(dn, 1e-12)[:, None], nrm)
        bad = sd < r
        p[bad] = c[bad] + direction[bad] * (r[bad] + 1e-4)[:, None]
        pos[0, s], pos[1, s] = p[:, 0], p[:, 1]
    return pos


def test_bodies_are_pushed_out_of_walls_as_before(packed_crowd, pillars_among_the_crowd):
    pos, _, radius, _, _ = packed_crowd
    grid = pillars_among_the_crowd
    want = _reference_projection(grid, pos, radius)
    got = pos.copy()
    project_out_of_walls(grid, got, radius)
    moved = np.hypot(*(want - pos))[:-1] > 1e-3
    wet = grid.nearest_label(pos[0, :-1], pos[1, :-1]) < 0
    assert (moved & ~wet).sum() > 20 and (moved & wet).sum() > 5   # out of the polygons, and of the water
    np.testing.assert_array_equal(got, want)
    # Those moved out of a polygon stand clear of the polygon nearest them now (a radius clear of the one
    # they were in, unless another wall stands within a radius: two passes do not settle every squeeze).
    sd, _, _ = polygon_signed_distance(got[:, :-1].T.astype(np.float64),
                                       grid.polygons[grid.nearest_label(got[0, :-1], got[1, :-1])])
    solid = moved & ~wet
    assert (sd[solid] > 0).all() and np.median(sd[solid] - radius[:-1][solid]) > -1e-6


def _reference_wall_hit(grid, p, ux, uy, radius, horizon):
    s = np.array([0.25, 0.5, 1.0, 2.0, 4.0], np.float32)
    s = s[s <= horizon]
    x = p[0][:, None, None] + ux[..., None] * s
    y = p[1][:, None, None] + uy[..., None] * s
    limit = np.minimum(radius, grid.clearance(p[0], p[1])[0] - 0.05)[:, None, None]
    near = grid.clearance(x.ravel(), y.ravel())[0].reshape(x.shape) < limit
    return np.where(near.any(axis=2), s[np.argmax(near, axis=2)] - 0.25, horizon)


def test_blasts_wound_and_kill_as_the_whole_array_form_did():
    """A blast's falloff with distance (float64 distances, float32 values) and the wounds it deals (health
    only worsens; a kill counts where the thresholds cross), bit for bit."""
    rng = np.random.default_rng(9)
    n = 4000
    x, y = rng.uniform(-30.0, 30.0, (2, n)).astype(np.float32)
    x[:5], y[:5] = 3.0, -2.0                                               # at the centre
    ox, oy, R = 3.0, -2.0, 17.5
    want = np.minimum(np.maximum(1.0 - np.hypot(x - np.float64(ox), y - np.float64(oy)) / R, 0.0), 1.0)
    got = K.radial_falloff(x, y, ox, oy, R)
    np.testing.assert_array_equal(got, want.astype(np.float32))
    assert got.dtype == np.float32 and (got == 1).sum() >= 5 and (got == 0).sum() > 100 and (got > 0.5).sum() > 100
    health = rng.choice(np.array([0, 1, 2], np.int8), n, p=[0.8, 0.15, 0.05])
    wound_at = rng.uniform(0.1, 0.6, n).astype(np.float32)
    dead_at = rng.uniform(0.4, 0.95, n).astype(np.float32)                  # some below their wound level
    dmg = got * np.float32(0.9)
    dmg[7] = wound_at[7]                                                    # on the thresholds
    dmg[8] = dead_at[8]
    expect = np.maximum(health, np.where(dmg >= wound_at, np.int8(1), np.int8(0)))
    expect = np.maximum(expect, np.where(dmg >= dead_at, np.int8(2), np.int8(0)))
    K.worsen_health(health, dmg, wound_at, dead_at, np.int8(1), np.int8(2))
    np.testing.assert_array_equal(health, expect)
    assert ((dmg >= dead_at) & (dmg < wound_at)).any() and (health == 1).sum() > 100 and (health == 2).sum() > 100


def _reference_flight(pos, rows, o, alarm, safe, dirs, grid, speed, freeze):
    """Civilians' flight as whole arrays (the former Reactions._civilians, before the blend)."""
    d = np.hypot(pos[0, rows] - o[0], pos[1, rows] - o[1])
    rows, d = rows[d < alarm], d[d < alarm]
    away = -dirs[:, grid.flat_index(pos[0, rows], pos[1, rows])]
    radial, _ = unit(np.stack([pos[0, rows] - o[0], pos[1, rows] - o[1]]).astype(np.float32))
    flat = (away[0] == 0) & (away[1] == 0)
    away[:, flat] = radial[:, flat]
    v = away * np.where(d < safe, speed[rows] * P.PANIC_SPEED_FACTOR, speed[rows])
    v[:, freeze[rows]] = 0.0
    beh = np.where(freeze[rows], 5, np.where(d < safe, 4, 3)).astype(np.int8)
    return rows, d, v, beh


def test_civilians_flee_a_blast_as_the_whole_array_form_did(walled_grid):
    """Who is alarmed, how far, which way (down the map, radially where it has no way) and how fast (running
    inside the safe distance, standing when frozen), bit for bit."""
    g = walled_grid
    rng = np.random.default_rng(12)
    n = 3000
    pos = rng.uniform(-90.0, 90.0, (2, n + 1)).astype(np.float32)
    o = np.array([-60.0, -55.0, 0.0])
    pos[:, :4] = o[:2, None]                                             # at the centre
    dirs = rng.normal(0.0, 1.0, (2, g.h * g.w)).astype(np.float32)
    dirs /= np.hypot(*dirs)
    dirs[:, rng.uniform(size=g.h * g.w) < 0.2] = 0.0                     # no way here
    dirs[:, g.flat_index(pos[0, :4], pos[1, :4])] = 0.0
    speed = rng.uniform(1.0, 1.5, n + 1).astype(np.float32)
    freeze = rng.uniform(size=n + 1) < 0.1
    rows = np.flatnonzero(rng.uniform(size=n) < 0.9)
    want = _reference_flight(pos, rows, o, 40.0, 25.0, dirs, g, speed, freeze)
    near, d = K.within_reach(pos, rows, o[0], o[1], 40.0)
    v, beh = K.flee_blast(pos, near, d, o[0], o[1], 25.0, dirs, *g.lookup, speed,
                          np.float32(P.PANIC_SPEED_FACTOR), freeze, np.int8(4), np.int8(3), np.int8(5))
    for got, w in zip((near, d, v, beh), want):
        np.testing.assert_array_equal(got, w)
    assert 100 < len(near) < len(rows) and set(np.unique(beh)) == {3, 4, 5}
    assert (np.hypot(*v) > 0).sum() > 100 and np.isin(np.arange(4), near).all()


def _reference_goal_direction(sim, rows):
    """The whole-array form: straight at the goal, or down its distance map where that has a way."""
    p = sim.pos[:, rows]
    straight, dist = unit(sim.goal[:, rows] - p)
    gid = sim.goal_id[rows]
    d = sim.goal_dirs[np.maximum(gid, 0), :, sim.grid.flat_index(p[0], p[1])].T
    ok = (gid >= 0) & ((d[0] != 0) | (d[1] != 0))
    return np.where(ok[None, :], d, straight), dist


def test_walkers_head_for_their_goals_and_followers_for_their_leaders_as_whole_arrays_said():
    """Round the pillars down the goal's distance map (straight where it has no way or the walker no map),
    and Reynolds' arrive at the remembered leader, bit for bit."""
    sim = Simulation(S.room_with_pillars(n=120, seed=4), SimSettings())
    for _ in range(40):
        sim.step()
    rows = np.arange(sim.n)
    sim.goal_id[::7] = -1                                       # no map for these
    sim.pos[:, 5] = sim.goal[:, 5]                              # one standing on its goal
    flat = np.flatnonzero((sim.goal_dirs[sim.goal_id[6], 0] == 0) & (sim.goal_dirs[sim.goal_id[6], 1] == 0))
    sim.pos[:, 6] = sim.grid.cell_centers()[:, flat[len(flat) // 2]]   # one where the map has no way
    want_u, want_d = _reference_goal_direction(sim, rows)
    got_u, got_d = sim._goal_direction(rows)
    np.testing.assert_array_equal(got_u, want_u)
    np.testing.assert_array_equal(got_d, want_d)
    straight = unit(sim.goal - sim.pos[:, :sim.n])[0]
    assert (np.abs(got_u - straight).max(axis=0) > 0.05).sum() > 10 and got_d[5] == 0.0 and len(flat)
    rng = np.random.default_rng(4)
    target = (sim.pos[:, :sim.n] + rng.normal(0.0, 2.0, (2, sim.n))).astype(np.float32)
    target[:, 3] = sim.pos[:, 3]
    speed = rng.uniform(0.5, 1.5, sim.n).astype(np.float32)
    stop = rng.uniform(0.0, 1.5, sim.n).astype(np.float32)
    want_v, _ = arrive(sim.pos[:, rows], target, speed, slow_radius=P.FOLLOW_SLOW_RADIUS, stop_radius=stop)
    got_v = np.zeros((2, sim.n), np.float32)
    K.follow_leaders(sim.pos, rows, target, speed, np.float32(1.0), np.float32(P.FOLLOW_SLOW_RADIUS), stop,
                     np.zeros(sim.n, np.int64), np.zeros(sim.n, np.int8), np.int8(1), got_v, np.zeros(sim.n, np.int8))
    np.testing.assert_array_equal(got_v, want_v)
    pace = np.hypot(*got_v) / speed
    assert (pace == 0).sum() > 5 and (pace > 0.999).sum() > 5 and ((pace > 0.01) & (pace < 0.99)).sum() > 5


def _reference_sight_rounds(v, behavior, walk, ctype, human, vel, follows, waited, queued_until, sight, time, dt,
                            steps, every):
    """The bookkeeping as whole-array numpy (the former Simulation._walk_by_sight and _wait_turns)."""
    n = behavior.shape[0]
    speed = np.sqrt(v[0] * v[0] + v[1] * v[1])
    walking = (behavior == walk) & (ctype == human) & (speed > 1e-3)
    sight = sight.copy()
    sight[:, ~walking] = np.nan
    held = walking & follows & (vel[0, :n] * vel[0, :n] + vel[1, :n] * vel[1, :n] < np.float32(P.QUEUE_SPEED ** 2))
    waited = np.where(held, waited + dt, np.float32(0.0))
    queued_until = queued_until.copy()
    queued_until[waited >= P.QUEUE_AFTER] = time + P.QUEUE_HOLD
    rows = np.flatnonzero(walking)
    due = rows[((steps + rows) % every == 0) | ~np.isfinite(sight[0, rows])]
    return speed, rows, due, waited, queued_until, sight


def test_the_bookkeeping_of_walking_by_sight_is_the_numpy_it_replaces(packed_crowd):
    """Who walks by sight, who has waited long enough in line to wait their turn, whose look is due: the
    same rows, seconds and looks as the whole-array form, over a few steps of a crowd where some stand."""
    _, vel, _, _, _ = packed_crowd
    n = vel.shape[1] - 1
    rng = np.random.default_rng(21)
    vel = vel * np.where(rng.uniform(size=n + 1) < 0.4, 0.05, 1.0).astype(np.float32)   # some stand in line
    v = rng.normal(0.0, 1.0, (2, n)).astype(np.float32)
    v[:, :30] = 0.0                                                                    # some mean to stay
    behavior = rng.choice(np.array([0, 1, 2], np.int8), n, p=[0.1, 0.8, 0.1])
    ctype = np.where(rng.uniform(size=n) < 0.95, 0, 3).astype(np.int8)
    follows = rng.uniform(size=n) < 0.6
    sight = rng.normal(0.0, 1.0, (2, n)).astype(np.float32)
    sight[:, rng.uniform(size=n) < 0.2] = np.nan
    waited = np.zeros(n, np.float32)
    queued_until = np.full(n, -np.inf)
    dt, every = np.float32(0.125), 3                                  # a binary fraction: QUEUE_AFTER met exactly
    for step in range(20):
        time = 1.0 + step * float(dt)
        want = _reference_sight_rounds(v, behavior, 1, ctype, 0, vel, follows, waited, queued_until, sight,
                                       time, dt, step, every)
        got = K.sight_rounds(v, behavior, 1, ctype, 0, vel, follows, waited, queued_until, sight, time, dt, step,
                             every)
        for g, w in zip(got + (waited, queued_until, sight), want):
            np.testing.assert_array_equal(g, w)
        sight[:, want[2]] = rng.normal(0.0, 1.0, (2, len(want[2])))                  # looked again
        follows[rng.uniform(size=n) < 0.05] ^= True
    assert 0 < len(want[1]) < n and 0 < len(want[2]) < len(want[1])
    assert 0 < (queued_until > time).sum() < len(want[1]) and ((waited > 0) & (waited < P.QUEUE_AFTER)).any()


@pytest.mark.parametrize("walls", [False, True], ids=["open", "walls"])
def test_walking_by_sight_gives_the_reference_bits(packed_crowd, pillars_among_the_crowd, walls):
    pos, vel, radius, idx, _ = packed_crowd
    vel = vel * np.float32(0.3)     # a crowd at a walking pace: some stand in line, some walk against
    grid = pillars_among_the_crowd if walls else None
    rows = np.arange(0, idx.shape[0], 2)
    rng = np.random.default_rng(5)
    a = rng.uniform(-np.pi, np.pi, len(rows))
    goal = np.stack([np.cos(a), np.sin(a)])
    v0 = rng.uniform(1.0, 1.5, len(rows))
    queued = rng.uniform(size=len(rows)) < 0.5
    n = idx.shape[0]
    idx = idx.copy()
    idx[::3, 5:] = n                # fewer neighbours for some: the rest is the ghost, skipped, far away
    got, free, follows = heuristic_velocity(pos, vel, goal, v0, idx, radius, rows, grid=grid, queued=queued,
                                            ghost=n)
    # The reference: every walker x direction x neighbour (the ghost too) as broadcast arrays.
    nb = idx[rows]
    ox = (pos[0, nb] - pos[0, rows, None])[:, None, :]
    oy = (pos[1, nb] - pos[1, rows, None])[:, None, :]
    reach = (radius[rows, None] + radius[nb])[:, None, :]
    base = np.arctan2(goal[1], goal[0]).astype(np.float32)[:, None]
    d = P.VISION_DIRECTIONS
    offsets = np.radians(np.linspace(-P.VISION_FIELD_DEG, P.VISION_FIELD_DEG, d)).astype(np.float32)[None, :]
    ux, uy = np.cos(base + offsets)[..., None], np.sin(base + offsets)[..., None]
    f = _reference_ray_hit(ox, oy, ux, uy, v0.astype(np.float32)[:, None, None], vel[0, nb][:, None, :],
                           vel[1, nb][:, None, :], reach).min(axis=2)
    f = np.minimum(f, P.VISION_HORIZON)
    if walls:
        f_wall = _reference_wall_hit(grid, pos[:, rows], ux[..., 0], uy[..., 0], radius[rows], P.VISION_HORIZON)
        assert (f_wall < P.VISION_HORIZON).sum() > 50     # walls in the way of many
        f = np.minimum(f, f_wall)
    left = f * f - np.float32(2.0 * P.VISION_HORIZON) * f * np.cos(offsets)
    best = np.argmin(left, axis=1)
    pick = np.arange(len(rows))
    ux, uy = ux[pick, best, 0], uy[pick, best, 0]
    still = _reference_ray_hit(ox[:, 0], oy[:, 0], ux[:, None], uy[:, None], np.float32(1.0), 0.0, 0.0,
                               reach[:, 0])
    first = np.argmin(still, axis=1)
    gap = np.minimum(still.min(axis=1), P.VISION_HORIZON)
    person = gap < (np.minimum(f_wall[pick, best], P.VISION_HORIZON) if walls else P.VISION_HORIZON)
    if walls:
        gap = np.minimum(gap, f_wall[pick, best])
    # In line: the first person that way is not coming toward the walker, and no neighbour walks
    # against its goal's way faster than COUNTERFLOW_SPEED.
    j = nb[pick, first]
    along_way = vel[0, j] * ux + vel[1, j] * uy >= 0.0
    gx, gy = np.cos(base[:, 0]), np.sin(base[:, 0])
    against = (vel[0, nb] * gx[:, None] + vel[1, nb] * gy[:, None] < -P.COUNTERFLOW_SPEED).any(axis=1)
    want_follows = person & along_way & ~against
    tau = np.where(queued & want_follows, np.float32(P.QUEUE_TAU), np.float32(P.VISION_TAU))
    v = np.minimum(v0.astype(np.float32), np.maximum(gap, 0.0) / tau)
    want = np.stack([ux * v, uy * v]).astype(np.float32)
    want_free = (best == d // 2) & (v >= v0.astype(np.float32))
    assert 0 < want_free.sum() < len(rows)                # some walkers blocked, some not
    assert ((best == d // 2) & ~want_free).any()          # some ahead, slowed by someone in the way
    assert 0 < (queued & want_follows).sum() < len(rows)  # some closing up in line, some not
    assert (queued & want_follows & (gap > 0.0) & (gap / P.VISION_TAU < v0)).any()  # ... nearer than else
    np.testing.assert_array_equal(follows, want_follows)
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(free, want_free)


def test_the_compiled_step_gives_the_same_bytes_run_to_run():
    """Both cores share the loops: each agent's sums still run in one order, so a seed gives one result."""
    sc = S.room_with_pillars(n=120, seed=4)
    runs = []
    for _ in range(2):
        sim = Simulation(sc, SimSettings())
        for _ in range(150):
            sim.step()
        runs.append((sim.pos.tobytes(), sim.vel.tobytes()))
    assert runs[0] == runs[1]


def _reference_turn(heading, want, vel, face, turn_rate, dt):
    n = heading.shape[0]
    vx, vy = vel[0, :n], vel[1, :n]
    move = (vx * vx + vy * vy > P.HEADING_MIN_SPEED ** 2) | face
    delta = np.mod(want - heading + np.pi, 2 * np.pi) - np.pi
    lim = turn_rate * dt
    heading = heading + np.where(move, np.minimum(np.maximum(delta, -lim), lim), 0.0).astype(np.float32)
    return (np.mod(heading + np.pi, 2 * np.pi) - np.pi).astype(np.float32)


def test_headings_turn_and_wrap_as_numpys_mod_does(packed_crowd):
    """Rate-limited turns toward the velocity or a faced point, wrapped to [-pi, pi), bit for bit, for
    headings at the wrap, on it, and authored turns away (the compiled loop wraps those in full)."""
    _, vel, _, _, _ = packed_crowd
    n = vel.shape[1] - 1
    rng = np.random.default_rng(5)
    pi = np.float32(np.pi)
    heading = rng.uniform(-np.pi, np.pi, n).astype(np.float32)
    heading[:40] = np.float32(-pi)                                   # on the wrap
    heading[40:80] = np.nextafter(pi, np.float32(0.0))               # just inside it
    heading[80:90] = rng.uniform(-30.0, 30.0, 10).astype(np.float32)  # authored far out
    heading[90:100] = np.float32(0.0)
    vel = vel.copy()
    vel[:, 100:200] *= np.float32(0.01)                               # too slow to turn...
    heading[100:110] = pi                                             # ...but wrapped: pi + pi is 2 pi
    face = np.zeros(n, bool)
    face[150:170] = True                                              # ...unless facing something
    want = np.arctan2(rng.normal(size=n), rng.normal(size=n)).astype(np.float32)
    want[90:100] = np.float32(-pi)
    turn_rate = np.where(np.arange(n) % 3 == 0, 2.0, 6.0).astype(np.float32)
    for dt in (np.float32(0.01), np.float32(0.04)):
        expect = _reference_turn(heading, want, vel, face, turn_rate, dt)
        got = heading.copy()
        K.turn_headings(got, want, vel, face, turn_rate, dt)
        np.testing.assert_array_equal(got.view(np.int32), expect.view(np.int32))
        assert (got != heading).sum() > n // 2 and (got == heading)[100:150].any()
        assert ((got >= -pi) & (got < pi)).all() and (np.abs(heading[80:90]) > 2 * np.pi).any()


def test_integration_and_move_limits_are_the_numpy_steps_they_replace(packed_crowd):
    """Seed 003's integration with its clips, the overlap move limit and the position-based velocity,
    against the same steps written with steering.clip_norm on whole arrays."""
    pos, vel, _, _, _ = packed_crowd
    n = pos.shape[1] - 1
    rng = np.random.default_rng(11)
    F = rng.normal(0.0, 6.0, (2, n)).astype(np.float32)
    alive = rng.uniform(size=n) > 0.1
    max_accel = np.full(n, 5.0, np.float32)
    vmax = rng.uniform(0.0, 2.0, n).astype(np.float32)
    vmax[~alive] = 0.0
    dt = np.float32(0.01)
    # The reference.
    p, v, f = pos.copy(), vel.copy(), F.copy()
    clip_norm(f, max_accel)
    f[:, ~alive] = 0.0
    p[:, :n] += v[:, :n] * dt + f * (np.float32(0.5) * dt * dt)
    v[:, :n] += f * dt
    clip_norm(v[:, :n], vmax)
    # The kernel.
    got_p, got_v = pos.copy(), vel.copy()
    K.integrate(got_p, got_v, F.copy(), alive, max_accel, vmax, dt)
    assert (np.hypot(*F) > max_accel).sum() > 100 and (np.hypot(*v[:, :n]) >= vmax - 1e-6).sum() > 100
    np.testing.assert_array_equal(got_p, p)
    np.testing.assert_array_equal(got_v, v)
    # Moves since `old` limited to vmax dt, then constraint displacements made velocity.
    old = pos.copy()
    shoved = p + rng.normal(0.0, 0.02, p.shape).astype(np.float32)
    want = shoved.copy()
    moved = want[:, :n] - old[:, :n]
    clip_norm(moved, vmax * dt)
    want[:, :n] = old[:, :n] + moved
    got = shoved.copy()
    K.limit_moves(got, old, vmax, dt)
    np.testing.assert_array_equal(got, want)
    want_v = v.copy()
    want_v[:, :n] += (want[:, :n] - p[:, :n]) * np.float32(100.0)
    clip_norm(want_v[:, :n], np.maximum(vmax, 0.0))
    K.settle_velocities(got, got_v, p[:, :n].copy(), np.float32(100.0), vmax)
    np.testing.assert_array_equal(got_v, want_v)


def _reference_memory(groups, step, pos, grid):
    """groups.Groups.update_memory as numpy arrays, probe by probe (the former code); returns the memory."""
    memory = groups.memory.copy()
    f = len(groups.followers)
    sub = np.arange(step % P.LOS_EVERY, f, P.LOS_EVERY)
    me = groups.followers[sub]
    mx, my = pos[0, me], pos[1, me]
    todo = np.ones(sub.size, dtype=bool)
    slot = groups.slot[sub]
    candidates = [pos[:, groups.leader_of[sub]]]
    candidates += [groups.trail[:, slot, (groups.head - o) % P.TRAIL_LENGTH] for o in P.TRAIL_PROBES]
    for cand in candidates:
        w = np.where(todo)[0]
        cx, cy = cand[0, w], cand[1, w]
        dx, dy = cx - mx[w], cy - my[w]
        ok = (dx * dx + dy * dy < np.float32(P.PERCEPTION_RANGE ** 2)) & grid.line_of_sight(mx[w], my[w], cx, cy)
        hit = w[ok]
        memory[0, sub[hit]] = cx[ok]
        memory[1, sub[hit]] = cy[ok]
        todo[hit] = False
    return memory


@pytest.fixture
def groups_round_a_wall():
    """Twelve groups of 6 (a leader each) walking across a wall with three gaps, after 6 s."""
    rng = np.random.default_rng(9)
    start = np.stack([rng.uniform(-18.0, -4.0, 72), rng.uniform(-15.0, 15.0, 72)], axis=1)
    first = np.arange(0, 72, 6)
    start[first + 3] = start[first] + [14.0, 0.0]          # some members on the far side of the wall
    leader = np.repeat(first, 6)
    leader[first] = -1
    at = S.agents(start, group=np.arange(72) // 6, leader=leader,
                  role=["leader" if i % 6 == 0 else "member" for i in range(72)])
    walls = [S.box(0.0, -12.0, 0.3, 6.0), S.box(0.0, 1.0, 0.3, 5.0), S.box(0.0, 13.0, 0.3, 4.0)]
    sim = Simulation(S.scenario(at, S.groups([[15.0, 0.0, 0.0]] * 12, leaders=list(first)), obstacles=walls),
                     SimSettings())
    for _ in range(6 * 48):
        sim.step()
    return sim


def test_members_remember_their_leader_as_the_probe_by_probe_search_did(groups_round_a_wall):
    sim = groups_round_a_wall
    g = sim.groups
    for step in range(sim.steps, sim.steps + P.LOS_EVERY):
        want = _reference_memory(g, step, sim.pos, sim.grid)
        before = g.memory.copy()
        g.update_memory(step, sim.pos, sim.grid)
        np.testing.assert_array_equal(g.memory, want)
    # Some members see their leader, others (behind the wall) one of its breadcrumbs.
    at_leader = (g.memory == sim.pos[:, g.leader_of]).all(axis=0)
    on_trail = (g.memory[:, :, None] == g.trail[:, g.slot, :]).all(axis=0).any(axis=1) & ~at_leader
    assert at_leader.sum() > 20 and on_trail.sum() > 3, (at_leader.sum(), on_trail.sum())
    assert (g.memory != before).any()


@pytest.mark.parametrize("spread", [12.0, 400.0, 1.0e5], ids=["packed", "sparse", "far-flung"])
def test_the_neighbour_table_holds_the_k_nearest_within_reach(spread):
    """Against all pairs: the distances of each agent's neighbours are the k smallest within reach, nearest
    first (ties may name either agent); pinned bodies, far-flung crowds and coincident pairs included."""
    rng = np.random.default_rng(13)
    n = 700
    pos = np.empty((2, n + 1), np.float32)
    pos[:, :n] = rng.uniform(-spread / 2, spread / 2, (2, n))
    pos[:, 10:14] = pos[:, 20:24]
    pos[:, n] = P.GHOST_POSITION
    members = np.setdiff1d(np.arange(n), np.arange(0, n, 50))       # some take no part
    nl = NeighborList(n, members)
    nl.update(pos)
    p = pos[:, members].T.astype(np.float64)
    d2 = ((p[:, None] - p[None]) ** 2).sum(-1)
    np.fill_diagonal(d2, np.inf)
    reach2 = (nl.radius + nl.skin) ** 2
    row = {a: i for i, a in enumerate(members)}
    found = 0
    for a in members:
        want = np.sort(d2[row[a]])[:nl.k]
        want = want[want <= reach2]
        got = [b for b in nl.idx[a] if b != n]
        assert all(b in row for b in got)
        np.testing.assert_array_equal([d2[row[a], row[b]] for b in got], want)
        found += len(got)
    assert (nl.idx[np.arange(0, n, 50)] == n).all()
    assert found > {12.0: 4000, 400.0: 100, 1.0e5: 4}[spread]     # far-flung: the coincident pairs


def test_the_neighbour_table_is_built_again_once_someone_moved_half_the_skin():
    """Kept while every member stays under half the skin from where the table was built (others may go
    anywhere), built again when one reaches it or the table reaches its age."""
    rng = np.random.default_rng(3)
    n = 300
    pos = np.empty((2, n + 1), np.float32)
    pos[:, :n] = rng.uniform(-20.0, 20.0, (2, n))
    pos[:, n] = P.GHOST_POSITION
    members = np.arange(1, n)                                          # agent 0 takes no part
    nl = NeighborList(n, members, max_age=1000)
    assert nl.update(pos) and nl.rebuilds == 1
    half = np.float32(0.5 * nl.skin)
    moved = pos.copy()
    moved[0, 1:n] += np.float32(0.95) * half                          # everyone under half the skin
    moved[:, 0] += np.float32(50.0)
    assert not nl.update(moved) and nl.rebuilds == 1
    moved[:, 77] = pos[:, 77] + np.array([0.0, 1.02 * half], np.float32)  # one of them just over it
    assert nl.update(moved) and nl.rebuilds == 2
    aged = NeighborList(n, members, max_age=3)
    assert [aged.update(pos) for _ in range(7)] == [True, False, False, True, False, False, True]


def test_leaders_wait_for_their_group_as_the_bincount_said(groups_round_a_wall):
    sim = groups_round_a_wall
    g = sim.groups
    d = sim.pos[:, g.followers] - sim.pos[:, g.leader_of]
    spread = np.bincount(g.slot, weights=np.sqrt(d[0] * d[0] + d[1] * d[1]), minlength=len(g.leaders))
    np.testing.assert_array_equal(K.group_spread(sim.pos, g.followers, g.leader_of, g.slot, len(g.leaders)),
                                  spread)
    pace = g.leader_pace(sim.pos)
    assert (pace < 1.0).any() and (pace == 1.0).any()            # some leaders wait, some need not


def test_on_one_thread_or_spread_over_the_cores_the_loops_give_the_same_bytes(packed_crowd, pillars_among_the_crowd):
    pos, vel, radius, idx, mates = packed_crowd
    grid = pillars_among_the_crowd
    n = idx.shape[0]
    v_des = np.random.default_rng(1).normal(0.0, 1.0, (2, n)).astype(np.float32)
    lo, hi = np.array([-5.0, -5.0], np.float32), np.array([5.0, 5.0], np.float32)
    gain = np.full(n, 1.0 / P.TAU_RELAX, np.float32)
    args = (pos, vel, v_des, gain, radius, idx, mates, True, *grid.lookup, grid.flat_sdf, grid.flat_nx, grid.flat_ny,
            *grid.exact, lo, hi)
    np.testing.assert_array_equal(K.forces.serial(*args), K.forces.parallel(*args))
    x, y = pos[0, :n].astype(np.float64), pos[1, :n].astype(np.float64)
    np.testing.assert_array_equal(K.nearest_within.serial(x, y, 8, 4.6), K.nearest_within.parallel(x, y, 8, 4.6))
    a, b = pos.copy(), pos.copy()
    K.push_out_of_walls.serial(a, radius, 2, np.float32(0.6), grid.polygons, *grid.lookup, grid.flat_sdf,
                               grid.flat_nx, grid.flat_ny, grid.flat_label)
    K.push_out_of_walls.parallel(b, radius, 2, np.float32(0.6), grid.polygons, *grid.lookup, grid.flat_sdf,
                                 grid.flat_nx, grid.flat_ny, grid.flat_label)
    assert not np.array_equal(a, pos)
    np.testing.assert_array_equal(a, b)


def test_a_process_forked_after_the_loops_ran_on_threads_still_steps_its_crowd():
    """GNU OpenMP cannot start threads in a child forked from a process that used it (numba would end the
    child): there the loops run on one thread, with the same result."""
    import multiprocessing as mp

    sc = S.room_with_pillars(n=120, seed=4)
    sim = Simulation(sc, SimSettings())
    assert sim.n >= K.PARALLEL_MIN
    for _ in range(5):
        sim.step()                                        # on threads, in this process
    ctx = mp.get_context("fork")
    queue = ctx.Queue()

    def child():
        for _ in range(20):
            sim.step()
        queue.put(sim.pos.tobytes())

    proc = ctx.Process(target=child)
    proc.start()
    proc.join(120)
    assert proc.exitcode == 0
    for _ in range(20):
        sim.step()
    assert queue.get(timeout=5) == sim.pos.tobytes()


def test_the_steps_bookkeeping_loops_give_the_numpy_forms_bits():
    """Top speeds, wounded pace, the bounds clip, followers' intent and blended reactions: one loop each
    where the step had chains of numpy calls (their cost, not their work, dominated a small crowd's
    step); each gives the former code's bits."""
    from usdcrowd.core.model import BEHAVIORS, HEALTH_STATES, code

    rng = np.random.default_rng(11)
    n = 500
    run, rest, walk = (np.int8(code(BEHAVIORS, b)) for b in ("run", "rest", "walk"))
    dead, wounded = np.int8(code(HEALTH_STATES, "dead")), np.int8(code(HEALTH_STATES, "wounded"))
    behavior = rng.choice([run, rest, walk], n).astype(np.int8)
    health = rng.choice([np.int8(0), wounded, dead], n, p=[0.6, 0.2, 0.2]).astype(np.int8)
    pref = rng.uniform(0.5, 2.0, n).astype(np.float32)
    cap = np.where(rng.random(n) < 0.3, 1.2, np.inf).astype(np.float32)
    want = np.where(behavior == run, pref * (P.PANIC_SPEED_FACTOR * 1.1), pref * P.MAX_SPEED_FACTOR)
    want = np.minimum(np.where(behavior == rest, np.minimum(want, P.REST_SPEED_MAX), want), cap)
    want[health == dead] = 0.0
    got = K.speed_limits(behavior, pref, cap, health, run, rest, dead, np.float32(P.PANIC_SPEED_FACTOR * 1.1),
                         np.float32(P.MAX_SPEED_FACTOR), np.float32(P.REST_SPEED_MAX), np.empty(n, np.float32))
    np.testing.assert_array_equal(got, want)
    assert len(set(np.round(got / pref, 3))) > 4          # every branch taken
    np.testing.assert_array_equal(K.preferred_speeds(pref, health, wounded, np.float32(P.WOUNDED_SPEED_FACTOR)),
                                  np.where(health == wounded, pref * P.WOUNDED_SPEED_FACTOR, pref))

    pos = rng.uniform(-12.0, 12.0, (2, n + 1)).astype(np.float32)
    radius = rng.uniform(0.2, 0.3, n).astype(np.float32)
    lo, hi = np.array([-10.0, -8.0], np.float32), np.array([10.0, 9.0], np.float32)
    want = pos.copy()
    for c in (0, 1):
        want[c, :n] = np.minimum(np.maximum(pos[c, :n], lo[c] + radius), hi[c] - radius)
    K.clip_to_bounds(pos, radius, lo, hi)
    np.testing.assert_array_equal(pos, want)

    rows = rng.choice(n, 200, replace=False)
    weight = rng.choice([0.0, 0.3, 0.7, 1.0], n).astype(np.float32)
    v = rng.normal(0.0, 1.0, (2, n)).astype(np.float32)
    for v_rows in (rng.normal(0.0, 2.0, (2, 200)).astype(np.float32), rng.normal(0.0, 2.0, (2, 200))):
        beh_rows = rng.choice([run, rest], 200).astype(np.int8)
        want_v, want_b = v.copy(), behavior.copy()
        w = weight[rows]
        want_v[:, rows] = want_v[:, rows] * (1.0 - w) + v_rows * w
        want_b[rows[w > 0.5]] = beh_rows[w > 0.5]
        got_v, got_b = v.copy(), behavior.copy()
        K.blend_rows(got_v, got_b, rows, weight, v_rows, beh_rows)
        np.testing.assert_array_equal(got_v, want_v)
        np.testing.assert_array_equal(got_b, want_b)

    followers = rng.choice(n, 300, replace=False)
    leader_of = rng.integers(0, n, 300)
    memory = (pos[:, followers] + rng.normal(0.0, 2.0, (2, 300))).astype(np.float32)
    stop = rng.uniform(0.0, 1.5, 300).astype(np.float32)
    want_v, want_b = v.copy(), behavior.copy()
    want_v[:, followers] = arrive(pos[:, followers], memory, pref[followers] * np.float32(P.FOLLOW_SPEED_FACTOR),
                                  slow_radius=P.FOLLOW_SLOW_RADIUS, stop_radius=stop)[0]
    was = rng.choice([run, walk], n).astype(np.int8)
    want_b[followers] = np.where(was[leader_of] == run, run, want_b[followers])
    got_v, got_b = v.copy(), behavior.copy()
    K.follow_leaders(pos, followers, memory, pref, np.float32(P.FOLLOW_SPEED_FACTOR),
                     np.float32(P.FOLLOW_SLOW_RADIUS), stop, leader_of, was, run, got_v, got_b)
    np.testing.assert_array_equal(got_v, want_v)
    np.testing.assert_array_equal(got_b, want_b)
