"""Time-sampled goals: a group goes to one waypoint, then on to the next when its time comes."""

from __future__ import annotations

import numpy as np

import tests.helpers.scenarios as S
from usdcrowd.scenario import load_scenario
from usdcrowd.sim import simulate

PIER, WAREHOUSE = np.array([2.0, 0.0]), np.array([-8.0, 0.0])
BACK = 360.0          # frame of the second waypoint; leaders walk about 0.9 m/s with their group


def _there_and_back(frames=720):
    # A leader and four members; waypoints at frame 1 (pier) and frame BACK (back to the warehouse).
    start = [[-8, 0], [-9, 1], [-9, -1], [-10, 1], [-10, -1]]
    a = S.agents(start, leader=[-1, 0, 0, 0, 0], role=["leader", "member", "member", "member", "member"],
                 speed=1.4, max_slope=1.0)
    g = S.groups([[PIER[0], PIER[1], 0]], leaders=[0])
    g.waypoints = [(np.array([1.0, BACK]), np.array([[PIER[0], PIER[1], 0], [WAREHOUSE[0], WAREHOUSE[1], 0]]))]
    return S.scenario(a, g, frames=frames)


def test_the_group_reaches_the_first_waypoint_then_returns():
    f = simulate(_there_and_back())
    leader = f.position[:, 0, :2]
    at_pier = np.linalg.norm(leader - PIER, axis=1) < 1.0
    k = int(BACK) - 1
    assert at_pier[:k].any(), "the leader never reached the pier before the second waypoint"
    assert np.linalg.norm(leader[k - 1] - PIER) < 1.0              # it waited there for the waypoint
    assert np.linalg.norm(leader[-1] - WAREHOUSE) < 1.5           # then went back where it came from
    members = f.position[-1, 1:, :2]
    assert np.all(np.linalg.norm(members - WAREHOUSE, axis=1) < 4.0)


def test_waypoints_are_read_from_a_time_sampled_goal(write_stage):
    path = write_stage('''
def CrowdGroup "Workers"
{
    uniform int crowd:clones = 2
    point3f crowd:goal.timeSamples = {
        1: (2, 0, 0),
        360: (-8, 0, 0),
    }
    def CrowdGroup "Gang"
    {
        uniform int crowd:clones = 1
    }
}
''', end=720)
    sc = load_scenario(path)
    times, points = sc.groups.waypoints[0]
    assert times.tolist() == [1.0, BACK] and np.allclose(points[:, :2], [PIER, WAREHOUSE])
    assert np.allclose(sc.groups.goal[0, :2], PIER)              # the goal in force at the start
    assert sc.groups.waypoints[1] is sc.groups.waypoints[0]      # the subgroup follows its parent's
