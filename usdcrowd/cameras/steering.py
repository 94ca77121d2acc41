"""Steering camera agents (seed 000): scouting and tracking cameras stepped together.

:class:`CameraAgents` holds every camera's state as arrays and advances
them one time step at a time (Algorithms 1 and 2): forces from
:mod:`.forces` move positions, torques from :mod:`.torques` turn
orientations. Camera-camera terms and camera-obstacle terms come from
KD-trees, never all pairs.

Modes: a scouting camera wanders and looks along its own wandering
direction (the paper's wandering torque); when one of a running event's
people enters its frustum it starts tracking it, preferring events no other
camera follows. A scout knows only what it sees: nothing it decides reads a
character outside its frustum (tested); the crowd's centre, which the
paper's containing force pulls toward, is the one thing all cameras know. A tracking camera whose event ends scouts again. A camera whose
``crowd:camera:target`` is authored tracks only that event (or agent) while
it runs, and scouts before and after. Every camera starts scouting (an
authored ``crowd:camera:mode`` of tracking means nothing without a target),
from its authored pose with the roll removed and the pitch limited.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..core import model
from . import forces, torques
from .frustum import half_tangents
from .sightlines import CHEST_HEIGHT, HEAD_HEIGHT, Prisms, seen_points
from .orientation import axes, integrate, level_from_forward, matrix_to_quat
from .params import CameraParams

SCOUTING = model.code(model.CAMERA_MODES, "scouting")
TRACKING = model.code(model.CAMERA_MODES, "tracking")
# Cameras never look steeper than this (sin of the pitch): a level head.
_MAX_PITCH_SIN = 0.95
# Heights through its elevation range a tracking camera checks its sight lines from.
_HEIGHTS = 8


@dataclass
class _ObstacleSet:
    """Scenery footprints that occlude or block cameras."""

    tree: cKDTree | None
    xyz: np.ndarray          # (o, 3) footprint centres, half height up
    radius: np.ndarray       # (o,) horizontal radius
    height: np.ndarray       # (o,)
    polygons: list           # (k, 2) ccw convex

    @classmethod
    def of(cls, obstacles: model.Obstacles, min_height: float) -> "_ObstacleSet":
        keep = [i for i in range(len(obstacles)) if obstacles.height[i] >= min_height]
        if not keep:
            return cls(None, np.zeros((0, 3)), np.zeros(0), np.zeros(0), [])
        polys = [np.asarray(obstacles.polygons[i], dtype=np.float64) for i in keep]
        centre = np.array([p.mean(axis=0) for p in polys])
        radius = np.array([np.linalg.norm(p - c, axis=1).max() for p, c in zip(polys, centre)])
        height = np.asarray(obstacles.height, dtype=np.float64)[keep]
        xyz = np.column_stack([centre, 0.5 * height])
        return cls(cKDTree(centre), xyz, radius, height, polys)


class CameraAgents:
    """Every camera agent's state, stepped through a shot.

    Parameters
    ----------
    table : CameraAgentTable
        Initial poses, lenses and limits.
    events : EventTable
        The shot's events (detected and authored).
    obstacles : Obstacles
        Scenery footprints.
    agent_rows : dict[str, int]
        Agent prim path to row (for cameras whose target is an agent).
    params : CameraParams, optional
    seed : int
        Seeds the wandering.
    bounds : (2, 2) float, optional
        [[xmin, ymin], [xmax, ymax]] the cameras stay inside (the scenario's
        walkable area: a museum's cameras stay indoors).
    visible : (n,) bool, optional
        Characters that are rendered; scouts look only at these.
    fps : float
        Frames per second of the shot (time codes to seconds).
    overhead : Obstacles, optional
        Raised scenery (awnings): it hides a tracking camera's event from above.
    """

    def __init__(self, table: model.CameraAgentTable, events: model.EventTable, obstacles: model.Obstacles,
                 agent_rows: dict[str, int] | None = None, params: CameraParams | None = None, seed: int = 0,
                 bounds: np.ndarray | None = None, visible: np.ndarray | None = None, fps: float = 24.0,
                 overhead: model.Obstacles | None = None):
        self.table = table
        self.fps = float(fps)
        self.params = params or CameraParams()
        c = len(table)
        self.p = table.cam_to_world[:, 3, :3].astype(np.float64).copy()
        self.v = np.zeros((c, 3))
        self.q = _level(matrix_to_quat(table.cam_to_world[:, :3, :3])) if c else np.zeros((0, 4))
        self.w = np.zeros((c, 3))
        self.tan_x, self.tan_y = half_tangents(table.focal_length, table.horizontal_aperture,
                                               table.vertical_aperture)
        self.half_x = np.arctan(self.tan_x)
        self.alpha = table.view_angle * 2.0 * self.half_x
        self.beta = np.full(c, np.radians(self.params.beta_deg))
        self.rng = np.random.default_rng(seed)
        fwd = axes(self.q)[0] if c else np.zeros((0, 3))
        self.wander = np.arctan2(fwd[:, 1], fwd[:, 0]) if c else np.zeros(0)
        self.returning = np.zeros(c, bool)     # scouts turning their wandering toward the crowd (_head_back)
        self.visible = None if visible is None else np.asarray(visible, bool)
        self.visible_rows = None if visible is None else np.flatnonzero(visible)
        self.bounds = None if bounds is None else np.asarray(bounds, dtype=np.float64)
        self.events = list(events)
        self.n_shot_events = len(self.events)
        # Authored targets: an event of the shot, or an agent followed as a one-member event.
        self.pinned = np.full(c, -1)
        rows = agent_rows or {}
        paths = {e.path: k for k, e in enumerate(self.events)}
        for k, target in enumerate(table.target):
            if not target:
                continue
            if target in paths:
                self.pinned[k] = paths[target]
            elif target in rows:
                self.pinned[k] = len(self.events)
                self.events.append(_agent_event(target, rows[target]))
                paths[target] = self.pinned[k]
        self.mode = np.full(c, SCOUTING, dtype=np.int8)
        self.tracked = np.full(c, -1)
        self.since = np.zeros(c)
        self.obstacles = _ObstacleSet.of(obstacles, self.params.obstacle_min_height)
        self._prisms = Prisms.of(obstacles, self.params.obstacle_min_height, overhead)
        self._tree = None           # this step's kd-tree of camera positions (forces and torques share it)
        self.time = None
        # Share of its event's people each tracking camera sees, measured once per time code.
        self.seen_share = np.ones(c)
        self.crowded = np.zeros(c)
        self.lift = np.zeros(c)           # share of its elevation range a tracking camera holds, for sight
        # Heights a tracking camera might stand at over its ground point (c, HEIGHTS) and those from which
        # scenery hides the fewest of its event's people.
        self.heights = np.zeros((c, _HEIGHTS))
        self.clear_height = np.ones((c, _HEIGHTS), bool)
        # A tracking camera that cannot see its event from where it stands walks round it to a bearing
        # (radians, from the event's centre) where it can: NaN while it need not.
        self.seek = np.full(c, np.nan)
        self.seek_since = np.zeros(c)
        # Since when a tracking camera has seen none of its event's people (NaN: it sees some), and the
        # event it last gave up for that, refused until a time code.
        self.unseen_since = np.full(c, np.nan)
        self.refused = np.full(c, -1)
        self.refused_until = np.full(c, -np.inf)
        self._seen_time = None
        self._seen_positions = None
        # Everyone's ground velocity (n, 3), m/s, from the last two time codes (what a camera sees of
        # people's motion: where they walk next).
        self._pace_time = None
        self._pace_positions = None
        self.pace = np.zeros((0, 3))

    def __len__(self) -> int:
        return len(self.p)

    def show(self, visible: np.ndarray) -> None:
        """Who is rendered from now on (n,) bool: a replay's people enter and leave."""
        self.visible = np.asarray(visible, bool)
        self.visible_rows = np.flatnonzero(self.visible)

    # ------------------------------------------------------------------ modes
    def _running(self, time: float) -> list[int]:
        """Events under way at ``time`` with someone taking part (someone visible, if visibility is known)."""
        out = []
        for k, e in enumerate(self.events):
            if not e.start - 1e-6 <= time <= e.end + 1e-6:
                continue
            rows = e.members_at(time)
            if len(rows) and (self.visible is None or self.visible[rows].any() or k in self.pinned):
                out.append(k)
        return out

    def _event_state(self, k: int, time: float, positions: np.ndarray, core: bool = True):
        """The rows of the event's people a camera frames, their positions (j, 3) and the event's radius
        at ``time``.

        Members nobody can see (invisible leaders) are left out while a visible one takes part. With
        ``core``, an event spread wider than ``frame_radius`` (a crowd fleeing in every direction, whose
        centre is empty ground) is framed by its densest part: the members within ``frame_radius`` of
        the one with the most others that near.
        """
        e = self.events[k]
        rows = e.members_at(time)
        if self.visible is not None:
            shown = rows[self.visible[rows]]
            rows = shown if len(shown) else rows
        pts = positions[rows]
        i = e.sample(time)
        radius = float(e.radius[i]) if i >= 0 and len(e.radius) else 1.0
        reach = self.params.frame_radius
        if core and len(rows) > 2:
            flat = pts[:, :2]
            if np.linalg.norm(flat - flat.mean(axis=0), axis=1).max() > reach:
                counts = cKDTree(flat).query_ball_point(flat, reach, return_length=True)
                keep = np.linalg.norm(flat - flat[np.argmax(counts)], axis=1) <= reach
                rows, pts, radius = rows[keep], pts[keep], min(radius, reach)
        return rows, pts, radius

    def update_modes(self, time: float, positions: np.ndarray) -> None:
        """Drop ended events; scouting cameras pick up events they see (section 4.1)."""
        running = self._running(time)
        alive = set(running)
        ended = (self.tracked >= 0) & ~np.isin(self.tracked, list(alive))
        self.mode[ended], self.tracked[ended] = SCOUTING, -1
        self.lift[self.tracked < 0] = 0.0
        self.seek[self.tracked < 0] = np.nan
        self.unseen_since[self.tracked < 0] = np.nan
        pinned = self.pinned >= 0
        on = pinned & np.isin(self.pinned, list(alive)) & (self.tracked < 0)
        self.mode[on], self.tracked[on], self.since[on] = TRACKING, self.pinned[on], time
        self.seek[on] = np.nan
        followers = np.bincount(self.tracked[self.tracked >= 0], minlength=max(len(self.events), 1))
        # Free to pick: scouts, and trackers that have held a shared event long
        # enough (they may leave it for one nobody follows).
        shared = (self.tracked >= 0) & (followers[np.maximum(self.tracked, 0)] > 1) & (
            time - self.since >= self.params.min_track_seconds * self.fps)
        free = np.flatnonzero(((self.mode == SCOUTING) | shared) & ~pinned)
        if len(free) == 0 or not running:
            return
        # An event is seen when one of its people (a rendered one) is in the camera's frustum within
        # scout_range: what the camera knows of an event is what it sees of it.
        fwd, right, up = axes(self.q[free])
        seen = np.zeros((len(free), len(running)), bool)
        dist = np.full((len(free), len(running)), np.inf)
        moving = self.pace.shape == np.shape(positions)
        for j, k in enumerate(running):
            rows, pts = self._event_state(k, time, positions, core=False)[:2]
            pts = pts + [0.0, 0.0, self.params.look_height]
            d = pts[None] - self.p[free, None]                        # (f, m, 3)
            z = np.einsum("fmk,fk->fm", d, fwd)
            x = np.einsum("fmk,fk->fm", d, right)
            y = np.einsum("fmk,fk->fm", d, up)
            r = np.linalg.norm(d, axis=2)
            inside = (z > 0.5) & (r < self.params.scout_range) & (np.abs(x) <= self.tan_x[free, None] * z) & (
                np.abs(y) <= self.tan_y[free, None] * z)
            framed = inside.sum(axis=1)
            # ... and not behind scenery: a camera does not see through a building, nor takes people it
            # sees walking behind one (where they will be ``occlusion_lookahead`` seconds on) ...
            f_i, m_i = np.nonzero(inside)
            if len(f_i) and len(self._prisms):
                clear = ~self._prisms.blocks(self.p[free[f_i]], pts[m_i])
                if moving:
                    later = pts[m_i] + self.pace[rows[m_i]] * [1.0, 1.0, 0.0] * self.params.occlusion_lookahead
                    clear &= ~self._prisms.blocks(self.p[free[f_i]], later)
                inside[f_i, m_i] = clear
            inside &= ~((self.refused[free] == k) & (time < self.refused_until[free]))[:, None]
            # ... and sees a good part of them: a glimpse of a few of a group walking under an awning is
            # no view of it.
            seen[:, j] = inside.sum(axis=1) >= np.maximum(1, self.params.take_share * framed)
            dist[:, j] = np.where(inside, r, np.inf).min(axis=1)
        run = np.asarray(running)
        for row, cam in enumerate(free):
            cand = np.flatnonzero(seen[row])
            if self.tracked[cam] >= 0:
                cand = cand[followers[run[cand]] == 0]          # only for an event nobody follows
            if len(cand) == 0:
                continue
            # Events no other camera follows first, then the nearest.
            score = followers[run[cand]] * 1e6 + dist[row, cand]
            k = run[cand[np.argmin(score)]]
            if self.tracked[cam] >= 0:
                followers[self.tracked[cam]] -= 1
            self.mode[cam], self.tracked[cam], self.since[cam] = TRACKING, k, time
            self.seek[cam], self.unseen_since[cam] = np.nan, np.nan
            followers[k] += 1

    # ------------------------------------------------------------------- step
    def step(self, time: float, positions: np.ndarray, crowd_centre: np.ndarray, crowd_radius: float,
             dt: float) -> None:
        """Advance every camera by ``dt`` seconds.

        Parameters
        ----------
        time : float
            Time code (for events).
        positions : (n, 3) float
            Every agent's ground position at ``time``, metres.
        crowd_centre : (3,) float
            Centre of the visible crowd (containment).
        crowd_radius : float
            Radius of the visible crowd, metres.
        dt : float
            Seconds.
        """
        if len(self) == 0:
            return
        fwd, right, _ = axes(self.q)
        look, height, force = self._aims(time, positions, fwd, dt, crowd_centre, crowd_radius)
        force += self._forces(look, height, fwd, right, crowd_centre, crowd_radius)
        # Algorithm 1, with Reynolds' limits on force and speed; the crane's vertical move comes first
        # within them (Reynolds' prioritised allocation): a camera rising over people who hide its event
        # is not held down by its horizontal moves. Up to ``crane_share`` of the force: a crane move
        # taking all of it would leave a camera coasting into people walking at it.
        t = self.table
        share = self.params.crane_share
        force = _clamp_vertical_first(self.params.force_gain * force, t.max_force, share)
        force = _clamp_vertical_first(self._brake_at_bounds(force, dt), t.max_force, share)
        self.v = _clamp(self.v + force * dt, t.max_speed)
        self.p = self.p + self.v * dt
        self._constrain()
        # Algorithm 2: torques -> rotational velocity -> orientation.
        tau = self._torques(look, fwd, right)
        self.w = _clamp(self.w + self.params.angular_gain * tau * dt, t.max_angular_speed)
        self.q = _level(integrate(self.q, self.w, dt))

    def _aims(self, time: float, positions: np.ndarray, fwd: np.ndarray, dt: float, crowd_centre: np.ndarray,
              crowd_radius: float):
        """Where each camera looks, how high it wants to be, and its framing or wandering force.

        Returns
        -------
        look : (c, 3) float64
            Aim points: the tracked event's centre at chest height, or the
            character a scout looks at.
        height : (c,) float64
            Desired heights (crane shots for large events).
        force : (c, 3) float64
            The framing force (tracking) or the wandering force (scouting).
        """
        prm, t = self.params, self.table
        c = len(self)
        force = np.zeros((c, 3))
        self._measure_sight(time, positions)       # may send a camera that lost its event back to scouting
        self._keep_pace(time, positions)
        tracking = np.flatnonzero(self.tracked >= 0)
        scouting = np.flatnonzero(self.tracked < 0)
        self.returning[tracking] = False            # a scout again later wanders afresh
        look = self.p + fwd * prm.wander_look_distance
        height = 0.5 * (t.elevation[:, 0] + t.elevation[:, 1])
        if len(tracking):
            a = np.zeros((len(tracking), 2))
            b = np.zeros((len(tracking), 2))
            n_members = np.zeros(len(tracking))
            radius = np.zeros(len(tracking))
            pace = np.zeros((len(tracking), 3))
            # Where each camera frames its event from: near where it stands, or, while it walks round
            # the event to see it, near the bearing it seeks.
            near = self.p[tracking, :2].copy()
            for j, cam in enumerate(tracking):
                rows, pts, r = self._event_state(self.tracked[cam], time, positions)
                if np.isfinite(self.seek[cam]):
                    near[j] = self._seek_point(cam, pts[:, :2].mean(axis=0))
                a[j], b[j] = _extremes(near[j], pts[:, :2])
                look[cam] = pts.mean(axis=0) + np.array([0.0, 0.0, prm.look_height])
                n_members[j], radius[j] = len(pts), r
                pace[j] = self.pace[rows].mean(axis=0)          # the event's people's mean velocity
            # An event's area is framed too: one visible member of a wide authored event is not a close-up.
            width = np.maximum(prm.min_frame_width, radius)
            goal = self._framing_goal(tracking, near, a, b, width, look[tracking, :2])
            goal3 = np.column_stack([goal, self.p[tracking, 2]])
            f = forces.arrival(self.p[tracking], goal3, self.v[tracking] * [1, 1, 0], t.max_speed[tracking],
                               t.arrival_distance[tracking])
            # People walking at the camera: it backs away as fast as they come (Reynolds' offset pursuit,
            # for the approach only; an event walking off is followed by the arrival alone).
            back = _unit(self.p[tracking, :2] - look[tracking, :2])
            coming = np.maximum(np.einsum("ij,ij->i", pace[:, :2], back), 0.0)
            f[:, :2] += coming[:, None] * back
            force[tracking] += prm.w_framing * f
            height[tracking] = forces.crane_height(n_members, radius, t.elevation[tracking], prm.crane_members,
                                                   prm.crane_gain)
            height[tracking] = self._sight_height(tracking, look, height[tracking], dt)
        if len(scouting):
            force[scouting] += self._scout(scouting, time, positions, look, crowd_centre, crowd_radius, dt)
        return look, height, force

    def _scout(self, scouting: np.ndarray, time: float, positions: np.ndarray, look: np.ndarray,
               crowd_centre: np.ndarray, crowd_radius: float, dt: float) -> np.ndarray:
        """(k, 3) the wandering force of scouting cameras ``scouting`` (k,); sets their aim points in
        ``look`` (c, 3)."""
        prm, t = self.params, self.table
        jitter = self.rng.normal(0.0, prm.wander_jitter * np.sqrt(dt), len(scouting))
        # One heading back turns steadily: the jitter (86 degrees a second) would outrun its turn.
        back = self._head_back(scouting, crowd_centre, crowd_radius, dt)
        self.wander[scouting[~back]] += jitter[~back]
        wander = prm.w_wander * forces.wandering(self.v[scouting], self.wander[scouting], t.max_speed[scouting],
                                                 prm.wander_speed)
        # The wandering torque (section 4.4): aim at a point along the camera's own wandering
        # direction, at people's height; a scout knows nobody it has not seen.
        ahead = np.column_stack([np.cos(self.wander[scouting]), np.sin(self.wander[scouting]),
                                 np.zeros(len(scouting))])
        look[scouting] = self.p[scouting] * [1.0, 1.0, 0.0] + prm.wander_look_distance * ahead + [
            0.0, 0.0, prm.look_height]
        # A camera told to film an event (an authored target) turns to the people who will take part
        # (or, if it names none, where it will begin) in the last ``ready_seconds`` before it does:
        # it is not still turning round when it starts.
        for cam in scouting[self.pinned[scouting] >= 0]:
            e = self.events[self.pinned[cam]]
            if not e.start - prm.ready_seconds * self.fps <= time < e.start:
                continue
            rows = e.members_at(e.start)
            if self.visible is not None and self.visible[rows].any():
                rows = rows[self.visible[rows]]
            if len(rows):
                look[cam] = positions[rows].mean(axis=0) + [0.0, 0.0, prm.look_height]
            elif len(e.center):
                look[cam] = e.center[0] + [0.0, 0.0, prm.look_height]
        return wander

    def _framing_goal(self, tracking: np.ndarray, near: np.ndarray, a: np.ndarray, b: np.ndarray,
                      width: np.ndarray, centre: np.ndarray) -> np.ndarray:
        """(k, 2) where tracking cameras ``tracking`` go to frame their events: the viewpoint of the
        framing range (section 4.3) nearest ``near`` (k, 2) for extremes ``a``, ``b`` (k, 2) and ``width``
        (k,), pushed back from the event's ``centre`` (k, 2) as the rules below say."""
        prm = self.params
        goal = forces.framing_target(near, a, b, self.alpha[tracking], self.beta[tracking], width)
        out = goal - centre
        reach = np.linalg.norm(out, axis=1)
        # Deep inside the range (people walked at the camera), the nearest viewpoint may lie on either
        # side and flip from one step to the next, holding the camera over them: it steps straight back.
        mine = near - centre
        inside = np.linalg.norm(mine, axis=1) < 0.5 * reach
        back = _unit(mine)
        out = np.where(inside[:, None], back * reach[:, None], out)
        # A craned camera stands back far enough to look at its event less steeply than
        # ``steepest_deg`` (the framing range is drawn for a level view).
        least = (self.p[tracking, 2] - prm.look_height) / np.tan(np.radians(prm.steepest_deg))
        away = np.where(reach[:, None] > 1e-6, out / np.maximum(reach, 1e-9)[:, None],
                        _unit(self.p[tracking, :2] - centre))
        return np.where((reach < least)[:, None], centre + away * least[:, None], centre + out)

    def _keep_pace(self, time: float, positions: np.ndarray) -> None:
        """``pace`` (n, 3): everyone's velocity over the last time codes, m/s (zero on the first)."""
        if self._pace_time is not None and time == self._pace_time:
            return
        positions = np.asarray(positions, dtype=np.float64)
        last, previous = self._pace_time, self._pace_positions
        self._pace_time, self._pace_positions = time, positions.copy()
        if previous is None or previous.shape != positions.shape or time <= last:
            self.pace = np.zeros_like(positions)
            return
        self.pace = (positions - previous) / (time - last) * self.fps

    def _sight_height(self, tracking: np.ndarray, look: np.ndarray, height: np.ndarray, dt: float) -> np.ndarray:
        """(k,) the heights tracking cameras ``tracking`` stand at for sight, from the ``height`` (k,) their
        framing wants: over people, under or past scenery, never too steep above their event."""
        prm, t = self.params, self.table
        # Beyond the paper: a camera that sees under half its event's people (hidden by others or by
        # scenery) cranes up, toward the top of its elevation range, to look over them.
        hidden = np.maximum(np.clip(1.5 * (1.0 - self.seen_share[tracking]), 0.0, 1.0),
                            0.75 * self.crowded[tracking])
        # Up at once, down slowly: coming down the moment the view clears would lose it again.
        self.lift[tracking] = np.maximum(hidden, self.lift[tracking] - dt / prm.lift_hold)
        lo, hi = t.elevation[tracking, 0], t.elevation[tracking, 1]
        top = np.maximum(lo, hi - 0.5)          # short of the ceiling: arriving, not stopped by it
        height = np.maximum(height, lo + self.lift[tracking] * (top - lo))
        # No higher than lets it look at its event less steeply than ``steepest_deg`` (a camera right
        # over its event cannot pan with people walking under it).
        flat = np.linalg.norm(look[tracking, :2] - self.p[tracking, :2], axis=1)
        steep = prm.look_height + np.maximum(flat, 1.0) * np.tan(np.radians(prm.steepest_deg))
        height = np.maximum(lo, np.minimum(height, steep))
        # Where scenery hides the event from some heights (an awning over it, tree crowns or a roof in
        # the way), the camera stands at the clear height nearest the one it wants, whatever the lift.
        rows = np.flatnonzero(~self.clear_height[tracking].all(axis=1))
        blocked = tracking[rows]
        if len(blocked):
            gap = np.where(self.clear_height[blocked], np.abs(self.heights[blocked] - height[rows, None]),
                           np.inf)
            height[rows] = self.heights[blocked, np.argmin(gap, axis=1)]
        return height

    def _measure_sight(self, time: float, positions: np.ndarray) -> None:
        """``seen_share``: for each tracking camera, the share of its event's (rendered) people it sees
        unhidden by scenery or by the people round the event, now and where everyone will be in a
        moment if they walk on (a crane move takes time: the camera starts rising before a crowd walks
        in front of its event); ``crowded``: how many others stand round its event (ten or more: 1).

        Every ``sight_interval`` seconds, on at most ``sight_people`` of an event's people and the
        ``sight_occluders`` nearest others round it: the cost stays flat whatever the crowd's size.
        """
        prm = self.params
        if self._seen_time is not None and 0 <= time - self._seen_time < prm.sight_interval * self.fps - 1e-6:
            return
        last, self._seen_time = self._seen_time, time
        previous, self._seen_positions = self._seen_positions, np.asarray(positions, dtype=np.float64).copy()
        self.seen_share[:] = 1.0
        self.crowded[:] = 0.0
        self.clear_height[:] = True
        tracking = np.flatnonzero(self.tracked >= 0)
        if len(tracking) == 0 or len(positions) == 0:
            return
        # Where everyone, the camera too, will be over the next moments if they move on (seconds ahead,
        # then the positions): a passer-by crossing a sight line between two checks is caught too.
        moments = [(0.0, positions)]
        if previous is not None and previous.shape == positions.shape and time > last:
            velocity = (positions - previous) / (time - last) * self.fps          # per second
            for s in (prm.sight_interval / 2, prm.sight_interval, *(np.array([1 / 3, 2 / 3, 1.0]) *
                                                                    prm.occlusion_lookahead)):
                moments.append((float(s), positions + velocity * s))
        occluders = np.zeros(len(positions), bool)
        occluders[self.visible_rows if self.visible_rows is not None else slice(None)] = True
        occ_rows = np.flatnonzero(occluders)
        tree = cKDTree(positions[occ_rows, :2]) if len(occ_rows) else None
        cams, owners, cand_pair, cand_row = [], [], [], []
        groups = []                         # (camera, its people checked, who may hide them, event centre)
        n_pairs = 0
        for cam in tracking:
            rows, pts, r = self._event_state(self.tracked[cam], time, positions)
            rows = rows[occluders[rows]]
            if len(rows) == 0 or tree is None:
                continue
            if len(rows) > prm.sight_people:
                rows = rows[np.linspace(0, len(rows) - 1, prm.sight_people).round().astype(int)]
            centre = pts[:, :2].mean(axis=0)
            self.heights[cam], self.clear_height[cam] = self._clear_heights(cam, positions[rows])
            dist, idx = tree.query(centre, k=min(prm.sight_occluders, len(occ_rows)), distance_upper_bound=r + 3.0)
            near = occ_rows[np.atleast_1d(idx)[np.isfinite(np.atleast_1d(dist))]]
            self.crowded[cam] = min(1.0, max(0, len(near) - len(rows)) / 10.0)
            groups.append((cam, rows, near, centre))
            cams.append(np.full(len(rows), cam))
            owners.append(rows)
            pair = n_pairs + np.arange(len(rows))
            cand_pair.append(np.repeat(pair, len(near)))
            cand_row.append(np.tile(near, len(rows)))
            n_pairs += len(rows)
        if not cams:
            return
        cam_of, owner = np.concatenate(cams), np.concatenate(owners)
        candidates = (np.concatenate(cand_pair), np.concatenate(cand_row))
        fwd, right, up = axes(self.q)
        t = self.table
        seen = np.ones(len(owner), bool)
        for ahead, where in moments:
            eye = self.p[cam_of] + ahead * self.v[cam_of]
            view = (right[cam_of], up[cam_of], fwd[cam_of]) if ahead == 0.0 else self._turned(eye, cam_of,
                                                                                                where[owner])
            seen_then = seen_points(eye, view, self.tan_x[cam_of], self.tan_y[cam_of], t.near[cam_of], t.far[cam_of],
                                    where, owner, candidates, self._prisms)
            if ahead == 0.0:
                seen_now = np.bincount(cam_of, weights=seen_then, minlength=len(self))
            seen &= seen_then
        counted = np.unique(cam_of)
        self.seen_share[counted] = (np.bincount(cam_of, weights=seen, minlength=len(self))[counted]
                                    / np.bincount(cam_of, minlength=len(self))[counted])
        self._give_up(time, counted, seen_now[counted] > 0)
        self._seek_sight(time, groups, moments)

    def _turned(self, eye: np.ndarray, cam_of: np.ndarray, people: np.ndarray) -> tuple:
        """(right, up, forward), three (m, 3): each camera ``cam_of`` (m,) at ``eye`` (m, 3) turned to the
        mean of its ``people`` (m, 3) ground positions. Ahead, a camera will have turned to follow its
        people: only what hides them counts (a walker coming at it leaves its present frame at the
        bottom; that is no reason to crane)."""
        count = np.maximum(np.bincount(cam_of, minlength=len(self)), 1)
        centre = np.column_stack([np.bincount(cam_of, weights=people[:, k], minlength=len(self))
                                  for k in range(3)]) / count[:, None]
        fwd, right, up = axes(_level_towards(centre[cam_of] + [0.0, 0.0, self.params.look_height] - eye))
        return right, up, fwd

    def _give_up(self, time: float, cams: np.ndarray, seeing: np.ndarray) -> None:
        """Tracking cameras ``cams`` that have seen none of their event's people for ``give_up_seconds``
        (behind a building they cannot fly round) leave it and scout again; they do not take it again
        for ``give_up_seconds`` more."""
        prm = self.params
        self.unseen_since[cams[seeing]] = np.nan
        fresh = cams[~seeing & np.isnan(self.unseen_since[cams])]
        self.unseen_since[fresh] = time
        done = cams[~seeing & (time - self.unseen_since[cams] >= prm.give_up_seconds * self.fps - 1e-6)]
        done = done[self.pinned[done] < 0]
        if len(done) == 0:
            return
        self.refused[done], self.refused_until[done] = self.tracked[done], time + prm.give_up_seconds * self.fps
        self.mode[done], self.tracked[done] = SCOUTING, -1
        self.lift[done], self.seek[done], self.unseen_since[done] = 0.0, np.nan, np.nan

    def _clear_heights(self, cam: int, people: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(HEIGHTS,) heights over camera ``cam``'s ground point, through its elevation range, and whether
        from each scenery hides as few of ``people`` ((k, 3) ground positions; chest and head) as from
        any. Under an awning a camera must stand below its underside; far from it, it may stand high and
        look under its edge; behind tree crowns it looks under or over them."""
        lo, hi = self.table.elevation[cam]
        heights = np.linspace(max(lo, 0.3), max(lo, hi - 0.5), _HEIGHTS)
        if len(self._prisms) == 0:
            return heights, np.ones(_HEIGHTS, bool)
        k = len(people)
        # From its ground point now and where it flies in ``occlusion_lookahead``: a camera closing in on
        # people under an awning starts down before the awning's edge is between them.
        body = np.concatenate([people + [0.0, 0.0, CHEST_HEIGHT], people + [0.0, 0.0, HEAD_HEIGHT]])
        clear = np.zeros(_HEIGHTS)
        for ground in (self.p[cam, :2], self.p[cam, :2] + self.v[cam, :2] * self.params.occlusion_lookahead):
            eye = np.repeat(np.column_stack([np.tile(ground, (_HEIGHTS, 1)), heights]), 2 * k, 0)
            hidden = self._prisms.blocks(eye, np.tile(body, (_HEIGHTS, 1))).reshape(_HEIGHTS, 2, k).all(axis=1)
            clear += (~hidden).sum(axis=1)
        return heights, clear == clear.max()

    def _seek_point(self, cam: int, centre: np.ndarray) -> np.ndarray:
        """(2,) the point at camera ``cam``'s present distance from its event's ``centre`` on the bearing it
        seeks."""
        r = max(float(np.linalg.norm(self.p[cam, :2] - centre)), 1.0)
        return centre + r * np.array([np.cos(self.seek[cam]), np.sin(self.seek[cam])])

    def _seek_sight(self, time: float, groups: list, moments: list) -> None:
        """Beyond the paper: a tracking camera that sees under ``seek_below`` of its event's people, and
        cannot crane over those in the way (an awning above, or its elevation range spent), walks round
        the event to where it would see more.

        Viewpoints at the camera's distance and height, on bearings ``seek_bearings`` away from its own,
        aimed at the event, are checked as the camera checks itself (now and a moment ahead); the best
        one, a turn of the bearing costing ``seek_turn_cost`` of the people seen per half turn, is sought
        when it sees ``seek_gain`` more than where the camera stands. A camera stops seeking at the
        bearing, when its view clears, or after ``seek_seconds``.
        """
        prm, t = self.params, self.table
        for cam, _, _, centre in groups:
            if not np.isfinite(self.seek[cam]):
                continue
            d = self.p[cam, :2] - centre
            off = np.angle(np.exp(1j * (np.arctan2(d[1], d[0]) - self.seek[cam])))
            if (abs(off) < np.radians(10.0) or self.seen_share[cam] >= 1.0 - 1e-9
                    or time - self.seek_since[cam] > prm.seek_seconds * self.fps):
                self.seek[cam] = np.nan
        wanting = [g for g in groups if self.seen_share[g[0]] < prm.seek_below and not np.isfinite(self.seek[g[0]])]
        if not wanting:
            return
        turns = np.radians(np.concatenate([[0.0], np.asarray(prm.seek_bearings, dtype=np.float64)]))
        k_n = len(turns)
        eyes, looks, owners, cand_pair, cand_row, view_of, viewpoints = [], [], [], [], [], [], []
        n_pairs = 0
        for g, (cam, rows, near, centre) in enumerate(wanting):
            d = self.p[cam, :2] - centre
            r = max(float(np.linalg.norm(d)), 1.0)
            bearing = np.arctan2(d[1], d[0]) + turns
            eye = np.column_stack([centre + r * np.column_stack([np.cos(bearing), np.sin(bearing)]),
                                   np.full(k_n, self.p[cam, 2])])
            look = np.append(centre, self.params.look_height)
            viewpoints.append(eye)
            for k in range(k_n):
                eyes.append(np.repeat(eye[k:k + 1], len(rows), axis=0))
                looks.append(np.repeat(look[None], len(rows), axis=0))
                owners.append(rows)
                pair = n_pairs + np.arange(len(rows))
                cand_pair.append(np.repeat(pair, len(near)))
                cand_row.append(np.tile(near, len(rows)))
                view_of.append(np.full(len(rows), g * k_n + k))
                n_pairs += len(rows)
        eye, owner = np.concatenate(eyes), np.concatenate(owners)
        fwd, right, up = axes(_level_towards(np.concatenate(looks) - eye))
        cam_of = np.repeat([g[0] for g in wanting], [k_n * len(g[1]) for g in wanting])
        candidates = (np.concatenate(cand_pair), np.concatenate(cand_row))
        seen = np.ones(len(owner), bool)
        for _, where in moments:
            seen &= seen_points(eye, (right, up, fwd), self.tan_x[cam_of], self.tan_y[cam_of], t.near[cam_of],
                                t.far[cam_of], where, owner, candidates, self._prisms)
        view = np.concatenate(view_of)
        share = (np.bincount(view, weights=seen, minlength=len(wanting) * k_n)
                 / np.maximum(np.bincount(view, minlength=len(wanting) * k_n), 1)).reshape(len(wanting), k_n)
        usable = self._usable(np.concatenate(viewpoints)).reshape(len(wanting), k_n)
        score = np.where(usable, share - prm.seek_turn_cost * np.abs(turns) / np.pi, -np.inf)
        best = np.argmax(score, axis=1)
        for g, (cam, _, _, centre) in enumerate(wanting):
            k = best[g]
            if k == 0 or share[g, k] < share[g, 0] + prm.seek_gain:
                continue
            d = self.p[cam, :2] - centre
            self.seek[cam] = np.arctan2(d[1], d[0]) + turns[k]
            self.seek_since[cam] = time

    def _usable(self, points: np.ndarray) -> np.ndarray:
        """(k,) bool: camera positions (k, 3) inside the scene's bounds and not inside scenery."""
        ok = np.ones(len(points), bool)
        if self.bounds is not None:
            margin = self.params.bounds_margin
            ok &= ((points[:, :2] >= self.bounds[0] + margin) & (points[:, :2] <= self.bounds[1] - margin)).all(axis=1)
        obs = self.obstacles
        if obs.tree is not None:
            for k, near in enumerate(obs.tree.query_ball_point(points[:, :2], r=float(obs.radius.max()))):
                for o in near:
                    if points[k, 2] <= obs.height[o] + self.params.obstacle_clearance and _push_out(
                            obs.polygons[o], points[k, :2], self.params.obstacle_clearance) is not None:
                        ok[k] = False
        return ok

    def _forces(self, look, height, fwd, right, crowd_centre, crowd_radius) -> np.ndarray:
        """(c, 3) obstacle avoidance, crane, separation and containment (section 4.3), weighted."""
        prm, t = self.params, self.table
        vmax = t.max_speed
        f_obs, blocking = forces.obstacle_avoidance(
            self.p, self.v, fwd, right, look, vmax, self.tan_x, self.obstacles.tree, self.obstacles.xyz,
            self.obstacles.radius, prm.obstacle_range, prm.obstacle_clearance)
        force = prm.w_obstacle * f_obs
        # Beyond Algorithm 3's sidestep: where the elevation range allows, crane up over what is in the way.
        over = blocking + prm.obstacle_clearance + 1.0
        # (Not for a tracking camera whose sight lines chose its height: they know what over is worth.)
        chosen = (self.tracked >= 0) & ~self.clear_height.all(axis=1)
        height = np.where((blocking > 0) & (over <= t.elevation[:, 1]) & ~chosen, np.maximum(height, over), height)
        force += prm.w_elevation * forces.elevation(self.p, self.v, height, vmax)
        self._tree = cKDTree(self.p)
        pairs = self._tree.query_pairs(float(t.separation_distance.max()), output_type="ndarray")
        force += prm.w_separation * forces.separation(self.p, self.v, fwd, right, vmax, t.separation_distance, pairs)
        force += prm.w_containment * forces.containment(self.p, self.v, crowd_centre,
                                                        crowd_radius + prm.contain_margin, vmax)
        return force

    def _torques(self, look, fwd, right) -> np.ndarray:
        """(c, 3) aiming (or wandering) and camera-avoidance torques (section 4.4), weighted."""
        prm, t = self.params, self.table
        q_desired = _level_towards(look - self.p)
        tau = prm.w_aim * torques.aiming(self.q, q_desired, self.w, t.max_angular_speed, t.aim_threshold)
        scouting = self.tracked < 0
        tau[scouting] *= prm.w_wander_torque / max(prm.w_aim, 1e-9)
        # Algorithm 6 tests the frusta between near and far planes; clipping ranges
        # (0.1 to 1000 m) would make every pair collide, so a shared view counts
        # from avoid_near to avoid_range. Pairs come from this step's camera kd-tree.
        pairs = self._tree.query_pairs(2.0 * prm.avoid_range, output_type="ndarray")
        avoid = torques.avoidance(self.p, fwd, right, self.half_x, self.w, t.max_angular_speed, pairs,
                                  prm.avoid_near, prm.avoid_range)
        # Beyond the paper: a tracking camera pans away from another's view only while its event stays
        # well inside its frame (its centre within half the half-angle of the axis); further, it would
        # pan its event out of the picture.
        to_look = look - self.p
        off = np.arccos(np.clip(np.einsum("ij,ij->i", fwd, to_look)
                                / np.maximum(np.linalg.norm(to_look, axis=1), 1e-9), -1.0, 1.0))
        tau += prm.w_avoid * avoid * np.where(scouting | (off < 0.5 * self.half_x), 1.0, 0.0)[:, None]
        return tau

    def _head_back(self, cams: np.ndarray, centre: np.ndarray, radius: float, dt: float) -> np.ndarray:
        """Turn the wandering direction of scouts toward the crowd's centre while they are beyond the
        containment radius (the paper's containing force brings the camera back, and its wandering
        torque looks where it goes), while it points out of the scene's bounds (a scout would
        otherwise stand at the edge looking out), or while scenery hides the point it looks at (a
        room's wall, a partition: it would film the wall; scenery is known, people are not), unless
        scenery hides the way to the centre as well. Once
        turning, a scout turns until it wanders toward the centre: stopped as soon as the wall left
        its look point, it would look along the wall. Returns which of ``cams`` (k,) bool turned."""
        prm = self.params
        d = centre[None, :2] - self.p[cams, :2]
        back = (np.linalg.norm(d, axis=1) > radius + prm.contain_margin) | self.returning[cams]
        ahead = self.p[cams, :2] + prm.wander_look_distance * np.column_stack(
            [np.cos(self.wander[cams]), np.sin(self.wander[cams])])
        if self.bounds is not None:
            lo, hi = self.bounds[0] + prm.bounds_margin, self.bounds[1] - prm.bounds_margin
            back |= ((ahead < lo) | (ahead > hi)).any(axis=1)
        if len(self._prisms):
            # Only toward a centre it can see over: one behind scenery too (a kiosk the crowd walks round)
            # would hold the scout staring at the kiosk.
            height = np.full((len(cams), 1), prm.look_height)
            hidden = np.flatnonzero(self._prisms.blocks(self.p[cams], np.hstack([ahead, height])))
            toward = self.p[cams[hidden], :2] + prm.wander_look_distance * _unit(d[hidden])
            back[hidden] |= ~self._prisms.blocks(self.p[cams[hidden]], np.hstack([toward, height[hidden]]))
        if back.any():
            turning, d = cams[back], d[back]
            turn = np.angle(np.exp(1j * (np.arctan2(d[:, 1], d[:, 0]) - self.wander[turning])))
            step = prm.wander_turn * dt
            self.wander[turning] += np.clip(turn, -step, step)
            self.returning[turning] = np.abs(turn) > step
        return back

    def _brake_at_bounds(self, force: np.ndarray, dt: float) -> np.ndarray:
        """``force`` (c, 3) changed so that no camera heads for the scene's bounds faster than it can stop
        (at ``bounds_braking`` of its maxForce) before their margin."""
        if self.bounds is None:
            return force
        margin = self.params.bounds_margin
        lo, hi = self.bounds[0] + margin, self.bounds[1] - margin
        brake = self.params.bounds_braking * self.table.max_force[:, None]
        v = self.v[:, :2] + force[:, :2] * dt
        p = self.p[:, :2] + v * dt
        fastest_out_hi = np.sqrt(2.0 * brake * np.maximum(hi - p, 0.0))
        fastest_out_lo = np.sqrt(2.0 * brake * np.maximum(p - lo, 0.0))
        limited = np.clip(v, -fastest_out_lo, fastest_out_hi)
        force = force.copy()
        force[:, :2] += (limited - v) / dt
        return force

    def _constrain(self) -> None:
        """Keep cameras inside their elevation range and out of scenery (pushed to its outline)."""
        t = self.table
        self.p[:, 2] = np.clip(self.p[:, 2], np.maximum(t.elevation[:, 0], 0.3), t.elevation[:, 1])
        if self.bounds is not None:
            margin = self.params.bounds_margin
            lo, hi = self.bounds[0] + margin, self.bounds[1] - margin
            out = (self.p[:, :2] < lo) | (self.p[:, :2] > hi)
            self.p[:, :2] = np.clip(self.p[:, :2], lo, np.maximum(lo, hi))
            self.v[:, :2][out] = 0.0
        obs = self.obstacles
        if obs.tree is None:
            return
        clearance = self.params.obstacle_clearance
        lists = obs.tree.query_ball_point(self.p[:, :2], r=float(obs.radius.max()) + clearance)
        for cam, near in enumerate(lists):
            for o in near:
                if self.p[cam, 2] > obs.height[o] + clearance:
                    continue                        # flying over it
                pushed = _push_out(obs.polygons[o], self.p[cam, :2], clearance)
                if pushed is not None:
                    normal = pushed - self.p[cam, :2]
                    normal /= max(np.linalg.norm(normal), 1e-9)
                    self.p[cam, :2] = pushed
                    inward = min(0.0, float(self.v[cam, :2] @ normal))
                    self.v[cam, :2] -= inward * normal

    # ---------------------------------------------------------------- output
    def cam_to_world(self) -> np.ndarray:
        """(c, 4, 4) current camera-to-world matrices (row vectors)."""
        from ..character.rig import quat_to_matrix

        m = np.zeros((len(self), 4, 4))
        m[:, :3, :3] = quat_to_matrix(self.q)
        m[:, 3, :3] = self.p
        m[:, 3, 3] = 1.0
        return m

    def tracked_paths(self) -> list[str]:
        return [self.events[k].path if k >= 0 else "" for k in self.tracked]


def _agent_event(path: str, row: int) -> model.Event:
    """An agent tracked by an authored target, as an event that always runs."""
    return model.Event(path, model.code(model.EVENT_KINDS, "interaction"), -np.inf, np.inf,
                       np.array([row], np.int32), np.array([0.0]), np.ones((1, 1), bool), np.zeros((1, 3)),
                       np.array([1.0]))


def _extremes(camera_xy: np.ndarray, pts: np.ndarray):
    from .framing import extreme_pair

    if len(pts) == 1:
        return pts[0], pts[0]
    return extreme_pair(camera_xy, pts)


def _clamp_vertical_first(v: np.ndarray, limit: np.ndarray, share: float) -> np.ndarray:
    """(c, 3) ``v`` within ``limit`` (c,) in length, its vertical part (up to ``share`` of the limit) kept
    first, the horizontal one shortened to what is left."""
    out = v.copy()
    out[:, 2] = np.clip(v[:, 2], -share * limit, share * limit)
    room = np.sqrt(np.maximum(limit ** 2 - out[:, 2] ** 2, 0.0))
    out[:, :2] = _clamp(v[:, :2], room)
    return out


def _unit(v: np.ndarray) -> np.ndarray:
    """(c, k) ``v`` normalised; zero rows become the first axis."""
    n = np.linalg.norm(v, axis=1, keepdims=True)
    first = np.zeros_like(v)
    first[:, 0] = 1.0
    return np.where(n > 1e-9, v / np.maximum(n, 1e-12), first)


def _clamp(v: np.ndarray, limit: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=1)
    return v * np.minimum(1.0, limit / np.maximum(n, 1e-12))[:, None]


def _level_towards(direction: np.ndarray) -> np.ndarray:
    d = direction / np.maximum(np.linalg.norm(direction, axis=1, keepdims=True), 1e-9)
    return level_from_forward(_limit_pitch(d))


def _limit_pitch(f: np.ndarray) -> np.ndarray:
    f = f.copy()
    z = np.clip(f[:, 2], -_MAX_PITCH_SIN, _MAX_PITCH_SIN)
    flat = f[:, :2]
    n = np.linalg.norm(flat, axis=1, keepdims=True)
    flat = np.where(n > 1e-9, flat / np.maximum(n, 1e-12), [1.0, 0.0])
    f[:, :2] = flat * np.sqrt(1.0 - z ** 2)[:, None]
    f[:, 2] = z
    return f


def _level(q: np.ndarray) -> np.ndarray:
    """Roll removed and pitch limited."""
    return level_from_forward(_limit_pitch(axes(q)[0]))


def _push_out(poly: np.ndarray, p: np.ndarray, clearance: float):
    """Nearest point ``clearance`` outside a convex ccw polygon if ``p`` is closer than that, else None."""
    a = poly
    b = np.roll(poly, -1, axis=0)
    e = b - a
    length = np.maximum(np.linalg.norm(e, axis=1), 1e-12)
    outward = np.stack([e[:, 1], -e[:, 0]], 1) / length[:, None]     # ccw: the right of each edge is out
    signed = np.einsum("ij,ij->i", p - a, outward)
    if signed.max() >= clearance:
        return None                            # outside, with room to spare
    k = int(np.argmax(signed))
    return p + (clearance - signed[k]) * outward[k]


