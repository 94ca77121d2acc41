"""Paths (seed 004): Bezier curves, gradient (slope) navigation, and the rule between them.

- **Bezier**: every agent walks its own cubic Bezier curve from where it
  stands to its goal, with random control points, so that a group does not
  move in lockstep. When the next point of the curve is blocked (solid or too
  steep) the two inner control points are re-drawn, keeping the start and the
  end ("moving the control points ... without changing the starting and
  ending points").
- **Gradient**: the height layer's slope ``|grad h|`` against the agent's
  ``max_slope``. The agent estimates the slope one step ahead in its
  direction; when it is too steep it tries random directions (it "knows
  nothing about the area") and keeps the best allowed one for a while.
- **Rule**: by the size of the obstacles relative to the character (the
  seed: large obstacles -> gradient map, small -> Bezier control points, with
  per-character thresholds :data:`params.GRADIENT_SIZE_RATIO`). A scene with
  neither obstacles nor steep ground gets ``direct``.

Whatever the method, :func:`enforce_slope` refuses any step onto ground
steeper than the agent's limit (the hard guarantee tests check).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from ..core.model import BehaviorField, CHARACTER_TYPES, PATH_METHODS, Scenario, code
from . import params as P
from .steering import unit

DIRECT, BEZIER, GRADIENT = (code(PATH_METHODS, m) for m in PATH_METHODS)


def slope_map(field: BehaviorField) -> np.ndarray:
    """Terrain slope ``|grad h|`` (rise over run) of a height layer, per pixel.

    Parameters
    ----------
    field : BehaviorField
        Height layer; ``values`` row 0 is the +Y edge.

    Returns
    -------
    (h, w) float32
    """
    v = np.asarray(field.values, dtype=np.float64)
    h, w = v.shape
    px = (field.extent_max[0] - field.extent_min[0]) / w
    py = (field.extent_max[1] - field.extent_min[1]) / h
    if h < 2 or w < 2:
        return np.zeros_like(v, dtype=np.float32)
    d_row, d_col = np.gradient(v, py, px)
    # Rows go toward -Y, so dh/dy = -dh/drow; the magnitude doesn't care.
    return np.hypot(d_row, d_col).astype(np.float32)


class Terrain:
    """Ground height and slope from the scenario's height layer (flat if none).

    Parameters
    ----------
    field : BehaviorField or None
    """

    def __init__(self, field: BehaviorField | None):
        self.field = field
        self.flat = field is None or field.values is None
        if self.flat:
            return
        self.values = np.asarray(field.values, dtype=np.float32)
        self.h, self.w = self.values.shape
        self.lo = np.asarray(field.extent_min, dtype=np.float64)
        self.hi = np.asarray(field.extent_max, dtype=np.float64)
        self.px = (self.hi[0] - self.lo[0]) / self.w
        self.py = (self.hi[1] - self.lo[1]) / self.h
        sm = slope_map(field)
        self.slope_values = sm
        self.flat = bool(np.ptp(self.values) == 0)
        # Nearest-pixel sampling exactly like BehaviorField.sample (tests use it).
        self.slope_field = BehaviorField(field.path, field.meaning, field.generator, sm,
                                         self.lo, self.hi)

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Bilinear ground height at points, (n,) float32 (clamped at the edges)."""
        if self.field is None or self.field.values is None:
            return np.zeros(len(x), np.float32)
        u = np.clip((x - self.lo[0]) / self.px - 0.5, 0, self.w - 1)
        v = np.clip((self.hi[1] - y) / self.py - 0.5, 0, self.h - 1)
        c0 = np.minimum(u.astype(np.int64), self.w - 2) if self.w > 1 else np.zeros(len(x), np.int64)
        r0 = np.minimum(v.astype(np.int64), self.h - 2) if self.h > 1 else np.zeros(len(x), np.int64)
        fu = (u - c0).astype(np.float32)
        fv = (v - r0).astype(np.float32)
        c1 = np.minimum(c0 + 1, self.w - 1)
        r1 = np.minimum(r0 + 1, self.h - 1)
        V = self.values
        top = V[r0, c0] * (1 - fu) + V[r0, c1] * fu
        bot = V[r1, c0] * (1 - fu) + V[r1, c1] * fu
        return (top * (1 - fv) + bot * fv).astype(np.float32)

    def slope(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Nearest-pixel terrain slope at points, (n,) float32 (0 outside the layer)."""
        if self.flat:
            return np.zeros(len(x), np.float32)
        return self.slope_field.sample(np.stack([x, y], axis=1))

    def obstacle_size(self) -> float:
        """Size of the largest steep region (sqrt of its area), metres."""
        if self.flat:
            return 0.0
        steep = self.slope_values > P.STEEP_SLOPE
        lab, k = ndimage.label(steep)
        if k == 0:
            return 0.0
        areas = np.bincount(lab.ravel())[1:] * self.px * self.py
        return float(np.sqrt(np.max(areas)))


def choose_path_method(scenario: Scenario, terrain: Terrain) -> np.ndarray:
    """Path method of every agent by the seed's rule (obstacle size vs character size).

    Returns
    -------
    (n,) int8
        Codes into PATH_METHODS.
    """
    a = scenario.agents
    n = len(a)
    sizes = []
    if len(scenario.obstacles):
        # The largest obstacle decides: one long wall is enough to trap an agent
        # on a random curve.
        ext = [np.ptp(np.asarray(p), axis=0).max() for p in scenario.obstacles.polygons]
        sizes.append(float(np.max(ext)))
    tsize = terrain.obstacle_size()
    if tsize > 0:
        sizes.append(tsize)
    if not sizes:
        return np.full(n, DIRECT, np.int8)
    size = max(sizes)
    thr = np.asarray(P.GRADIENT_SIZE_RATIO)[np.asarray(a.character_type, dtype=np.int64)]
    ratio = size / np.maximum(np.asarray(a.height, dtype=np.float64), 1e-3)
    out = np.where(ratio > thr, GRADIENT, BEZIER).astype(np.int8)
    out[np.asarray(a.character_type) == code(CHARACTER_TYPES, "bird")] = DIRECT
    return out


class BezierPaths:
    """Per-agent cubic Bezier curves with random control points.

    Parameters
    ----------
    start, goal : (2, b) float32
    rng : numpy.random.Generator

    Attributes
    ----------
    s : (b,) float32
        Curve parameter of each agent's carrot, in [0, 1].
    """

    def __init__(self, start: np.ndarray, goal: np.ndarray, rng):
        self.rng = rng
        self.p0 = start.astype(np.float32)
        self.p3 = goal.astype(np.float32)
        d = self.p3 - self.p0
        self.length = np.sqrt(d[0] * d[0] + d[1] * d[1]).astype(np.float32)
        self.spread = np.minimum(P.BEZIER_SPREAD * self.length, P.BEZIER_SPREAD_MAX).astype(np.float32)
        self.p1 = np.empty_like(self.p0)
        self.p2 = np.empty_like(self.p0)
        self._draw(np.arange(self.p0.shape[1]), 1.0)
        self.s = np.zeros(self.p0.shape[1], np.float32)
        self.ds = (0.5 * P.BEZIER_LOOKAHEAD / np.maximum(self.length, 1e-3)).astype(np.float32)

    def retarget(self, rows: np.ndarray, start: np.ndarray, goal: np.ndarray) -> None:
        """New curves for some agents (their goal changed): from where they stand to the new goal.

        Parameters
        ----------
        rows : (m,) int
            Indices into this object's agents.
        start, goal : (2, m) float32
        """
        self.p0[:, rows] = start
        self.p3[:, rows] = goal
        d = self.p3[:, rows] - self.p0[:, rows]
        self.length[rows] = np.sqrt(d[0] * d[0] + d[1] * d[1])
        self.spread[rows] = np.minimum(P.BEZIER_SPREAD * self.length[rows], P.BEZIER_SPREAD_MAX)
        self.ds[rows] = 0.5 * P.BEZIER_LOOKAHEAD / np.maximum(self.length[rows], 1e-3)
        self.s[rows] = 0.0
        self._draw(rows, 1.0)

    def _draw(self, rows, scale):
        d = self.p3[:, rows] - self.p0[:, rows]
        u, _ = unit(d)
        perp = np.stack([-u[1], u[0]])
        k = rows.size
        o1 = self.rng.normal(0.0, 1.0, k).astype(np.float32) * self.spread[rows] * scale
        o2 = self.rng.normal(0.0, 1.0, k).astype(np.float32) * self.spread[rows] * scale
        self.p1[:, rows] = self.p0[:, rows] + d / 3 + perp * o1
        self.p2[:, rows] = self.p0[:, rows] + 2 * d / 3 + perp * o2

    def point(self, s: np.ndarray) -> np.ndarray:
        """Curve points at parameters ``s`` (b,), (2, b)."""
        t = s[None, :]
        m = 1 - t
        return m * m * m * self.p0 + 3 * m * m * t * self.p1 + 3 * m * t * t * self.p2 + t * t * t * self.p3

    def carrot(self, pos: np.ndarray):
        """Advance each agent's carrot along its curve and return it.

        Parameters
        ----------
        pos : (2, b) float32

        Returns
        -------
        target : (2, b) float32
        last : (b,) bool
            The carrot reached the curve's end (arrive rather than seek).
        """
        for _ in range(3):  # a few fixed advances per step (no loop over agents)
            c = self.point(self.s)
            d = c - pos
            close = d[0] * d[0] + d[1] * d[1] < P.BEZIER_LOOKAHEAD ** 2
            self.s = np.where(close, np.minimum(self.s + self.ds, 1.0), self.s).astype(np.float32)
        return self.point(self.s), self.s >= 1.0

    def repair(self, bad: np.ndarray) -> None:
        """Re-draw the inner control points of agents whose way is blocked."""
        rows = np.where(bad)[0]
        if rows.size:
            self._draw(rows, 1.5)


class SlopeSteering:
    """Gradient-map navigation with a per-agent maximum slope (seed 004).

    Parameters
    ----------
    terrain : Terrain
    max_slope : (b,) float32
    rng : numpy.random.Generator
    """

    def __init__(self, terrain: Terrain, max_slope: np.ndarray, rng):
        self.terrain = terrain
        self.max_slope = max_slope.astype(np.float32)
        self.rng = rng
        b = len(max_slope)
        self.detour = np.zeros((2, b), np.float32)
        self.timer = np.zeros(b, np.float32)

    def _ok(self, x, y, dx, dy, limit):
        """Is the ground one and a half look-ahead ahead walkable for this limit?"""
        t = self.terrain
        h0 = t.height(x, y)
        ok = np.ones(len(x), dtype=bool)
        for f in (0.5, 1.0, 1.5):
            qx = x + dx * P.SLOPE_LOOKAHEAD * f
            qy = y + dy * P.SLOPE_LOOKAHEAD * f
            rise = np.abs(t.height(qx, qy) - h0) / (P.SLOPE_LOOKAHEAD * f)
            ok &= (t.slope(qx, qy) <= limit) & (rise <= limit)
        return ok

    def direction(self, pos: np.ndarray, want: np.ndarray, dt: float) -> np.ndarray:
        """Walking direction: ``want`` unless the way ahead is too steep.

        Parameters
        ----------
        pos : (2, b) float32
        want : (2, b) float32
            Unit desired directions.
        dt : float, s

        Returns
        -------
        (2, b) float32 unit directions
        """
        if self.terrain.flat or pos.shape[1] == 0:
            return want
        x, y = pos
        out = want.copy()
        self.timer -= np.float32(dt)
        ok_want = self._ok(x, y, want[0], want[1], self.max_slope)
        keep = (self.timer > 0) & ~ok_want
        if keep.any():
            k = np.where(keep)[0]
            still = self._ok(x[k], y[k], self.detour[0, k], self.detour[1, k], self.max_slope[k])
            out[:, k[still]] = self.detour[:, k[still]]
            keep[k[~still]] = False
        bad = ~ok_want & ~keep
        if bad.any():
            b = np.where(bad)[0]
            m = P.SLOPE_PROBES
            ang = self.rng.uniform(-np.pi, np.pi, (b.size, m)).astype(np.float32)
            base = np.arctan2(want[1, b], want[0, b])[:, None]
            cx = np.cos(base + ang)
            cy = np.sin(base + ang)
            ok = self._ok(np.repeat(x[b], m), np.repeat(y[b], m), cx.ravel(), cy.ravel(),
                          np.repeat(self.max_slope[b], m)).reshape(b.size, m)
            score = np.where(ok, np.cos(ang), -np.inf)
            j = np.argmax(score, axis=1)
            r = np.arange(b.size)
            found = np.isfinite(score[r, j])
            dx = np.where(found, cx[r, j], -want[0, b])
            dy = np.where(found, cy[r, j], -want[1, b])
            self.detour[0, b] = dx
            self.detour[1, b] = dy
            self.timer[b] = P.DETOUR_TIME
            out[0, b] = dx
            out[1, b] = dy
        return out


def enforce_slope(terrain: Terrain, old: np.ndarray, pos: np.ndarray, vel: np.ndarray,
                  rows: np.ndarray, max_slope: np.ndarray) -> None:
    """Refuse steps onto ground steeper than an agent's limit (in place).

    A step is undone (position restored, velocity zeroed) when the ground at
    the new position is steeper than both the agent's ``max_slope`` and the
    ground it came from (an agent placed on a steep spot may still walk off
    it).

    Parameters
    ----------
    terrain : Terrain
    old, pos, vel : (2, n + 1) float32
        Positions before / after the step, velocities.
    rows : (m,) int
        Agents subject to the limit (walkers, not birds).
    max_slope : (n,) float32
    """
    if terrain.flat or rows.size == 0:
        return
    s_new = terrain.slope(pos[0, rows], pos[1, rows])
    lim = max_slope[rows]
    bad = s_new > lim
    if not bad.any():
        return
    r = rows[bad]
    s_old = terrain.slope(old[0, r], old[1, r])
    undo = s_new[bad] > np.maximum(lim[bad], s_old)
    r = r[undo]
    pos[:, r] = old[:, r]
    vel[:, r] = 0.0
