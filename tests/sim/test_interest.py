"""Interest fields (seed 003): distance maps with occlusion, decay, visiting profiles."""

from __future__ import annotations

import numpy as np
import pytest

import tests.helpers.scenarios as S
from usdcrowd.core.model import BEHAVIORS
from usdcrowd.sim import Simulation, simulate
from usdcrowd.sim import params as P
from usdcrowd.sim.distance_maps import DistanceMaps
from usdcrowd.sim.grid import WalkGrid

VISIT = BEHAVIORS.index("visit")
EXHIBITS = [[-8.0, 5.0, 1.5], [8.0, -2.0, 1.5]]


def museum(profile="detailed", frames=960, budget=600.0, goal=(np.nan, np.nan, np.nan)):
    rng = np.random.default_rng(0)
    start = np.concatenate([[[-2.0, -8.0]], rng.uniform(-4, 0, (4, 2)) + [0, -8]])
    at = S.agents(start, leader=[-1, 0, 0, 0, 0], role=["invisibleLeader"] + ["member"] * 4, behavior="visit",
                  profile=profile)
    ip = S.interest_points(EXHIBITS, interest=[1.0, 0.8], radius=2.0, decay=0.3, prior=[1.0, 0.0])
    return S.scenario(at, S.groups([goal], leaders=[0], budget=budget), obstacles=[S.box(0, 2, 0.3, 6)],
                      interest=ip, frames=frames)


def test_group_visits_dominant_exhibit_then_the_next():
    sc = museum()
    fr = simulate(sc)
    e = np.asarray(EXHIBITS)[:, :2]
    lead = fr.position[:, 0, :2]
    d = np.linalg.norm(lead[:, None, :] - e[None], axis=2)  # (t, 2)
    at_a = np.where(d[:, 0] < 1.5)[0]
    at_b = np.where(d[:, 1] < 2.0)[0]
    assert at_a.size and at_b.size and at_a[0] < at_b[0]  # A first (closer, more interesting)
    assert at_a[-1] - at_a[0] > 3 * sc.time.fps  # lingered there while interest decayed
    # Looking at the exhibit being visited, members too.
    k = at_a[len(at_a) // 2]
    np.testing.assert_allclose(fr.look_at[k, 0], EXHIBITS[0], atol=1e-5)
    assert np.all(fr.behavior[k] == VISIT)
    near_members = np.linalg.norm(fr.position[k, 1:, :2] - e[0], axis=1) < P.LOOK_AT_RANGE * 2.0
    np.testing.assert_allclose(fr.look_at[k, 1:][near_members], np.broadcast_to(EXHIBITS[0], (near_members.sum(), 3)))


def test_interest_decays_only_near_the_exhibit():
    sim = Simulation(museum(frames=10))
    ip = sim.interest
    a0 = ip.alpha.copy()
    for _ in range(24):
        sim.step()
    # Far from both exhibits (> 10 m, sigma = 2 m): essentially no decay.
    np.testing.assert_allclose(ip.alpha, a0, atol=1e-3)
    sim.pos[:, 0] = EXHIBITS[0][:2]
    for _ in range(96):  # 2 s at the exhibit
        sim.step()
    assert ip.alpha[0, 0] < a0[0, 0] - 0.1
    assert ip.alpha[0, 1] > a0[0, 1] - 1e-3


def test_time_limited_group_leaves_for_its_goal():
    sc = museum(profile="timeLimited", budget=3.0, goal=(-15.0, -15.0, 0.0), frames=480)
    fr = simulate(sc)
    assert np.linalg.norm(fr.position[-1, 0, :2] - [-15, -15]) < 2.0
    d = np.linalg.norm(fr.position[:, 0, None, :2] - np.asarray(EXHIBITS)[None, :, :2], axis=2)
    assert d.min() > 3.0  # never got to an exhibit


def test_visibility_and_prior_knowledge_modulate_attraction():
    sim = Simulation(museum(frames=2))
    ip, g = sim.interest, sim.grid
    behind = g.flat_index(np.array([8.0]), np.array([5.0]))  # wall between it and exhibit A
    seen = g.flat_index(np.array([-8.0]), np.array([0.0]))
    # Exhibit A is known (prior 1): full gain everywhere.
    assert ip.beta[0, behind][0] == pytest.approx(1.0) and ip.beta[0, seen][0] == pytest.approx(1.0)
    # Exhibit B is unknown (prior 0): attracts where it can be seen only.
    b_behind = g.flat_index(np.array([-3.0]), np.array([4.0]))
    assert ip.beta[1, b_behind][0] == pytest.approx(P.BETA_MIN)
    assert ip.beta[1, g.flat_index(np.array([8.0]), np.array([-8.0]))][0] == pytest.approx(1.0)


@pytest.mark.parametrize("method", ["dijkstra", "rays"])
def test_distance_maps_open_and_occluded(method):
    open_sc = S.scenario(S.agents([[0, 0]]), S.groups([[1, 0, 0]]), bounds=((-10, -10), (10, 10)))
    g = WalkGrid(open_sc)
    D = DistanceMaps(g, method).distance(np.array([[0.0, 0.0]]))
    euclid = np.hypot(g.centers_x, g.centers_y)
    assert np.all(D >= euclid - 1e-9)
    # Open ground: the 8-connected graph overestimates by < 8.3 %, rays are exact.
    assert np.all(D <= euclid * 1.083 + g.cell)

    wall_sc = S.scenario(S.agents([[0, 0]]), S.groups([[1, 0, 0]]), obstacles=[S.box(0, 0, 0.3, 6.0)],
                         bounds=((-10, -10), (10, 10)))
    g = WalkGrid(wall_sc)
    dm = DistanceMaps(g, method)
    D = dm.distance(np.array([[-3.0, 0.0]]))
    i = g.flat_index(np.array([3.0]), np.array([0.0]))[0]
    # Behind the wall: around its end, sqrt(3.3^2 + 6.3^2) * 2 ~ 14.2 m, far above 6 m straight.
    assert 13.0 < D.ravel()[i] < 16.5
    assert np.all(np.isinf(D[g.solid]))


def test_rays_are_closer_to_the_true_geodesic_than_dijkstra():
    sc = S.scenario(S.agents([[0, 0]]), S.groups([[1, 0, 0]]), obstacles=[S.box(0, 0, 0.3, 6.0)],
                    bounds=((-10, -10), (10, 10)))
    g = WalkGrid(sc)
    src = np.array([-3.0, 0.0])
    Dd = DistanceMaps(g, "dijkstra").distance(src[None])
    Dr = DistanceMaps(g, "rays").distance(src[None])
    # Exact geodesic for cells right of the wall: straight if the segment
    # clears the wall, else around its nearer end (two corners).
    x, y = g.centers_x, g.centers_y
    t = (0.0 - src[0]) / (x - src[0])
    y_cross = src[1] + t * (y - src[1])
    hidden = (x > 0.3) & (np.abs(y_cross) < 6.0)
    around = np.minimum.reduce([np.hypot(-0.3 - src[0], s * 6 - src[1]) + 0.6 + np.hypot(x - 0.3, y - s * 6)
                                for s in (-1, 1)])
    true = np.where(hidden, around, np.hypot(x - src[0], y - src[1]))
    sel = (x > 1.0) & np.isfinite(Dd) & np.isfinite(Dr)
    err_d = np.abs(Dd[sel] - true[sel]).mean()
    err_r = np.abs(Dr[sel] - true[sel]).mean()
    assert err_r < err_d
    # Corners are pushed 0.75 cell off the obstacle so their cells are free:
    # paths round them slightly wide.
    assert err_r < 0.3  # metres, on a 0.25 m grid (Dijkstra: ~1.5 m here)


@pytest.mark.parametrize("width, through", [(0.8, True), (1.2, True), (0.4, False)])
def test_a_door_wide_enough_for_a_body_is_a_way_through(width, through):
    """Paths go through a door a body fits (0.8 m, 1.2 m; walls between cell centres), not one it does not
    (0.4 m): the far side of the wall is reached only through the door."""
    h = width / 2.0
    walls = [S.box(0.0, h + 6.0, 0.5, 6.0), S.box(0.0, -h - 6.0, 0.5, 6.0)]    # across the grid, but a door
    g = WalkGrid(S.scenario(S.agents([[-5, 0]]), S.groups([[5, 0, 0]]), obstacles=walls,
                            bounds=((-8, -6.0), (8, 6.0))))
    D = DistanceMaps(g, "dijkstra").distance(np.array([[-4.0, 0.0]]))
    beyond = D.ravel()[g.flat_index(np.array([4.0]), np.array([0.0]))[0]]
    assert np.isfinite(beyond) == through, beyond
    if through:
        assert beyond < 8.0 * 1.083 + 2 * g.cell
