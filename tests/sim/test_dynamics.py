"""Dynamics of usdcrowd.sim: shapes, determinism, collisions, walls, leaders, errors."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.spatial import cKDTree

import tests.helpers.scenarios as S
from usdcrowd.core.model import ANIM_CLASSES, PATH_METHODS, CrowdFrames
from usdcrowd.sim import SimSettings, Simulation, simulate, simulate_chunks
from usdcrowd.sim import params as P
from usdcrowd.sim.collision import wall_avoidance
from usdcrowd.sim.grid import WalkGrid, polygon_signed_distance, polygon_table
from usdcrowd.sim.groups import Groups

try:
    from usdcrowd.core.errors import ScenarioError as Err
except ImportError:  # pragma: no cover
    Err = ValueError

R = P.AGENT_RADIUS[0]  # humans
PENETRATION_MAX = 0.05  # m, how deep a body may enter an obstacle
OVERLAP_MAX = 0.05  # m, deepest body-body overlap once the start has been resolved (1 s)
FOLLOW_MAX = 6.0  # m, farthest a member may be from its leader (group of 8, after 2 s)


def max_overlap(frames: CrowdFrames, first: int = 0) -> float:
    worst = 0.0
    for t in range(first, len(frames.times)):
        p = frames.position[t, :, :2]
        pairs = cKDTree(p).query_pairs(2 * R, output_type="ndarray")
        if len(pairs):
            d = np.linalg.norm(p[pairs[:, 0]] - p[pairs[:, 1]], axis=1)
            worst = max(worst, float((2 * R - d).max()))
    return worst


def max_penetration(frames: CrowdFrames, scenario) -> float:
    p = frames.position[:, :, :2].reshape(-1, 2).astype(np.float64)
    worst = -np.inf
    for poly in polygon_table(scenario.obstacles):
        sd, _, _ = polygon_signed_distance(p, np.broadcast_to(poly, (len(p),) + poly.shape))
        worst = max(worst, float((R - sd).max()))
    return worst


def test_shapes_dtypes_and_no_nan():
    sc = S.crossing(n_per_side=10, frames=30)
    fr = simulate(sc)
    t, n = 30, 20
    assert fr.position.shape == (t, n, 3) and fr.position.dtype == np.float32
    assert fr.heading.shape == (t, n) and fr.velocity.shape == (t, n, 2)
    assert fr.behavior.dtype == fr.anim_class.dtype == fr.health.dtype == np.int8
    assert fr.anim_phase.dtype == np.float32 and fr.look_at.shape == (t, n, 3)
    assert fr.path_method.shape == (n,)
    np.testing.assert_array_equal(fr.times, sc.time.codes)
    for a in (fr.position, fr.heading, fr.velocity, fr.anim_phase):
        assert np.all(np.isfinite(a))
    assert np.all((fr.anim_phase >= 0) & (fr.anim_phase < 1))
    assert fr.anim_class.max() < len(ANIM_CLASSES) and fr.path_method.max() < len(PATH_METHODS)
    # Frame 0 is the authored start.
    np.testing.assert_allclose(fr.position[0, :, :2], sc.agents.start[:, :2], atol=1e-5)
    # Nobody attends to anything in a plain crossing.
    assert np.all(np.isnan(fr.look_at))


def test_same_seed_same_arrays_and_chunks_match():
    sc = S.room_with_pillars(n=12, frames=40)
    a = simulate(sc, SimSettings(chunk_frames=7))
    b = simulate(sc, SimSettings(chunk_frames=40))
    chunks = list(simulate_chunks(sc, SimSettings(chunk_frames=16)))
    assert [len(c.times) for c in chunks] == [16, 16, 8]
    for f in dataclasses.fields(CrowdFrames):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if f.name == "anim_phase":  # continued across chunks from a float32 phase
            np.testing.assert_allclose(x, y, atol=1e-6)
        else:
            np.testing.assert_array_equal(x, y, err_msg=f.name)
    np.testing.assert_array_equal(np.concatenate([c.position for c in chunks]), a.position)


def test_seed_changes_wandering():
    at = S.agents(np.random.default_rng(0).uniform(-5, 5, (10, 2)), behavior="wander", condition="isolated")
    sc = S.scenario(at, S.groups([[np.nan, np.nan, np.nan]]), frames=48)
    a = simulate(sc, SimSettings(seed=1))
    b = simulate(sc, SimSettings(seed=2))
    c = simulate(sc, SimSettings(seed=1))
    np.testing.assert_array_equal(a.position, c.position)
    assert not np.array_equal(a.position, b.position)


def test_no_wall_penetration():
    sc = S.room_with_pillars(n=30, frames=360)
    fr = simulate(sc)
    assert max_penetration(fr, sc) < PENETRATION_MAX
    # ...and they got past the wall through its gap.
    assert np.median(fr.position[-1, :, 0]) > -4.0


def test_overlaps_bounded_in_counterflow():
    fr = simulate(S.crossing(n_per_side=20, frames=288))
    assert max_overlap(fr, first=24) < OVERLAP_MAX
    # The two groups went through each other (most crossed the middle).
    x0 = fr.position[0, :, 0]
    x1 = fr.position[-1, :, 0]
    assert np.mean(np.sign(x0) != np.sign(x1)) > 0.7


def test_same_direction_walkers_may_stay_close():
    # Two people side by side, 0.6 m apart (a 0.1 m gap), walking the same way:
    # time-to-impact avoidance leaves them alone.
    at = S.agents([[-10, 0.0], [-10, 0.6]], group=[0, 1], condition="isolated", speed=1.3)
    sc = S.scenario(at, S.groups([[10, 0.0, 0], [10, 0.6, 0]]), frames=96)
    fr = simulate(sc)
    d = np.linalg.norm(fr.position[:, 0, :2] - fr.position[:, 1, :2], axis=1)
    assert d.max() < 0.75


def test_head_on_pair_swerves_in_advance():
    at = S.agents([[-8, 0.0], [8, 0.0]], group=[0, 1], condition="isolated", heading=[0, np.pi])
    sc = S.scenario(at, S.groups([[12, 0, 0], [-12, 0, 0]]), frames=360)
    fr = simulate(sc)
    d = np.linalg.norm(fr.position[:, 0, :2] - fr.position[:, 1, :2], axis=1)
    assert d.min() > 2 * R  # never touched
    assert np.abs(fr.position[:, :, 1]).max() > 0.2  # side-stepped
    assert fr.position[-1, 0, 0] > 8 and fr.position[-1, 1, 0] < -8  # and passed


def test_walls_repel_only_agents_walking_toward_them():
    sc = S.scenario(S.agents([[0, 0]]), S.groups([[1, 0, 0]]), obstacles=[S.box(0, 0, 1, 1)])
    g = WalkGrid(sc)
    pos = np.array([[1.8, 1.8, 1.8], [0.0, 0.0, 0.0]], np.float32)  # 0.8 m right of the box
    vel = np.array([[-1.3, 1.3, 0.0], [0.0, 0.0, 1.3]], np.float32)  # toward / away / along
    f = wall_avoidance(g, pos, vel, np.full(3, R, np.float32))
    assert f[0, 0] > 0.5  # pushed back (+x)
    assert abs(f[0, 1]) < 1e-6 and abs(f[0, 2]) < 1e-6


def test_clearance_is_each_walls_own_distance_not_its_cells():
    """Walls falling between cell centres stand where they are: across a 1.2 m door the clearance is the
    distance to the nearer wall (to within a centimetre where it is linear between cell centres; never
    more than it on the door's axis, where it bends)."""
    door = [S.box(0.0, 2.6, 2.0, 2.0), S.box(0.0, -2.6, 2.0, 2.0)]        # walls at y = +-0.6
    g = WalkGrid(S.scenario(S.agents([[-5, 0]]), S.groups([[5, 0, 0]]), obstacles=door))
    y = np.linspace(-0.58, 0.58, 59)
    sdf, _, _ = g.clearance(np.full_like(y, 0.3), y)
    want = 0.6 - np.abs(y)
    away = np.abs(y) >= 0.5 * g.cell
    np.testing.assert_allclose(sdf[away], want[away], atol=0.01)
    assert (sdf <= want + 0.01).all()
    # Farther than the exact band, the distance transform's clearance is within a cell of the truth.
    far, _, _ = g.clearance(np.array([-8.0]), np.array([0.0]))
    assert abs(float(far[0]) - 6.0) < g.cell


def test_followers_stay_near_leader_around_a_wall():
    sc = S.led_group(frames=480)
    fr = simulate(sc)
    d = np.linalg.norm(fr.position[:, 1:, :2] - fr.position[:, :1, :2], axis=2)
    assert d[48:].max() < FOLLOW_MAX
    assert max_penetration(fr, sc) < PENETRATION_MAX
    # The leader went around the wall (x = 0) toward the goal.
    assert fr.position[-1, 0, 0] > 1.0


def test_follower_memory_is_last_visible_leader_position():
    # A leader walks behind a wall; the member keeps the last breadcrumb it can see.
    at = S.agents([[0.0, 3.0], [-6.0, -3.0]], leader=[-1, 0], role=["invisibleLeader", "member"])
    sc = S.scenario(at, S.groups([[10, 10, 0]], leaders=[0]), obstacles=[S.box(0, 0, 4.0, 0.3)])
    g = WalkGrid(sc)
    pos = np.full((2, 3), P.GHOST_POSITION, np.float32)
    pos[:, :2] = sc.agents.start[:, :2].T
    groups = Groups(sc.agents, sc.groups, pos)
    # Leader walks from (-5.5, 3) over to (5, 3): the sight line from (-6, -3)
    # clears the wall's end (x = -4) only while the leader's x < -2.
    for step, x in enumerate(np.linspace(-5.5, 5.0, 30)):
        pos[0, 0] = x
        groups.record_trail(step * P.TRAIL_INTERVAL, pos)
        for k in range(P.LOS_EVERY):
            groups.update_memory(step * P.LOS_EVERY + k, pos, g)
    mem = groups.memory[:, 0]
    # Not the current position behind the wall, but the newest visible breadcrumb
    # (breadcrumbs are 0.36 m apart; probes reach back 1, 2, 4... of them).
    assert -3.2 < mem[0] < -2.0
    assert g.line_of_sight(np.array([-6.0]), np.array([-3.0]), mem[:1], mem[1:])[0]


def test_heading_turns_smoothly():
    at = S.agents([[0, 0]], heading=np.pi)  # facing away from the goal
    sc = S.scenario(at, S.groups([[10, 0, 0]]), frames=48)
    fr = simulate(sc)
    dh = np.abs(np.angle(np.exp(1j * np.diff(fr.heading[:, 0].astype(np.float64)))))
    assert dh.max() <= P.TURN_RATE[0] / sc.time.fps + 1e-4
    assert abs(fr.heading[-1, 0]) < 0.2  # ends facing the goal


def test_speed_and_force_limits():
    fr = simulate(S.crossing(n_per_side=10, frames=96))
    speed = np.linalg.norm(fr.velocity, axis=2)
    assert speed.max() <= 1.3 * P.PANIC_SPEED_FACTOR * 1.1 + 1e-3
    idle = fr.anim_class[0] == ANIM_CLASSES.index("idle")  # standing at the start
    assert idle.all()


@pytest.mark.parametrize("mutate, words", [
    (lambda sc: sc.agents.speed.__setitem__(0, -1.0), "speed"),
    (lambda sc: setattr(sc, "groups", S.groups([[0, 0, 0], [1, 1, 0], [2, 2, 0]])), "no agents"),
    (lambda sc: setattr(sc.agents, "start", sc.agents.start * np.nan), "finite"),
])
def test_bad_values_raise_clear_errors(mutate, words):
    sc = S.crossing(n_per_side=2, frames=5)
    mutate(sc)
    with pytest.raises(Err, match=words):
        Simulation(sc)


def test_no_agents_is_an_error():
    sc = S.crossing(n_per_side=2, frames=5)
    sc.agents = S.agents(np.zeros((0, 2)))
    sc.groups = S.groups(np.zeros((0, 3)))
    with pytest.raises(Err, match="no agents"):
        simulate(sc)


def test_animation_classes_and_phase_follow_motion():
    at = S.agents([[0, 0], [0, 5]], group=[0, 1], behavior=["walk", "rest"], condition="isolated")
    sc = S.scenario(at, S.groups([[15, 0, 0], [np.nan, np.nan, np.nan]]), frames=96)
    sim = Simulation(sc)
    fr = simulate(sc)
    walk, idle = ANIM_CLASSES.index("walk"), ANIM_CLASSES.index("idle")
    assert np.all(fr.anim_class[48:, 0] == walk) and np.all(fr.anim_class[:, 1] == idle)
    # The walker's cycle advances by speed over stride length every frame.
    dphase = np.mod(np.diff(fr.anim_phase[48:, 0].astype(np.float64)), 1.0)
    assert np.all(dphase > 0.02) and np.all(dphase < 0.1)
    try:  # the character package's classifier is used when it exists
        from usdcrowd.character import animation
        assert sim._anim is animation
    except ImportError:  # pragma: no cover
        pass
