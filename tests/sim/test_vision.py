"""Walking by sight (Moussaïd, Helbing & Theraulaz 2011): the direction with the clearest view toward the
goal, and a speed that keeps a time gap to the first person ahead."""

from __future__ import annotations

import numpy as np

from tests.helpers import scenarios as S
from usdcrowd.sim import SimSettings, Simulation
from usdcrowd.sim import params as P
from usdcrowd.sim.vision import heuristic_velocity

RADIUS = 0.25


def _sight(others, others_vel=None, v0=1.3, **kw):
    """The desired velocity of a walker at the origin heading +X with people at ``others`` (k, 2)."""
    others = np.asarray(others, np.float64).reshape(-1, 2)
    k = len(others)
    pos = np.concatenate([[[0.0, 0.0]], others]).T.astype(np.float32)
    vel = np.zeros_like(pos) if others_vel is None else np.concatenate([[[v0, 0.0]], others_vel]).T.astype(
        np.float32)
    idx = np.arange(1, k + 1)[None, :]
    v, _ = heuristic_velocity(pos, vel, np.array([[1.0], [0.0]]), np.array([v0]), idx,
                              np.full(k + 1, RADIUS), np.array([0]), **kw)
    return v[:, 0]


def test_a_walker_slows_to_keep_its_time_gap_to_the_person_ahead():
    """Looking straight ahead only: a person standing 1 m ahead leaves 0.5 m between the bodies, so the
    walker wants 0.5 m / tau; 3 m ahead (2.5 m free) it walks at its own speed."""
    v = _sight([[1.0, 0.0]], fov_deg=0.0, directions=1)
    np.testing.assert_allclose(v, [0.5 / P.VISION_TAU, 0.0], rtol=1e-5)
    np.testing.assert_allclose(_sight([[3.0, 0.0]], fov_deg=0.0, directions=1), [1.3, 0.0], rtol=1e-5)


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
