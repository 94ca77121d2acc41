"""Small seeded Scenario factories for the simulation tests (pure numpy, no USD)."""

from __future__ import annotations

import numpy as np

from usdcrowd.core.model import (BEHAVIORS, CHARACTER_TYPES, CONDITIONS, FEAR_RESPONSES, LAYER_GENERATORS,
                                 LAYER_MEANINGS, PERSONALITIES, ROLES, VISIT_PROFILES, AgentTable, BehaviorField,
                                 GroupTable, InterestTable, Obstacles, Scenario, TimeRange, code)


def agents(start, *, group=None, leader=None, role="member", character="human", personality="civilian",
           behavior="walk", condition="grouped", fear="flee", profile="casual", speed=1.3, height=1.75,
           max_slope=1.0, map_influence=1.0, heading=0.0) -> AgentTable:
    """An AgentTable with every attribute given (scalars broadcast, tokens or per-agent lists)."""
    start = np.asarray(start, dtype=np.float64)
    if start.shape[1] == 2:
        start = np.concatenate([start, np.zeros((len(start), 1))], axis=1)
    n = len(start)

    def tok(vocab, v):
        if isinstance(v, str):
            return np.full(n, code(vocab, v), np.int8)
        return np.array([code(vocab, t) for t in v], np.int8)

    def num(v, dtype=np.float64):
        return np.broadcast_to(np.asarray(v, dtype=dtype), (n,)).copy()

    return AgentTable(
        path=[f"/World/Crowd/a{i}" for i in range(n)],
        agent_id=np.arange(1, n + 1, dtype=np.int32),
        group=num(0 if group is None else group, np.int32),
        leader=num(-1 if leader is None else leader, np.int32),
        role=tok(ROLES, role), character_type=tok(CHARACTER_TYPES, character),
        personality=tok(PERSONALITIES, personality), behavior=tok(BEHAVIORS, behavior),
        condition=tok(CONDITIONS, condition), fear_response=tok(FEAR_RESPONSES, fear),
        visit_profile=tok(VISIT_PROFILES, profile), speed=num(speed), height=num(height),
        max_slope=num(max_slope), map_influence=num(map_influence),
        color=np.full((n, 3), 0.5), start=start, start_heading=num(heading))


def groups(goals, leaders=None, parent=None, budget=600.0) -> GroupTable:
    goals = np.asarray(goals, dtype=np.float64).reshape(-1, 3) if len(goals) else np.zeros((0, 3))
    g = len(goals)
    return GroupTable(path=[f"/World/Crowd/g{i}" for i in range(g)],
                      parent=np.full(g, -1, np.int32) if parent is None else np.asarray(parent, np.int32),
                      goal=goals, visit_budget=np.full(g, budget),
                      leader=np.full(g, -1, np.int32) if leaders is None else np.asarray(leaders, np.int32))


def box(cx, cy, hx, hy) -> np.ndarray:
    """CCW rectangle footprint centred at (cx, cy) with half sizes."""
    return np.array([[cx - hx, cy - hy], [cx + hx, cy - hy], [cx + hx, cy + hy], [cx - hx, cy + hy]], float)


def scenario(agent_table, group_table, *, obstacles=(), fields=(), interest=None, bounds=((-20, -20), (20, 20)),
             frames=48, fps=24.0, seed=7) -> Scenario:
    obs = Obstacles([f"/World/Scenery/o{i}" for i in range(len(obstacles))], [np.asarray(p, float) for p in obstacles],
                    np.full(len(obstacles), 2.0)) if len(obstacles) else Obstacles.empty()
    return Scenario(source="test.usda", time=TimeRange(1.0, float(frames), fps), seed=seed, groups=group_table,
                    agents=agent_table, fields=list(fields), interest=interest or InterestTable.empty(),
                    obstacles=obs, bounds=np.asarray(bounds, dtype=np.float64))


def field(meaning, generator="painted", values=None, extent=((-20, -20), (20, 20)), origin=(0, 0, 0), radius=5.0,
          start_time=1.0, influence=1.0) -> BehaviorField:
    return BehaviorField(path=f"/World/Layers/{meaning}", meaning=code(LAYER_MEANINGS, meaning),
                         generator=code(LAYER_GENERATORS, generator),
                         values=None if values is None else np.asarray(values, np.float32),
                         extent_min=np.asarray(extent[0], float), extent_max=np.asarray(extent[1], float),
                         influence=influence, origin=np.asarray(origin, float), radius=radius,
                         start_time=start_time)


def interest_points(positions, interest=1.0, radius=2.0, visibility=1.0, prior=0.5, decay=0.2, view=10.0):
    p = np.asarray(positions, dtype=np.float64)
    m = len(p)
    b = lambda v: np.broadcast_to(np.asarray(v, float), (m,)).copy()  # noqa: E731
    return InterestTable([f"/World/Interest/i{i}" for i in range(m)], p, b(interest), b(radius), b(visibility),
                         b(prior), b(decay), b(view))


# -- ready-made scenes --------------------------------------------------------

def crossing(n_per_side=20, seed=3, frames=96):
    """Two groups crossing head-on through each other in an open 40 m square."""
    rng = np.random.default_rng(seed)
    a = np.stack([rng.uniform(-14, -8, n_per_side), rng.uniform(-4, 4, n_per_side)], axis=1)
    b = np.stack([rng.uniform(8, 14, n_per_side), rng.uniform(-4, 4, n_per_side)], axis=1)
    start = np.concatenate([a, b])
    grp = np.repeat([0, 1], n_per_side)
    at = agents(start, group=grp, condition="isolated", heading=np.where(grp == 0, 0.0, np.pi))
    gt = groups([[16, 0, 0], [-16, 0, 0]])
    return scenario(at, gt, frames=frames, seed=seed)


def room_with_pillars(n=30, seed=5, frames=96):
    """Agents walking across a room with pillars and a wall with a gap."""
    rng = np.random.default_rng(seed)
    start = np.stack([rng.uniform(-17, -12, n), rng.uniform(-10, 10, n)], axis=1)
    at = agents(start, condition="isolated")
    gt = groups([[15, 0, 0]])
    obs = [box(-5, 6, 0.5, 8.0), box(-5, -13, 0.5, 4.0), box(4, 4, 1.0, 1.0), box(4, -4, 1.5, 1.0),
           box(9, 0, 0.3, 0.3)]
    return scenario(at, gt, obstacles=obs, frames=frames, seed=seed)


def led_group(seed=11, frames=120, invisible=True, walls=True):
    """An (invisible) leader guiding 7 members to a goal around a wall."""
    rng = np.random.default_rng(seed)
    members = np.stack([rng.uniform(-16, -13, 7), rng.uniform(-3, 3, 7)], axis=1)
    start = np.concatenate([[[-14.0, 0.0]], members])
    role = ["invisibleLeader" if invisible else "leader"] + ["member"] * 7
    at = agents(start, leader=[-1] + [0] * 7, role=role, speed=1.2)
    gt = groups([[14, 8, 0]], leaders=[0])
    obs = [box(0, -2, 0.4, 8.0)] if walls else []
    return scenario(at, gt, obstacles=obs, frames=frames, seed=seed)
