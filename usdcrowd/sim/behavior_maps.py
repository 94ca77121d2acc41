"""Behavior maps (seed 004): painted or generated fields, and reactions to them.

A map does not dictate a behaviour; what an agent does depends on the map's
value *and* the agent's attributes:

- damage (explosion around ``origin`` within ``radius`` from ``start_time``;
  volcano around its crater, spreading over :data:`params.VOLCANO_SPREAD_TIME`;
  or painted): agents inside are wounded or die, by per-agent thresholds
  drawn from the seed (resilience varies);
- civilians within the alarm radius flee (``fear_response`` flee: up the
  geodesic distance from the threat, so around walls) or freeze (paralysed);
- security officers pursue attackers within reach, the others form a
  protective line between the threat and the civilians (the seed's volcano
  scene);
- attackers flee security (evade) once the threat is on;
- herbivores and ants seek food (down the distance map to food cells) and
  graze on it; birds seek rest places; herbivores evade predators, predators
  pursue herbivores;
- forbidden areas are walls (rasterised in :mod:`usdcrowd.sim.grid`); the
  height layer is handled in :mod:`usdcrowd.sim.paths`.

A reaction is blended with the agent's normal desired velocity by
``map_influence * layer.influence`` (the seed's "size of the influence of the
behavior maps").
"""

from __future__ import annotations

import numpy as np

from ..core.model import (BEHAVIORS, CHARACTER_TYPES, FEAR_RESPONSES, HEALTH_STATES, PERSONALITIES, BehaviorField,
                          Scenario, code)
from . import params as P
from .distance_maps import DistanceMaps, sample_grid
from .grid import field_is, generator_is
from .kernels import blend_rows, flee_blast, radial_falloff, within_reach, worsen_health
from .neighbors import nearest_of
from .steering import arrive, evade, pursue, unit

_B = {b: np.int8(code(BEHAVIORS, b)) for b in BEHAVIORS}
_OK, _WOUNDED, _DEAD = (np.int8(code(HEALTH_STATES, h)) for h in HEALTH_STATES)


class MapLayer:
    """A behavior field that can be sampled at any time, painted or generated.

    Parameters
    ----------
    field : BehaviorField
    to_seconds : callable
        Converts a time code to seconds since the shot start.
    rng : numpy.random.Generator
        Draws the patches of a generated food layer.
    """

    def __init__(self, field: BehaviorField, to_seconds, rng):
        self.field = field
        self.origin = np.asarray(field.origin, dtype=np.float64)[:2]
        self.radius = max(float(field.radius), 1e-3)
        self.start = to_seconds(field.start_time)
        self.influence = float(np.clip(field.influence, 0.0, 1.0))
        self.kind = next(g for g in ("painted", "explosion", "volcano", "food") if generator_is(field, g))
        if self.kind == "painted" and field.values is None:
            raise ValueError(f"{field.path}: painted behavior layer has no values")
        if self.kind == "food":
            k = P.FOOD_PATCHES
            r = self.radius * np.sqrt(rng.uniform(0, 1, k))
            a = rng.uniform(0, 2 * np.pi, k)
            self.patches = self.origin + np.stack([r * np.cos(a), r * np.sin(a)], axis=1)

    def active(self, t: float) -> bool:
        return self.kind == "painted" or t >= self.start

    def current_radius(self, t: float) -> float:
        if self.kind == "volcano":
            return self.radius * float(np.clip((t - self.start) / P.VOLCANO_SPREAD_TIME, 0.0, 1.0))
        return self.radius

    def sample(self, x: np.ndarray, y: np.ndarray, t: float) -> np.ndarray:
        """Layer values at points and time.

        Parameters
        ----------
        x, y : (n,) float, metres
        t : float, seconds since the shot start

        Returns
        -------
        (n,) float32 in [0, 1] for generated layers
        """
        if self.kind == "painted":
            return self.field.sample(np.stack([x, y], axis=1))
        if not self.active(t):
            return np.zeros(len(x), np.float32)
        if self.kind == "food":
            d2 = ((x[:, None] - self.patches[None, :, 0]) ** 2 + (y[:, None] - self.patches[None, :, 1]) ** 2)
            r = np.sqrt(d2.min(axis=1))
            return np.minimum(np.maximum(1.5 - r / P.FOOD_PATCH_RADIUS, 0.0), 1.0).astype(np.float32)
        R = self.current_radius(t)
        if R <= 0:
            return np.zeros(len(x), np.float32)
        return radial_falloff(np.asarray(x), np.asarray(y), float(self.origin[0]), float(self.origin[1]), R)

    def render(self, t: float, shape=(128, 128)) -> np.ndarray:
        """The layer as an image over its extent (row 0 at +Y), like BehaviorField.values.

        Returns
        -------
        (h, w) float32
        """
        h, w = shape
        f = self.field
        xs = f.extent_min[0] + (np.arange(w) + 0.5) / w * (f.extent_max[0] - f.extent_min[0])
        ys = f.extent_max[1] - (np.arange(h) + 0.5) / h * (f.extent_max[1] - f.extent_min[1])
        X, Y = np.meshgrid(xs, ys)
        return self.sample(X.ravel(), Y.ravel(), t).reshape(h, w)


class Reactions:
    """Reactions of agents to behavior maps, by personality and attributes.

    Parameters
    ----------
    scenario : Scenario
    dmaps : DistanceMaps
    to_seconds : callable
    rng : numpy.random.Generator
    """

    def __init__(self, scenario: Scenario, dmaps: DistanceMaps, to_seconds, rng):
        a = scenario.agents
        n = len(a)
        self.dmaps = dmaps
        self.grid = dmaps.grid
        layers = [MapLayer(f, to_seconds, rng) for f in scenario.fields]
        self.damage = [m for m in layers if field_is(m.field, "damage")]
        self.threats = [m for m in self.damage if m.kind in ("explosion", "volcano")]
        self.food = [m for m in layers if field_is(m.field, "food")]
        self.rest = [m for m in layers if field_is(m.field, "rest")]
        pers = np.asarray(a.personality)
        ctype = np.asarray(a.character_type)
        beh = np.asarray(a.behavior)
        self.civilians = np.where(pers == code(PERSONALITIES, "civilian"))[0]
        self.security = np.where(pers == code(PERSONALITIES, "security"))[0]
        self.attackers = np.where(pers == code(PERSONALITIES, "attacker"))[0]
        self.predators = np.where(pers == code(PERSONALITIES, "predator"))[0]
        herb = (pers == code(PERSONALITIES, "herbivore")) | (ctype == code(CHARACTER_TYPES, "herbivore"))
        herb &= pers != code(PERSONALITIES, "predator")
        self.prey = np.where(herb)[0]
        eaters = herb | (ctype == code(CHARACTER_TYPES, "ant")) | (beh == code(BEHAVIORS, "graze"))
        self.eaters = np.where(eaters & (pers != code(PERSONALITIES, "predator")))[0]
        self.birds = np.where(ctype == code(CHARACTER_TYPES, "bird"))[0]
        self.freeze = np.asarray(a.fear_response) == code(FEAR_RESPONSES, "freeze")
        self.weight = np.clip(np.asarray(a.map_influence, dtype=np.float32), 0.0, 1.0)
        # Per-agent resilience: damage thresholds for death and wounds.
        self.dead_at = rng.uniform(*P.DEAD_DAMAGE, n).astype(np.float32)
        self.wound_at = rng.uniform(*P.WOUND_DAMAGE, n).astype(np.float32)
        self._food_dir = self._region_field(self.food, "food")
        self._rest_dir = self._region_field(self.rest, "rest")

    def _region_field(self, layers, name):
        """Distance map / direction toward cells where a food or rest layer is high."""
        if not layers:
            return None
        g = self.grid
        cx, cy = g.centers_x.ravel(), g.centers_y.ravel()
        # Generated food appears at start_time; the map of where it will be is
        # known in advance (animals smell it), sampled at "forever".
        vals = np.max([m.sample(cx, cy, np.inf) for m in layers], axis=0).reshape(g.h, g.w)
        mask = (vals > P.MAP_THRESHOLD) & ~g.solid
        D = self.dmaps.distance_to_mask(mask, key=(name,))
        return self.dmaps.direction(None, key=(name,), distance=D)

    # -- health --------------------------------------------------------------
    def update_health(self, health: np.ndarray, x, y, t: float) -> None:
        """Wound or kill agents standing in damage (health only worsens), in place.

        Parameters
        ----------
        health : (n,) int8
        x, y : (n,) float32
        t : float, seconds
        """
        if not self.damage:
            return
        dmg = None
        for m in self.damage:
            if m.active(t):
                v = m.sample(x, y, t) * m.influence
                dmg = v if dmg is None else np.maximum(dmg, v)
        if dmg is None:
            return
        worsen_health(health, dmg, self.wound_at, self.dead_at, _WOUNDED, _DEAD)

    def active_threat(self, t: float):
        """The latest generated threat (explosion / volcano) already started, or None."""
        act = [m for m in self.threats if m.active(t)]
        return max(act, key=lambda m: m.start) if act else None

    # -- reactions -------------------------------------------------------------
    def apply(self, intent, pos, vel, speed, alive, t: float) -> None:
        """Overwrite / blend the desired velocities of reacting agents, in place.

        Parameters
        ----------
        intent : usdcrowd.sim.simulation.Intent
            Desired velocity (2, n), look-at (3, n), behavior (n,), facing (n,).
        pos, vel : (2, n + 1) float32
        speed : (n,) float32
            Preferred speeds (already reduced for the wounded).
        alive : (n,) bool
        t : float, seconds
        """
        threat = self.active_threat(t)
        if threat is not None:
            self._civilians(intent, pos, speed, alive, threat)
            self._security(intent, pos, vel, speed, alive, threat)
            self._attackers(intent, pos, vel, speed, alive, threat)
        self._animals(intent, pos, vel, speed, alive)

    def _blend(self, intent, rows, v, beh, look=None, face=False):
        beh = np.asarray(beh, np.int8)
        # A whole array for one behavior: numba reads a broadcast view's type slowly (~20 us a call).
        blend_rows(intent.v, intent.behavior, rows, self.weight, np.asarray(v),
                   np.full(rows.shape, beh, np.int8) if beh.ndim == 0 else beh)
        if look is not None:
            # (2, m) points: the simulation puts their height at eye level.
            intent.look[:2, rows] = look
            intent.look[2, rows] = np.nan if len(look) == 2 else look[2]
        if face:
            intent.face[rows[self.weight[rows] > 0.5]] = True

    def _civilians(self, intent, pos, speed, alive, threat):
        o, R = threat.origin, threat.radius
        rows, d = within_reach(pos, self.civilians[alive[self.civilians]], float(o[0]), float(o[1]),
                               max(P.ALARM_FACTOR * R, P.ALARM_MIN))
        if rows.size == 0:
            return
        _, dirs = self.dmaps.direction(o[None, :], key=("threat", id(threat)))
        # Panic speed inside the safe distance, walking pace up to the alarm radius.
        v, beh = flee_blast(pos, rows, d, float(o[0]), float(o[1]), P.SAFE_FACTOR * R, dirs.reshape(2, -1),
                            *self.grid.lookup, speed, np.float32(P.PANIC_SPEED_FACTOR), self.freeze, _B["run"],
                            _B["walk"], _B["rest"])
        look = np.empty((2, rows.size), np.float32)
        look[0], look[1] = o[0], o[1]
        self._blend(intent, rows, v, beh, look=look, face=False)
        intent.face[rows[self.freeze[rows]]] = True

    def _security(self, intent, pos, vel, speed, alive, threat):
        sec = self.security[alive[self.security]]
        if sec.size == 0:
            return
        att = self.attackers[alive[self.attackers]]
        tgt = nearest_of(pos, sec, att, P.PURSUIT_RANGE)
        chase = tgt >= 0
        if chase.any():
            rows, t = sec[chase], tgt[chase]
            v = pursue(pos[:, rows], vel[:, t], pos[:, t], speed[rows] * P.PANIC_SPEED_FACTOR)
            self._blend(intent, rows, v, _B["run"], look=pos[:, t])
        line = sec[~chase]
        if line.size == 0:
            return
        o = threat.origin.astype(np.float32)
        civ = self.civilians[alive[self.civilians]]
        c = pos[:, civ].mean(axis=1) if civ.size else pos[:, line].mean(axis=1)
        axis, norm = unit((c - o)[:, None])
        axis = axis[:, 0] if norm[0] > 1e-3 else np.array([1.0, 0.0], np.float32)
        perp = np.array([-axis[1], axis[0]], np.float32)
        centre = o + axis * np.float32(threat.radius * P.LINE_OFFSET)
        # Slots along the line, assigned in the order officers already stand
        # (sorting their projections), so nobody crosses the line.
        proj = (pos[0, line] - centre[0]) * perp[0] + (pos[1, line] - centre[1]) * perp[1]
        order = np.argsort(proj, kind="stable")
        k = np.empty(line.size, np.float32)
        k[order] = np.arange(line.size, dtype=np.float32) - 0.5 * (line.size - 1)
        slots = centre[:, None] + perp[:, None] * (k * np.float32(P.LINE_SPACING))[None, :]
        v, d = arrive(pos[:, line], slots, speed[line] * P.PANIC_SPEED_FACTOR, slow_radius=P.SLOW_RADIUS)
        look = np.broadcast_to(o[:, None], (2, line.size))
        beh = np.where(d > P.SLOW_RADIUS, _B["run"], _B["walk"]).astype(np.int8)
        self._blend(intent, line, v, beh, look=look, face=True)

    def _attackers(self, intent, pos, vel, speed, alive, threat):
        att = self.attackers[alive[self.attackers]]
        if att.size == 0:
            return
        sec = self.security[alive[self.security]]
        thr = nearest_of(pos, att, sec, P.THREAT_RANGE)
        near = thr >= 0
        sp = speed[att] * P.PANIC_SPEED_FACTOR
        v = np.empty((2, att.size), np.float32)
        if near.any():
            v[:, near] = evade(pos[:, att[near]], vel[:, thr[near]], pos[:, thr[near]], sp[near])
        far = ~near
        if far.any():
            # Nobody on their heels: get away from the scene of the attack.
            u, _ = unit(pos[:, att[far]] - threat.origin.astype(np.float32)[:, None])
            v[:, far] = u * sp[far]
        look = np.where(near[None, :], pos[:, np.where(near, thr, att)], np.nan).astype(np.float32)
        self._blend(intent, att, v, _B["run"], look=look)

    def _animals(self, intent, pos, vel, speed, alive):
        # Prey evade predators, predators pursue prey.
        if self.predators.size and self.prey.size:
            prey = self.prey[alive[self.prey]]
            pred = self.predators[alive[self.predators]]
            thr = nearest_of(pos, prey, pred, P.THREAT_RANGE)
            near = thr >= 0
            if near.any():
                rows, t = prey[near], thr[near]
                v = evade(pos[:, rows], vel[:, t], pos[:, t], speed[rows] * P.PANIC_SPEED_FACTOR)
                self._blend(intent, rows, v, _B["run"], look=pos[:, t])
            tgt = nearest_of(pos, pred, prey, P.PERCEPTION_RANGE)
            ch = tgt >= 0
            if ch.any():
                rows, t = pred[ch], tgt[ch]
                v = pursue(pos[:, rows], vel[:, t], pos[:, t], speed[rows] * P.PANIC_SPEED_FACTOR)
                self._blend(intent, rows, v, _B["run"], look=pos[:, t])
        # Eaters go to food and graze there.
        if self._food_dir is not None and self.eaters.size:
            self._region(intent, pos, speed, alive, self.eaters, self._food_dir, _B["graze"],
                         P.GRAZE_SPEED_FACTOR)
        if self._rest_dir is not None and self.birds.size:
            self._region(intent, pos, speed, alive, self.birds, self._rest_dir, _B["rest"], 0.0)

    def _region(self, intent, pos, speed, alive, rows, field, beh_there, pace_there):
        rows = rows[alive[rows] & (intent.behavior[rows] != _B["run"])]
        if rows.size == 0:
            return
        D, dirs = field
        d = sample_grid(self.grid, D, pos[0, rows], pos[1, rows])
        reach = np.isfinite(d)
        rows, d = rows[reach], d[reach]
        u = sample_grid(self.grid, dirs, pos[0, rows], pos[1, rows])
        there = d <= 0.5 * self.grid.cell
        v = u * speed[rows] * np.where(there, 0.0, np.minimum(np.maximum(d / P.SLOW_RADIUS, 0.2), 1.0)).astype(np.float32)
        # On the patch: keep the current (wander) motion, slowed to a drift.
        v[:, there] = intent.v[:, rows[there]] * np.float32(pace_there)
        beh = np.where(there, beh_there, intent.behavior[rows]).astype(np.int8)
        self._blend(intent, rows, v, beh)
