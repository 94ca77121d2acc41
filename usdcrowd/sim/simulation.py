"""The simulation loop: state, one fixed time step, frame recording.

Where each force is computed:

===========================  ===============================================
steering (seek, arrive, ...)  :mod:`usdcrowd.sim.steering`
collision (time to impact)    :mod:`usdcrowd.sim.collision`
flocking, leaders, memory     :mod:`usdcrowd.sim.groups`
interest fields               :mod:`usdcrowd.sim.interest`
behavior maps, reactions      :mod:`usdcrowd.sim.behavior_maps`
Bezier / slope paths          :mod:`usdcrowd.sim.paths`
walkable grid, distance maps  :mod:`usdcrowd.sim.grid`, :mod:`usdcrowd.sim.distance_maps`
neighbour lists               :mod:`usdcrowd.sim.neighbors`
integration, limits, heading  :meth:`Simulation.step` (below)
===========================  ===============================================

The per-agent and per-pair loops of the step run compiled, in
:mod:`usdcrowd.sim.kernels`: the force on each agent (:func:`.kernels.forces`
adds up the terms whose numpy forms are in ``steering``, ``collision`` and
``groups``), the neighbour table, integration and constraints, grid queries,
leader memory and walking by sight.

Dynamics (seed 003): second order, ``x += v dt + F dt^2 / 2``, ``v += F dt``
with ``F = -grad E(x, v, t)`` the sum of the components above, clipped to
the agent's maximum force, and ``|v|`` clipped to its maximum speed.
Afterwards the hard constraints (overlap correction, exact wall projection,
bounds, slope limit) adjust positions, and velocities by the same amount.

State is kept in structure-of-arrays layout, float32: ``pos`` and ``vel``
are ``(2, n + 1)``, the last column a far-away, motionless ghost that pads
neighbour lists.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Iterator

import numpy as np

from ..core.model import BEHAVIORS, CHARACTER_TYPES, HEALTH_STATES, ROLES, CrowdFrames, Scenario, code
from . import params as P
from .behavior_maps import Reactions
from .collision import project_out_of_walls, resolve_overlaps, room_for_piles, separate_spawns
from .distance_maps import DistanceMaps
from .grid import WalkGrid
from .groups import Groups, mate_mask
from .interest import InterestFields
from .kernels import (clip_to_bounds, forces, goal_directions, integrate, limit_moves, preferred_speeds,
                      settle_velocities, sight_rounds, speed_limits, turn_headings, turned_sideways)
from .neighbors import NeighborList
from .paths import BEZIER, GRADIENT, BezierPaths, SlopeSteering, Terrain, choose_path_method, enforce_slope
from .steering import arrive, wander
from .trade import Trading, top_groups
from .validate import validate
from .vision import heuristic_velocity

_B = {b: np.int8(code(BEHAVIORS, b)) for b in BEHAVIORS}
_DEAD = np.int8(code(HEALTH_STATES, "dead"))
_WOUNDED = np.int8(code(HEALTH_STATES, "wounded"))
# Top speeds (kernels.speed_limits), float32 as the preferred speeds they multiply.
_RUN_LIMIT = np.float32(P.PANIC_SPEED_FACTOR * 1.1)
_WALK_LIMIT = np.float32(P.MAX_SPEED_FACTOR)
_REST_LIMIT = np.float32(P.REST_SPEED_MAX)
_WOUNDED_PACE = np.float32(P.WOUNDED_SPEED_FACTOR)


def _ramp(d):
    """Speed factor of walkers ``d`` metres from their goal: 0 at ARRIVE_RADIUS, 1 from SLOW_RADIUS beyond."""
    return np.minimum(np.maximum((d - P.ARRIVE_RADIUS) / P.SLOW_RADIUS, 0), 1)


_HUMAN = code(CHARACTER_TYPES, "human")
LOOK_HEIGHT = 1.5  # m above the ground: eye level of a point looked at without a height
MAX_GOAL_FIELDS = 64  # distinct goals with their own distance map (others: straight seek)
_NO_GOAL_DIRS = np.zeros((0, 2, 1), np.float32)  # goal_directions' table when no goal has a map


@dataclass
class SimSettings:
    """How to run a simulation.

    Attributes
    ----------
    fps : float or None
        Output frames per second; None takes ``scenario.time.fps``.
    substeps : int
        Integration steps per frame (fixed time step ``1 / (fps * substeps)``).
    seed : int or None
        Overrides ``scenario.seed``.
    chunk_frames : int
        Frames per chunk yielded by :func:`simulate_chunks`.
    distance_method : {"dijkstra", "rays"}
        How distance maps are computed (see :mod:`usdcrowd.sim.distance_maps`).
    grid_cell : float or None
        Walkable-grid cell size, metres (None: automatic).
    neighbor_k : int
        Neighbours per agent.
    """

    fps: float | None = None
    substeps: int = P.DEFAULT_SUBSTEPS
    seed: int | None = None
    chunk_frames: int = P.DEFAULT_CHUNK_FRAMES
    distance_method: str = "dijkstra"
    grid_cell: float | None = None
    neighbor_k: int = P.NEIGHBOR_K


@dataclass
class Intent:
    """What agents want this step (filled anew every step).

    Attributes
    ----------
    v : (2, n) float32
        Desired velocity, m/s.
    look : (3, n) float32
        Point attended to, NaN where none.
    behavior : (n,) int8
        Current behavior code.
    face : (n,) bool
        Turn the body toward ``look`` rather than the velocity.
    """

    v: np.ndarray
    look: np.ndarray
    behavior: np.ndarray
    face: np.ndarray = field(default=None)


class Simulation:
    """A crowd simulation that can be stepped, or run frame by frame.

    Parameters
    ----------
    scenario : Scenario
    settings : SimSettings, optional
    """

    def __init__(self, scenario: Scenario, settings: SimSettings | None = None):
        validate(scenario)
        s = settings or SimSettings()
        if s.substeps < 1 or s.chunk_frames < 1:
            raise ValueError("substeps and chunk_frames must be >= 1")
        self.scenario = scenario
        self.settings = s
        self.fps = float(s.fps or scenario.time.fps)
        if not self.fps > 0:
            raise ValueError(f"fps must be > 0, got {self.fps}")
        self.dt = 1.0 / (self.fps * s.substeps)
        seed = scenario.seed if s.seed is None else s.seed
        # Independent streams so that adding draws in one part does not shift
        # another's.
        r_init, r_paths, r_interest, r_maps, r_step, r_slope, r_trade = np.random.default_rng(seed).spawn(7)
        self.rng = r_step
        a = scenario.agents
        n = self.n = len(a)
        self._init_agent_state(a, r_init)
        scenario = self.scenario = self._make_room(scenario)
        self.lo = np.asarray(scenario.bounds[0], dtype=np.float32)
        self.hi = np.asarray(scenario.bounds[1], dtype=np.float32)
        self.time = 0.0  # seconds since the first frame
        self.steps = 0
        self._init_scene(scenario, s)
        self._init_steering(scenario, r_paths, r_slope, r_trade)

        self.interest = (InterestFields(scenario, self.dmaps, self.visitors, r_interest)
                         if self.visitors.size else None)
        t0 = scenario.time.start
        self.reactions = Reactions(scenario, self.dmaps, lambda tc: (tc - t0) / self.fps, r_maps)
        self._anim = _animation_module()
        self._anim_prev = None
        self._sight = None          # (2, n) each walker's last choice by sight (NaN: none yet)
        self._dom_of = np.full(n, -1, np.int64)  # dominant exhibit of each visitor

    # -- set-up helpers ---------------------------------------------------------
    def _init_agent_state(self, a, r_init) -> None:
        """Per-agent constants and starting state (positions with the ghost column, headings, behaviours)."""
        n = self.n
        ctype = np.asarray(a.character_type, dtype=np.int64)
        self.ctype = ctype
        f32 = np.float32
        self.radius = np.append(np.asarray(P.AGENT_RADIUS)[ctype], 0.0).astype(f32)
        self.pref = np.asarray(a.speed, dtype=f32)
        self.max_accel = np.asarray(P.MAX_ACCEL, dtype=f32)[ctype]
        self.steer = np.full(self.n, 1.0 / P.TAU_RELAX, f32)   # 1 / relaxation time, set each step
        self.speed_cap = np.asarray(P.SPEED_CAP, dtype=f32)[ctype]
        self.turn_rate = np.asarray(P.TURN_RATE, dtype=f32)[ctype]
        self.max_slope = np.asarray(a.max_slope, dtype=f32)
        self.pos = np.full((2, n + 1), P.GHOST_POSITION, dtype=f32)
        self.pos[:, :n] = np.asarray(a.start, dtype=np.float64)[:, :2].T
        self.vel = np.zeros((2, n + 1), dtype=f32)
        self.heading = np.asarray(a.start_heading, dtype=f32).copy()
        self.group = np.append(np.asarray(a.group, dtype=np.int32), -1).astype(np.int32)
        self.health = np.zeros(n, np.int8)
        self.base_behavior = np.asarray(a.behavior, dtype=np.int8)
        self.behavior = self.base_behavior.copy()
        self.look = np.full((3, n), np.nan, f32)
        self.birds = ctype == code(CHARACTER_TYPES, "bird")
        self.walkers = np.where(~self.birds)[0]
        self.altitude = np.where(self.birds, r_init.uniform(*P.BIRD_ALTITUDE, n), 0.0).astype(f32)
        self.wander_angle = r_init.uniform(-np.pi, np.pi, n).astype(f32)

    def _make_room(self, scenario: Scenario) -> Scenario:
        """The scenario, its bounds widened where clones spawned on one point spread out beyond them."""
        room = room_for_piles(self.pos[:, :self.n], self.radius[:self.n])
        if room is None:
            return scenario
        return dataclasses.replace(scenario, bounds=np.array(
            [np.minimum(scenario.bounds[0], room[0]), np.maximum(scenario.bounds[1], room[1])]))

    def _init_scene(self, scenario: Scenario, s: SimSettings) -> None:
        """Walkable grid, distance maps, terrain, neighbours and groups; starts moved out of walls and apart."""
        a, n = scenario.agents, self.n
        self.grid = WalkGrid(scenario, s.grid_cell)
        self.dmaps = DistanceMaps(self.grid, s.distance_method)
        self.terrain = Terrain(scenario.field("height"))
        project_out_of_walls(self.grid, self.pos, self.radius)

        # Neighbours. Invisible leaders neither avoid nor are avoided.
        invisible = np.asarray(a.role) == code(ROLES, "invisibleLeader")
        self.nl = NeighborList(n, np.where(~invisible)[0], k=s.neighbor_k)
        self.movable = (~invisible).astype(np.float32)
        # Bodies that start on top of each other are set apart now, not flung apart by the first steps.
        separate_spawns(self.nl, self.grid, self.pos, self.radius, self.movable)
        # Inside the bounds from the first frame (the steps clip to them; a start pushed out would jump back).
        clip_to_bounds(self.pos, self.radius[:self.n], self.lo, self.hi)
        project_out_of_walls(self.grid, self.pos, self.radius)
        self.groups = Groups(a, scenario.groups, self.pos)
        self.isolated = self.groups.isolated
        self.mates = None

    def _init_steering(self, scenario: Scenario, r_paths, r_slope, r_trade) -> None:
        """Who steers how: followers follow; the others ("navigators") by behavior, goal and path method."""
        a, n = scenario.agents, self.n
        follower = np.zeros(n, bool)
        follower[self.groups.followers] = True
        nav = ~follower
        beh = self.base_behavior
        goal = self._resolve_goals(scenario)
        has_goal = np.isfinite(goal[0])
        self.goal = goal
        visit = nav & (beh == _B["visit"]) & (len(scenario.interest) > 0)
        self.visitors = np.where(visit)[0]
        self.rest_rows = np.where(nav & ~visit & (beh == _B["rest"]))[0]
        goers = nav & ~visit & has_goal & (beh != _B["rest"])
        self.wanderers = np.where(nav & ~visit & ~goers & (beh != _B["rest"]))[0]
        trades = np.zeros(n, bool) if a.trades is None else np.asarray(a.trades, bool)
        self.trading = Trading(self.wanderers, self.rest_rows, trades, top_groups(a, scenario.groups), r_trade) \
            if trades.any() else None
        self.path_method = choose_path_method(scenario, self.terrain)
        pm = self.path_method
        self.bez_rows = np.where(goers & (pm == BEZIER))[0]
        self.grad_rows = np.where(goers & (pm == GRADIENT))[0]
        self.direct_rows = np.where(goers & (pm != BEZIER) & (pm != GRADIENT))[0]
        self.bezier = BezierPaths(self.pos[:, self.bez_rows], goal[:, self.bez_rows], r_paths) \
            if self.bez_rows.size else None
        self.slope_nav = SlopeSteering(self.terrain, self.max_slope[self.grad_rows], r_slope)
        self._goers = goers
        self._goal_fields(goal, goers)
        self._waypoints = self._resolve_waypoints(scenario)

    def _resolve_goals(self, scenario: Scenario) -> np.ndarray:
        """(2, n) goal of each agent's group (inherited from ancestors), NaN if none."""
        g = scenario.groups
        n = self.n
        if len(g) == 0:
            return np.full((2, n), np.nan, np.float32)
        goal = np.asarray(g.goal, dtype=np.float64)[:, :2].copy()
        parent = np.asarray(g.parent, dtype=np.int64)
        up = parent.copy()
        for _ in range(len(g)):  # bounded by the hierarchy's depth
            miss = ~np.isfinite(goal[:, 0]) & (up >= 0)
            if not miss.any():
                break
            goal[miss] = goal[up[miss]]
            up = np.where(miss, parent[np.maximum(up, 0)], -1)
        return goal[np.asarray(scenario.agents.group, dtype=np.int64)].T.astype(np.float32)

    def _resolve_waypoints(self, scenario: Scenario) -> list:
        """[rows, times (s), points (k, 2), next index] per group whose goal is time-sampled."""
        out = []
        t0, fps = scenario.time.start, self.fps
        for gi, w in enumerate(scenario.groups.waypoints):
            rows = np.where(np.asarray(scenario.agents.group) == gi)[0]
            if w is None or rows.size == 0:
                continue
            times, points = w
            seconds = (np.asarray(times, dtype=np.float64) - t0) / fps
            # Waypoints already in force at the start are the initial goal.
            nxt = max(int(np.searchsorted(seconds, 0.0, side="right")), 1)
            out.append([rows, seconds, np.asarray(points, dtype=np.float32)[:, :2], nxt])
        return out

    def _advance_waypoints(self) -> None:
        """Switch groups to their next waypoint when its time comes."""
        changed = []
        for w in self._waypoints:
            rows, seconds, points, nxt = w
            k = nxt
            while k < len(seconds) and seconds[k] <= self.time:
                k += 1
            if k != nxt:
                self.goal[:, rows] = points[k - 1][:, None]
                w[3] = k
                changed.append(rows)
        if not changed:
            return
        rows = np.concatenate(changed)
        self._goal_fields(self.goal, self._goers)      # distance maps are cached per goal point
        if self.bezier is not None:
            sel = np.where(np.isin(self.bez_rows, rows))[0]
            if sel.size:
                r = self.bez_rows[sel]
                self.bezier.retarget(sel, self.pos[:, r], self.goal[:, r])

    def _goal_fields(self, goal, goers):
        """Distance-map directions to each distinct goal (only around obstacles)."""
        self.goal_id = np.full(self.n, -1, np.int64)
        self.goal_dirs = None
        if not self.grid.has_solid or not goers.any():
            return
        rows = np.where(goers)[0]
        pts, inv = np.unique(np.round(goal[:, rows].T, 3), axis=0, return_inverse=True)
        inv = inv.ravel()
        keep = min(len(pts), MAX_GOAL_FIELDS)
        dirs = np.empty((keep, 2, self.grid.h * self.grid.w), np.float32)
        for i in range(keep):  # once per distinct goal
            _, d = self.dmaps.direction(pts[i:i + 1], key=("goal", tuple(pts[i])))
            dirs[i] = d.reshape(2, -1)
        self.goal_dirs = dirs
        ok = inv < keep
        self.goal_id[rows[ok]] = inv[ok]

    # -- one step -----------------------------------------------------------------
    def _goal_direction(self, rows):
        """(2, m) unit direction toward each agent's goal (around obstacles), (m,) straight distance."""
        dirs = _NO_GOAL_DIRS if self.goal_dirs is None else self.goal_dirs
        return goal_directions(self.pos, self.goal, rows, self.goal_id, dirs, *self.grid.lookup)

    def _intent(self) -> Intent:
        n = self.n
        pos, vel = self.pos, self.vel
        alive = self.health != _DEAD
        speed = preferred_speeds(self.pref, self.health, _WOUNDED, _WOUNDED_PACE)
        it = Intent(np.zeros((2, n), np.float32), np.full((3, n), np.nan, np.float32),
                    self.base_behavior.copy(), np.zeros(n, bool))
        # Leaders wait for lagging groups.
        pace = np.ones(n, np.float32)
        if len(self.groups.leaders):
            pace[self.groups.leaders] = self.groups.leader_pace(pos)
        # Goal walkers: straight / distance-map direction, Bezier carrot, or slope-aware.
        if self.direct_rows.size:
            r = self.direct_rows
            u, d = self._goal_direction(r)
            it.v[:, r] = u * (speed[r] * pace[r] * _ramp(d))
        if self.grad_rows.size:
            r = self.grad_rows
            u, d = self._goal_direction(r)
            u = self.slope_nav.direction(pos[:, r], u, self.dt)
            it.v[:, r] = u * (speed[r] * pace[r] * _ramp(d))
        if self.bezier is not None:
            r = self.bez_rows
            carrot, last = self.bezier.carrot(pos[:, r])
            # Re-draw the control points when the carrot is blocked or too steep.
            blocked = self.grid.is_solid(carrot[0], carrot[1])
            if self.grid.has_solid:  # ...or hidden behind an obstacle
                blocked |= ~self.grid.line_of_sight(pos[0, r], pos[1, r], carrot[0], carrot[1])
            if not self.terrain.flat:
                blocked |= self.terrain.slope(carrot[0], carrot[1]) > self.max_slope[r]
            self.bezier.repair(blocked & ~last)
            v, _ = arrive(pos[:, r], carrot, speed[r] * pace[r],
                          slow_radius=np.where(last, P.SLOW_RADIUS, 1e-3).astype(np.float32),
                          stop_radius=np.where(last, P.ARRIVE_RADIUS, 0.0).astype(np.float32))
            it.v[:, r] = v
        if self.wanderers.size:
            r = self.wanderers
            noise = self.rng.standard_normal(r.size, dtype=np.float32)
            wa = self.wander_angle[r]
            it.v[:, r] = wander(self.heading[r], wa, noise, self.dt,
                                speed[r] * pace[r] * np.float32(P.WANDER_SPEED_FACTOR))
            self.wander_angle[r] = wa
        if self.trading is not None and self.trading.active:
            self.trading.apply(it, pos, self.time, speed)
        if self.interest is not None:
            r = self.visitors
            u, ipace, dom = self.interest.step(pos, self.dt, self.time)
            it.v[:, r] = u * (speed[r] * pace[r] * ipace)
            # Done with every exhibit: head for the group's goal if any.
            done = dom < 0
            gl = done & np.isfinite(self.goal[0, r])
            if gl.any():
                u2, d2 = self._goal_direction(r[gl])
                it.v[:, r[gl]] = u2 * (speed[r[gl]] * _ramp(d2))
            self._look_at_exhibits(it, r, dom)
        # Followers: arrive at the remembered leader position (E_L).
        if len(self.groups.followers):
            self.groups.follow(pos, speed, self.behavior, _B["run"], it.v, it.behavior)
            if self.interest is not None:
                self._member_look(it)
        # Behavior-map reactions (blend by map influence).
        self.reactions.apply(it, pos, vel, speed, alive, self.time)
        dead = ~alive
        it.v[:, dead] = 0.0
        it.behavior[dead] = _B["rest"]
        return it

    def _walk_by_sight(self, it: Intent, radius: np.ndarray) -> None:
        """People walking somewhere pick their way and pace by what they see ahead (:mod:`.vision`), each
        every VISION_INTERVAL seconds (in turn, so the cost is spread over the steps), keeping the
        choice in between; held up in line long enough, they wait their turn (:func:`.kernels.sight_rounds`)."""
        v = it.v
        if self._sight is None:
            self._sight = np.full((2, self.n), np.nan, np.float32)
            self._sight_free = np.zeros(self.n, bool)
            self._follows = np.zeros(self.n, bool)
            self._waited = np.zeros(self.n, np.float32)       # s held up behind someone, in a row
            self._queued_until = np.full(self.n, -np.inf)     # s, waiting their turn until then
        every = max(1, int(round(P.VISION_INTERVAL / self.dt)))
        speed, rows, due = sight_rounds(v, it.behavior, int(_B["walk"]), self.ctype, _HUMAN, self.vel, self._follows,
                                        self._waited, self._queued_until, self._sight, self.time,
                                        np.float32(self.dt), self.steps, every)
        self.steer[:] = np.float32(1.0 / P.TAU_RELAX)
        if len(rows) == 0:
            return
        if len(due):
            self._sight[:, due], self._sight_free[due], self._follows[due] = heuristic_velocity(
                self.pos, self.vel, v[:, due] / speed[due], speed[due], self.nl.idx, radius, due,
                grid=self.grid if self.grid.has_solid else None, queued=self._queued_until[due] > self.time,
                ghost=self.n)
        # Nothing in their way at their last look: they walk as they meant to, to the bit.
        held = rows[~self._sight_free[rows]]
        v[:, held] = self._sight[:, held]
        # Held up by someone, they take up the space as it opens (SIGHT_RELAX).
        self.steer[held] = np.float32(1.0 / P.SIGHT_RELAX)

    def _look_at_exhibits(self, it, rows, dom):
        ip = self.interest
        has = dom >= 0
        e = ip.position[np.maximum(dom, 0)]
        d = np.hypot(self.pos[0, rows] - e[:, 0], self.pos[1, rows] - e[:, 1])
        near = has & (d < P.LOOK_AT_RANGE * ip.radius[np.maximum(dom, 0)])
        it.look[:, rows[near]] = e[near].T
        it.behavior[rows[near]] = _B["visit"]
        it.face[rows[near & (d < ip.radius[np.maximum(dom, 0)])]] = True
        self._dom_of[rows] = dom

    def _member_look(self, it):
        g = self.groups
        dom = self._dom_of[g.leader_of]
        ip = self.interest
        e = ip.position[np.maximum(dom, 0)]
        fw = g.followers
        d = np.hypot(self.pos[0, fw] - e[:, 0], self.pos[1, fw] - e[:, 1])
        near = (dom >= 0) & (d < P.LOOK_AT_RANGE * ip.radius[np.maximum(dom, 0)])
        it.look[:, fw[near]] = e[near].T
        it.behavior[fw[near]] = _B["visit"]

    def step(self) -> None:
        """Advance the crowd by one fixed time step ``dt``."""
        n = self.n
        dt = np.float32(self.dt)
        pos, vel = self.pos, self.vel
        g = self.groups
        if self._waypoints:
            self._advance_waypoints()
        # Bookkeeping that perception depends on.
        self.reactions.update_health(self.health, pos[0, :n], pos[1, :n], self.time)
        g.record_trail(self.time, pos)
        g.update_memory(self.steps, pos, self.grid)
        if self.nl.update(pos) or self.mates is None:
            self.mates = mate_mask(self.group, self.nl.idx, self.isolated)
            if self.grid.has_solid:
                self._occlude_mates()
        it = self._intent()
        radius = self._turned_radius()
        self._walk_by_sight(it, radius)

        # Forces (accelerations): steering toward the desired velocity, then the seed's field
        # components (E_C against agents and walls, personal space, E_F + E_V, containment), one
        # pass over the agents and their neighbour table.
        idx = self.nl.idx
        g = self.grid
        F = forces(pos, vel, it.v, self.steer, radius, idx, self.mates, g.has_solid, *g.lookup, g.flat_sdf,
                   g.flat_nx, g.flat_ny, *g.exact, self.lo, self.hi)

        # Integration (seed 003): x += v dt + F dt^2 / 2, v += F dt, force and speed clipped.
        alive = self.health != _DEAD
        vmax = speed_limits(it.behavior, self.pref, self.speed_cap, self.health, _B["run"], _B["rest"], _DEAD,
                            _RUN_LIMIT, _WALK_LIMIT, _REST_LIMIT, np.empty(n, np.float32))
        old = pos.copy()
        integrate(pos, vel, F, alive, self.max_accel, vmax, dt)
        integrated = pos[:, :n].copy()

        # Hard constraints. Overlap corrections move no one faster than it may move: a pile of bodies
        # (clones spawned where they do not fit) spreads over frames instead of flinging them apart.
        resolve_overlaps(pos, idx, radius, self.movable * alive)
        limit_moves(pos, old, vmax, dt)
        project_out_of_walls(self.grid, pos, radius)
        clip_to_bounds(pos, self.radius[:n], self.lo, self.hi)
        enforce_slope(self.terrain, old, pos, vel, self.walkers, self.max_slope)
        # Constraint displacements count as velocity (position-based dynamics),
        # so agents stop pushing into what stopped them.
        settle_velocities(pos, vel, integrated, np.float32(1.0 / self.dt), vmax)
        pos[:, n] = P.GHOST_POSITION
        vel[:, n] = 0.0

        self._turn(it)
        self.behavior = it.behavior
        self.look = it.look
        self.time += self.dt
        self.steps += 1

    def _turned_radius(self) -> np.ndarray:
        """(n + 1,) float32 body radii this step: those in or walking into a passage narrower than two
        bodies turn their shoulders and take SIDEWAYS_RADIUS of theirs (:func:`.kernels.turned_sideways`)."""
        g = self.grid
        if not g.has_solid or P.SIDEWAYS_RADIUS >= 1.0:
            return self.radius
        sideways = turned_sideways(self.pos, self.vel, self.n, np.float32(P.SIDEWAYS_WIDTH),
                                   np.float32(P.SIDEWAYS_AHEAD), *g.lookup, g.flat_sdf, g.flat_nx, g.flat_ny,
                                   *g.exact)
        if not sideways.any():
            return self.radius
        radius = self.radius.copy()
        radius[:self.n][sideways] *= np.float32(P.SIDEWAYS_RADIUS)
        return radius

    def _occlude_mates(self):
        """Drop group-mates hidden behind walls (agents near obstacles only)."""
        n = self.n
        sdf, _, _ = self.grid.clearance(self.pos[0, :n], self.pos[1, :n])
        rows = np.where((sdf < P.FLOCK_RADIUS) & (self.mates.sum(axis=1) > 0))[0]
        if rows.size == 0:
            return
        idx = self.nl.idx[rows]
        k = idx.shape[1]
        ax = np.repeat(self.pos[0, rows], k)
        ay = np.repeat(self.pos[1, rows], k)
        bx = self.pos[0, idx.ravel()]
        by = self.pos[1, idx.ravel()]
        near = np.hypot(bx - ax, by - ay) < P.FLOCK_RADIUS + P.NEIGHBOR_SKIN
        vis = np.zeros(ax.size, bool)
        vis[near] = self.grid.line_of_sight(ax[near], ay[near], bx[near], by[near])
        self.mates[rows] *= vis.reshape(-1, k)

    def _turn(self, it: Intent) -> None:
        """Turn headings toward the velocity (or the attended point), rate-limited."""
        n = self.n
        vx, vy = self.vel[0, :n], self.vel[1, :n]
        want = np.arctan2(vy, vx)
        face = it.face & np.isfinite(it.look[0])
        if face.any():
            px, py = self.pos[0, :n], self.pos[1, :n]
            want[face] = np.arctan2(it.look[1, face] - py[face], it.look[0, face] - px[face])
        turn_headings(self.heading, want, self.vel, face, self.turn_rate, np.float32(self.dt))

    # -- frames ---------------------------------------------------------------------
    def _frame(self):
        """Current state as one frame's arrays (position (n, 3), ...)."""
        n = self.n
        x, y = self.pos[0, :n], self.pos[1, :n]
        z = self.terrain.height(x, y)
        if self.birds.any():
            sp = np.hypot(self.vel[0, :n], self.vel[1, :n])
            lift = np.minimum(sp / np.maximum(0.5 * self.pref, 1e-3), 1.0)
            z = z + self.altitude * lift
        look = self.look.copy()
        fill = np.isfinite(look[0]) & ~np.isfinite(look[2])
        if fill.any():
            look[2, fill] = self.terrain.height(look[0, fill], look[1, fill]) + LOOK_HEIGHT
        return (np.stack([x, y, z], axis=1), self.heading.copy(), self.vel[:, :n].T.copy(),
                self.behavior.copy(), self.health.copy(), look.T)

    def frames(self, n_frames: int, first_time_code: float) -> CrowdFrames:
        """Record ``n_frames`` frames, stepping ``substeps`` times between them.

        The first recorded frame is the current state (no step before it).
        """
        n = self.n
        pos = np.empty((n_frames, n, 3), np.float32)
        head = np.empty((n_frames, n), np.float32)
        vel = np.empty((n_frames, n, 2), np.float32)
        beh = np.empty((n_frames, n), np.int8)
        hp = np.empty((n_frames, n), np.int8)
        look = np.empty((n_frames, n, 3), np.float32)
        for f in range(n_frames):  # frames are sequential by nature
            if f > 0 or self.steps > 0:
                for _ in range(self.settings.substeps):
                    self.step()
            pos[f], head[f], vel[f], beh[f], hp[f], look[f] = self._frame()
        anim, phase = self._animate(vel, head)
        times = first_time_code + np.arange(n_frames, dtype=np.float64)
        return CrowdFrames(times, pos, head, vel, beh, anim, phase, hp, look, self.path_method.copy())

    def _animate(self, vel, head):
        cls = self._anim.classify(vel, head)
        speed = np.hypot(vel[..., 0], vel[..., 1])
        dt = 1.0 / self.fps
        if self._anim_prev is None:
            phase = self._anim.advance_phase(speed, cls, dt, None)
        else:
            # Continue the previous chunk: prepend its last frame.
            ps, pc, pp = self._anim_prev
            phase = self._anim.advance_phase(np.concatenate([ps[None], speed]), np.concatenate([pc[None], cls]),
                                             dt, pp)[1:]
        self._anim_prev = (speed[-1], cls[-1], phase[-1])
        return cls.astype(np.int8), phase.astype(np.float32)

    def run_chunks(self) -> Iterator[CrowdFrames]:
        """Yield the whole shot as consecutive chunks of frames."""
        tr = self.scenario.time
        total = tr.n_frames
        start = 0
        while start < total:
            k = min(self.settings.chunk_frames, total - start)
            yield self.frames(k, tr.start + start)
            start += k


def _animation_module():
    """The character package's classifier and phase (pure numpy, no pxr)."""
    from ..character import animation as anim

    return anim


def concat_frames(chunks: list[CrowdFrames]) -> CrowdFrames:
    """Join consecutive chunks along time."""
    if len(chunks) == 1:
        return chunks[0]
    cat = lambda name: np.concatenate([getattr(c, name) for c in chunks])  # noqa: E731
    return CrowdFrames(cat("times"), cat("position"), cat("heading"), cat("velocity"), cat("behavior"),
                       cat("anim_class"), cat("anim_phase"), cat("health"), cat("look_at"),
                       chunks[0].path_method, None if chunks[0].present is None else cat("present"))
