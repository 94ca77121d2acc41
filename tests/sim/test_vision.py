"""Walking by sight (Moussaïd, Helbing & Theraulaz 2011): the direction with the clearest view toward the
goal, and a speed that keeps a time gap to the first person ahead."""

from __future__ import annotations

import numpy as np

from tests.helpers import scenarios as S
from usdcrowd.sim import SimSettings, Simulation
from usdcrowd.sim import params as P
from usdcrowd.sim.vision import heuristic_velocity

RADIUS = 0.25


def _sight(others, others_vel=None, v0=1.3, in_line=False, **kw):
    """The desired velocity of a walker at the origin heading +X with people at ``others`` (k, 2); with
    ``in_line`` also whether it stands in line behind the first of them."""
    others = np.asarray(others, np.float64).reshape(-1, 2)
    k = len(others)
    pos = np.concatenate([[[0.0, 0.0]], others]).T.astype(np.float32)
    vel = np.zeros_like(pos) if others_vel is None else np.concatenate([[[v0, 0.0]], others_vel]).T.astype(
        np.float32)
    idx = np.arange(1, k + 1)[None, :]
    v, _, follows = heuristic_velocity(pos, vel, np.array([[1.0], [0.0]]), np.array([v0]), idx,
                                       np.full(k + 1, RADIUS), np.array([0]), **kw)
    return (v[:, 0], bool(follows[0])) if in_line else v[:, 0]


def test_a_walker_slows_to_keep_its_time_gap_to_the_person_ahead():
    """Looking straight ahead only: a person standing 1 m ahead leaves 0.5 m between the bodies, so the
    walker wants 0.5 m / tau; 3 m ahead (2.5 m free) it walks at its own speed."""
    v = _sight([[1.0, 0.0]], fov_deg=0.0, directions=1)
    np.testing.assert_allclose(v, [0.5 / P.VISION_TAU, 0.0], rtol=1e-5)
    np.testing.assert_allclose(_sight([[3.0, 0.0]], fov_deg=0.0, directions=1), [1.3, 0.0], rtol=1e-5)


def test_a_walker_waiting_its_turn_closes_up_on_the_one_ahead_but_not_on_someone_coming_toward_it():
    """Queued, the same walker keeps QUEUE_TAU instead of VISION_TAU to a person standing 1 m ahead
    (0.5 m between the bodies); it stands in line behind someone standing or walking on, not behind
    someone coming toward it, nor where a neighbour walks against its way faster than COUNTERFLOW_SPEED."""
    ahead = dict(fov_deg=0.0, directions=1)
    v, in_line = _sight([[1.0, 0.0]], in_line=True, queued=[True], **ahead)
    assert in_line
    np.testing.assert_allclose(v, [min(1.3, 0.5 / P.QUEUE_TAU), 0.0], rtol=1e-5)
    v, _ = _sight([[1.0, 0.0]], in_line=True, queued=[False], **ahead)
    np.testing.assert_allclose(v, [0.5 / P.VISION_TAU, 0.0], rtol=1e-5)
    # Coming toward it: the time gap stays VISION_TAU however long it waited.
    v, in_line = _sight([[1.0, 0.0]], others_vel=[[-0.2, 0.0]], in_line=True, queued=[True], **ahead)
    assert not in_line
    np.testing.assert_allclose(v, [0.5 / P.VISION_TAU, 0.0], rtol=1e-5)
    # Behind someone walking on, beside someone walking the other way: a standoff, not a queue.
    slow = P.COUNTERFLOW_SPEED
    _, in_line = _sight([[1.0, 0.0], [0.0, 1.0]], others_vel=[[0.2, 0.0], [-0.9 * slow, 0.0]], in_line=True,
                        **ahead)
    assert in_line
    _, in_line = _sight([[1.0, 0.0], [0.0, 1.0]], others_vel=[[0.2, 0.0], [-1.1 * slow, 0.0]], in_line=True,
                        **ahead)
    assert not in_line
    # Nobody that way: nothing to stand in line behind.
    assert not _sight([[0.0, 2.0]], in_line=True, **ahead)[1]


def test_a_walker_turns_just_enough_to_pass_someone_standing_in_its_way():
    """Someone 2 m ahead blocks the straight line (bodies 0.5 m wide together): the walker takes the
    direction nearest its goal whose line clears them, asin(0.5 / 2) = 14.5 degrees rounded up to the
    15-degree steps tried, at full speed."""
    v = _sight([[2.0, 0.0]])
    angle = np.degrees(np.arctan2(v[1], v[0]))
    assert abs(abs(angle) - 15.0) < 1e-3, angle
    np.testing.assert_allclose(np.hypot(*v), 1.3, rtol=1e-5)


def test_a_walker_keeps_on_behind_someone_walking_its_way_at_its_pace():
    """The same person 2 m ahead walking +X at 1.3 m/s: never in the way, so straight on at full speed."""
    v = _sight([[2.0, 0.0]], others_vel=[[1.3, 0.0]])
    np.testing.assert_allclose(v, [1.3, 0.0], atol=1e-5)


def _two_walkers(y_walls=None, seconds=12.0):
    """A slow walker (0.7 m/s) 2 m ahead of a fast one (1.5 m/s), both heading +X; optionally between
    walls at +-y_walls. Returns (t, 2, 2) positions."""
    obstacles = [] if y_walls is None else [S.box(0.0, y_walls + 0.5, 40.0, 0.5), S.box(0.0, -y_walls - 0.5, 40.0, 0.5)]
    a = S.agents([[2.0, 0.0], [0.0, 0.0]], group=[0, 1], speed=[0.7, 1.5], condition="isolated")
    g = S.groups([[30.0, 0.0, 0.0], [30.0, 0.0, 0.0]])
    frames = int(seconds * 24)
    sc = S.scenario(a, g, obstacles=obstacles, bounds=((-5, -5), (35, 5)), frames=frames)
    return Simulation(sc, SimSettings()).frames(frames, 1.0).position[:, :, :2].astype(np.float64)


def test_a_fast_walker_overtakes_a_slow_one_where_there_is_room_and_follows_where_there_is_not():
    """In the open the fast walker goes round the slow one and is ahead after 12 s. In a corridor 1 m wide
    (room for one, not two) it stays behind at the slow one's pace, never touching, the space between them
    what the slow pace covers in the time gap tau."""
    open_ = _two_walkers()
    assert open_[-1, 1, 0] > open_[-1, 0, 0] + 2.0, open_[-1]
    narrow = _two_walkers(y_walls=0.5)
    assert (narrow[:, 1, 0] < narrow[:, 0, 0]).all()
    gap = np.linalg.norm(narrow[:, 0] - narrow[:, 1], axis=1) - 2 * RADIUS
    assert gap.min() > -0.01, gap.min()
    late = slice(len(narrow) // 2, None)
    pace = np.diff(narrow[late, 1, 0]).mean() * 24
    assert abs(pace - 0.7) < 0.05, pace
    assert abs(gap[late].mean() - 0.7 * P.VISION_TAU) < 0.05, gap[late].mean()



def _through_a_door(seconds=60.0, n=60):
    """Sixty people packed in a 5 m x 6 m room leave through a passage 1.0 m wide and 2 m long for a
    goal beyond: the times (s) at which each has passed its middle, sorted (inf: not yet), and the
    bodies' deepest overlap (m)."""
    rng = np.random.default_rng(4)
    cols, rows = np.meshgrid(np.arange(10), np.arange(6))
    start = np.column_stack([-5.3 + 0.5 * cols.ravel(), -2.6 + 0.95 * rows.ravel()]) + rng.uniform(-0.05, 0.05, (n, 2))
    walls = [S.box(1.0, 1.8, 1.0, 1.3), S.box(1.0, -1.8, 1.0, 1.3), S.box(-2.75, 3.2, 2.75, 0.2),
             S.box(-2.75, -3.2, 2.75, 0.2), S.box(-5.7, 0.0, 0.2, 3.4)]
    a = S.agents(start, group=np.arange(n), speed=rng.uniform(1.1, 1.5, n), condition="isolated")
    g = S.groups(np.tile([[9.0, 0.0, 0.0]], (n, 1)))
    frames = int(seconds * 24)
    sc = S.scenario(a, g, obstacles=walls, bounds=((-6, -4), (11, 4)), frames=frames)
    xy = Simulation(sc, SimSettings()).frames(frames, 1.0).position[:, :, :2].astype(np.float64)
    passed = np.where((xy[..., 0] > 1.0).any(axis=0), np.argmax(xy[..., 0] > 1.0, axis=0) / 24.0, np.inf)
    d = np.linalg.norm(xy[:, :, None] - xy[:, None], axis=-1) + np.eye(n) * 9.0
    return np.sort(passed), float(2 * RADIUS - d.min())


def test_people_waiting_their_turn_at_a_door_close_up_and_pass_it_sooner(monkeypatch):
    """Held up behind one another at a narrow door, people close up (QUEUE_TAU) and so pass it sooner
    than if they kept VISION_TAU to the one ahead, without their bodies going into each other."""
    queued, overlap = _through_a_door()
    monkeypatch.setattr(P, "QUEUE_TAU", P.VISION_TAU)
    spaced, _ = _through_a_door()
    assert np.isfinite(queued[:36]).all() and np.isfinite(spaced[:36]).all()
    first, last = queued[[5, 35]], spaced[[5, 35]]
    assert (last[1] - last[0]) > 1.25 * (first[1] - first[0]), (first, last)   # measured 1.34
    assert overlap < 0.02, overlap


def test_a_walker_held_up_by_someone_takes_up_the_space_in_SIGHT_RELAX_a_free_one_in_TAU_RELAX():
    """A walker whose way is blocked (someone standing in a 1 m corridor before it) relaxes toward its
    desired velocity with SIGHT_RELAX; one walking free, from standstill toward a goal 30 m off, with
    TAU_RELAX: it is at 1 - 1/e of its speed after TAU_RELAX seconds."""
    a = S.agents([[0.0, 0.0], [0.9, 0.0], [0.0, 10.0]], group=[0, 1, 2], speed=1.3, condition="isolated",
                 behavior=["walk", "rest", "walk"])
    walls = [S.box(15.0, 1.0, 20.0, 0.5), S.box(15.0, -1.0, 20.0, 0.5)]       # a corridor 1 m wide at y = 0
    sc = S.scenario(a, S.groups([[30.0, 0.0, 0.0], [0.9, 0.0, 0.0], [30.0, 10.0, 0.0]]), obstacles=walls,
                    bounds=((-5, -5), (35, 15)))
    sim = Simulation(sc, SimSettings(fps=100.0, substeps=1))
    speeds = []
    for _ in range(int(round(P.TAU_RELAX * 100))):
        sim.step()
        speeds.append(np.hypot(*sim.vel[:, 2]))
    np.testing.assert_allclose(speeds[-1], 1.3 * (1 - np.exp(-1)), rtol=0.05)
    assert sim.steer[0] == np.float32(1 / P.SIGHT_RELAX) and sim.steer[2] == np.float32(1 / P.TAU_RELAX)
    assert sim.pos[0, 0] < 0.5                                       # still held behind the one standing


def test_a_walker_in_a_door_steps_beside_a_person_standing_in_it():
    """A 1.2 m door leaves room to pass a standing person at its side: the walker takes it at nearly its
    own speed. (With the walls placed on the grid's cells the door was 1.0 m wide and it waited.)"""
    from usdcrowd.sim.grid import WalkGrid

    door = [S.box(0.0, 2.6, 2.0, 2.0), S.box(0.0, -2.6, 2.0, 2.0)]        # walls at y = +-0.6
    grid = WalkGrid(S.scenario(S.agents([[-5.0, 0.0]]), S.groups([[5.0, 0.0, 0.0]]), obstacles=door))
    pos = np.array([[-1.5, 0.15], [-0.7, -0.15]], np.float32).T.copy()    # 0.8 m ahead, a little aside
    v, _, _ = heuristic_velocity(pos, np.zeros_like(pos), np.array([[1.0], [0.0]]), np.array([1.3]),
                                 np.array([[1]]), np.full(2, RADIUS, np.float32), np.array([0]), grid=grid)
    assert np.hypot(*v[:, 0]) > 1.2 and v[1, 0] > 0.2, v[:, 0]
