"""The walkable occupancy grid: obstacles and forbidden areas rasterised.

The grid covers the scenario bounds. Row ``i`` is ``y = origin_y + (i + 0.5)
* cell`` (row 0 at the *low* y edge, unlike image-like BehaviorField values).
It holds

- ``solid``: cells whose centre lies inside an obstacle footprint or a
  forbidden area (used for line of sight);
- ``sdf``: signed clearance of each cell centre to the solid region, metres
  (negative inside), and its unit gradient ``normal`` (pointing away from
  the nearest solid); used for wall avoidance forces;
- ``label``: the obstacle polygon nearest to each cell (-1 where the nearest
  solid is a forbidden area), for the exact wall projection in
  :mod:`usdcrowd.sim.collision`;
- ``near``: the obstacle whose exact distance is a cell's clearance, so that
  between cell centres the walkers measure to the polygons themselves
  (:func:`usdcrowd.sim.kernels._wall_at`): blending the centres' values
  narrowed a 0.8 m door to 0.55 m.

Agents' positions are handled in structure-of-arrays layout ``(2, n)``.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from ..core.model import Obstacles, Scenario, code, LAYER_MEANINGS, LAYER_GENERATORS
from . import kernels
from . import params as P


# Samples along a line of sight at most (longer lines are sampled more coarsely).
LOS_MAX_SAMPLES = 96


# Metres from an obstacle within which its clearance is its polygon's exact distance.
EXACT_BAND = 1.5


def polygon_table(obstacles: Obstacles) -> np.ndarray:
    """Obstacle polygons padded to a common vertex count.

    Returns
    -------
    (o, K, 2) float64
        Counter-clockwise vertices; short polygons repeat their last vertex
        (a zero-length edge, harmless to distance and inside tests).
    """
    if not obstacles.polygons:
        return np.zeros((0, 3, 2))
    kmax = max(len(p) for p in obstacles.polygons)
    out = np.empty((len(obstacles.polygons), kmax, 2))
    for i, poly in enumerate(obstacles.polygons):  # once per obstacle, not per agent
        poly = np.asarray(poly, dtype=np.float64)
        # Shoelace: make sure the winding is counter-clockwise.
        area = 0.5 * np.sum(poly[:, 0] * np.roll(poly[:, 1], -1) - np.roll(poly[:, 0], -1) * poly[:, 1])
        if area < 0:
            poly = poly[::-1]
        out[i, :len(poly)] = poly
        out[i, len(poly):] = poly[-1]
    return out


def polygon_signed_distance(p: np.ndarray, poly: np.ndarray):
    """Exact signed distance of points to convex CCW polygons.

    Parameters
    ----------
    p : (m, 2) float64
    poly : (m, K, 2) float64
        One (padded) polygon per point.

    Returns
    -------
    dist : (m,) signed distance, negative inside, metres
    closest : (m, 2) nearest boundary point
    normal : (m, 2) outward normal of the nearest edge
    """
    a = poly
    b = np.roll(poly, -1, axis=1)
    e = b - a  # (m, K, 2)
    ap = p[:, None, :] - a
    ll = np.einsum("mkc,mkc->mk", e, e)
    t = np.clip(np.einsum("mkc,mkc->mk", ap, e) / np.maximum(ll, 1e-18), 0.0, 1.0)
    c = a + e * t[..., None]
    d2 = np.einsum("mkc,mkc->mk", p[:, None, :] - c, p[:, None, :] - c)
    d2 = np.where(ll > 1e-18, d2, np.inf)  # padded zero-length edges
    k = np.argmin(d2, axis=1)
    r = np.arange(len(p))
    dist = np.sqrt(d2[r, k])
    cross = e[..., 0] * ap[..., 1] - e[..., 1] * ap[..., 0]
    inside = np.all((cross >= 0) | (ll <= 1e-18), axis=1)
    ek = e[r, k]
    nrm = np.stack([ek[:, 1], -ek[:, 0]], axis=1) / np.maximum(np.sqrt(ll[r, k]), 1e-12)[:, None]
    return np.where(inside, -dist, dist), c[r, k], nrm


class WalkGrid:
    """Occupancy grid, clearance field and line-of-sight queries.

    Parameters
    ----------
    scenario : Scenario
        Bounds, obstacles and forbidden behavior fields are read from it.
    cell : float, optional
        Cell size in metres; grows from :data:`params.GRID_CELL` so the grid
        stays under :data:`params.GRID_MAX_CELLS` cells.

    Attributes
    ----------
    flat_sdf, flat_nx, flat_ny, flat_solid, flat_label, flat_near : (h * w,) arrays
        The fields in flat cell order (:meth:`flat_index`), as the compiled loops read them.
    near : (h, w) int32
        The obstacle whose polygon's exact distance is a cell's clearance (-1: none, as far from
        obstacles and where a forbidden area is nearer).
    exact : tuple
        ``(flat_near, polygons, sizes)``: what the compiled loops need, besides ``flat_sdf``, for the
        clearance between cell centres (exact to the polygons where the four around have one; ``sizes``
        (o,) int64, each polygon's own vertex count in the padded table).
    lookup : tuple
        ``(origin_x, origin_y, 1 / cell, w, h)``: what the compiled loops need to find a point's cell.
    sight : tuple
        ``(samples per metre, LOS_MAX_SAMPLES) + lookup + (flat_solid, flat_sdf)``: what they need for
        a line of sight.
    """

    def __init__(self, scenario: Scenario, cell: float | None = None):
        lo = np.asarray(scenario.bounds[0], dtype=np.float64)
        hi = np.asarray(scenario.bounds[1], dtype=np.float64)
        size = np.maximum(hi - lo, 1e-3)
        if cell is None:
            cell = max(P.GRID_CELL, float(np.sqrt(size[0] * size[1] / P.GRID_MAX_CELLS)))
        self.cell = float(cell)
        # One extra cell of margin all around so agents on the bounds sample
        # valid cells.
        self.origin = lo - self.cell
        self.w = int(np.ceil(size[0] / self.cell)) + 2
        self.h = int(np.ceil(size[1] / self.cell)) + 2
        xs = self.origin[0] + (np.arange(self.w) + 0.5) * self.cell
        ys = self.origin[1] + (np.arange(self.h) + 0.5) * self.cell
        self.centers_x, self.centers_y = np.meshgrid(xs, ys)  # (h, w)

        self.polygons = polygon_table(scenario.obstacles)
        label = np.full((self.h, self.w), -1, dtype=np.int32)
        for i, poly in enumerate(self.polygons):  # per obstacle, bbox-limited
            self._raster_polygon(poly, i, label)
        solid = label >= 0
        fmask = np.zeros_like(solid)
        forb = scenario.field("forbidden")
        if forb is not None and forb.values is not None:
            pts = np.stack([self.centers_x.ravel(), self.centers_y.ravel()], axis=1)
            fmask = (forb.sample(pts) > P.MAP_THRESHOLD).reshape(self.h, self.w)
            solid |= fmask
        self.solid = solid
        self.has_solid = bool(solid.any())
        if self.has_solid:
            out_d, inds = ndimage.distance_transform_edt(~solid, return_indices=True)
            in_d = ndimage.distance_transform_edt(solid)
            # Cell-centre distances to the nearest solid centre, shifted by half
            # a cell so that the zero level sits on the solid's edge.
            sdf = np.where(solid, -(in_d - 0.5), out_d - 0.5) * self.cell
            self.label = label[inds[0], inds[1]].astype(np.int32)
            self.label[solid] = label[solid]
            sdf = self._exact_near_obstacles(sdf, fmask)
        else:
            sdf = np.full((self.h, self.w), 1e3)
            self.label = label
            self.near = np.full((self.h, self.w), -1, np.int32)
        self.sdf = sdf.astype(np.float32)
        gy, gx = np.gradient(self.sdf.astype(np.float64), self.cell)
        norm = np.hypot(gx, gy)
        norm[norm == 0] = 1.0
        self.normal = np.stack([gx / norm, gy / norm]).astype(np.float32)  # (2, h, w)
        self.flat_sdf = self.sdf.ravel()
        self.flat_nx = self.normal[0].ravel()
        self.flat_ny = self.normal[1].ravel()
        self.flat_solid = self.solid.ravel()
        self.flat_label = self.label.ravel()
        self.flat_near = self.near.ravel()
        sizes = np.array([len(p) for p in scenario.obstacles.polygons], np.int64)
        self.exact = (self.flat_near, np.ascontiguousarray(self.polygons, dtype=np.float64), sizes)
        self.lookup = (float(self.origin[0]), float(self.origin[1]), 1.0 / self.cell, self.w, self.h)
        self.sight = (1.0 / (0.7 * self.cell), LOS_MAX_SAMPLES) + self.lookup + (self.flat_solid, self.flat_sdf)

    def _exact_near_obstacles(self, sdf: np.ndarray, forbidden: np.ndarray) -> np.ndarray:
        """The clearance within ``EXACT_BAND`` of an obstacle, measured to the polygon itself.

        The distance transform puts a wall on the edge of the cells whose centres it covers, up to half
        a cell from where it stands: a 1.2 m door between walls that fall between cell centres was
        1.0 m wide to the walkers, and one of 0.8 m was 1.0 m. Outside the polygons and in their first
        cells inside, the clearance is their exact signed distance (at cell centres; the compiled loops
        interpolate between them); forbidden cells, which have no polygon, count by the transform's
        distance. Deeper inside, and inside forbidden cells, the transform's depth stays: bodies are
        pushed out along its slope, and it is the depth in the union of everything solid (water painted
        over a wall pushes out of both).

        Parameters
        ----------
        sdf : (h, w) float
            The distance transform's clearance, metres.
        forbidden : (h, w) bool
            Cells a forbidden field covers.
        """
        exact = np.full(sdf.shape, np.inf)
        nearest = np.full(sdf.shape, -1, np.int32)
        for i, poly in enumerate(self.polygons):
            c0 = np.clip(np.floor((poly.min(0) - EXACT_BAND - self.origin) / self.cell).astype(int), 0,
                         [self.w - 1, self.h - 1])
            c1 = np.clip(np.ceil((poly.max(0) + EXACT_BAND - self.origin) / self.cell).astype(int), 0,
                         [self.w - 1, self.h - 1])
            ys, xs = slice(c0[1], c1[1] + 1), slice(c0[0], c1[0] + 1)
            pts = np.stack([self.centers_x[ys, xs].ravel(), self.centers_y[ys, xs].ravel()], axis=1)
            d = polygon_signed_distance(pts, np.broadcast_to(poly, (len(pts),) + poly.shape))[0]
            d = d.reshape(exact[ys, xs].shape)
            nearer = d < exact[ys, xs]
            exact[ys, xs][nearer] = d[nearer]
            nearest[ys, xs][nearer] = i
        polygon = exact
        if forbidden.any():
            exact = np.minimum(exact, (ndimage.distance_transform_edt(~forbidden) - 0.5) * self.cell)
        use = (exact < EXACT_BAND) & (exact > -self.cell) & ~forbidden
        # The compiled loops measure to the polygon itself between centres whose clearance is its own.
        self.near = np.where(use & (polygon <= exact), nearest, -1).astype(np.int32)
        return np.where(use, exact, sdf)

    # -- rasterisation -------------------------------------------------------
    def _raster_polygon(self, poly: np.ndarray, index: int, label: np.ndarray) -> None:
        """Mark cells whose centre lies inside a convex CCW polygon."""
        lo = poly.min(axis=0)
        hi = poly.max(axis=0)
        c0 = np.clip(np.floor((lo - self.origin) / self.cell - 0.5).astype(int), 0, [self.w - 1, self.h - 1])
        c1 = np.clip(np.ceil((hi - self.origin) / self.cell + 0.5).astype(int), 0, [self.w - 1, self.h - 1])
        cx = self.centers_x[c0[1]:c1[1] + 1, c0[0]:c1[0] + 1]
        cy = self.centers_y[c0[1]:c1[1] + 1, c0[0]:c1[0] + 1]
        a = poly
        b = np.roll(poly, -1, axis=0)
        # Left of every CCW edge (cross >= 0) is inside.
        cross = ((b[:, 0] - a[:, 0])[:, None, None] * (cy[None] - a[:, 1, None, None])
                 - (b[:, 1] - a[:, 1])[:, None, None] * (cx[None] - a[:, 0, None, None]))
        inside = np.all(cross >= -1e-12, axis=0)
        sub = label[c0[1]:c1[1] + 1, c0[0]:c1[0] + 1]
        sub[inside] = index

    # -- sampling ------------------------------------------------------------
    def flat_index(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Flat cell index of points (clamped to the grid).

        Parameters
        ----------
        x, y : (n,) float
            World coordinates, metres.

        Returns
        -------
        (n,) int64
        """
        return kernels.cells(np.asarray(x), np.asarray(y), *self.lookup)

    def clearance(self, x: np.ndarray, y: np.ndarray):
        """Clearance and the direction away from the nearest wall at points: exact to the obstacles'
        polygons near them, elsewhere bilinear between cell centres with the nearest cell's slope.

        Returns
        -------
        sdf : (n,) float32
            Signed distance to the nearest solid, metres.
        nx, ny : (n,) float32
            Unit normal pointing away from it.
        """
        return kernels.clearance(np.asarray(x), np.asarray(y), *self.lookup, self.flat_sdf, self.flat_nx,
                                 self.flat_ny, *self.exact)

    def is_solid(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """(n,) bool: points whose cell is solid."""
        return self.flat_solid[self.flat_index(x, y)]

    def nearest_label(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """(n,) int32: nearest obstacle polygon per point (-1: none / forbidden)."""
        return self.flat_label[self.flat_index(x, y)]

    def line_of_sight(self, ax, ay, bx, by, max_samples: int = LOS_MAX_SAMPLES) -> np.ndarray:
        """Whether segments a->b cross no solid cell.

        Samples each segment strictly inside at (up to) 0.7 cell spacing, at
        least 2 points; a segment longer than ``max_samples`` such steps is
        sampled more coarsely (thin walls may then be missed, which only
        matters beyond the perception range).

        Parameters
        ----------
        ax, ay, bx, by : (n,) float
            Segment end points, metres.
        max_samples : int
            Upper bound on samples per segment.

        Returns
        -------
        (n,) bool
        """
        n = len(ax)
        if n == 0 or not self.has_solid:
            return np.ones(n, dtype=bool)
        # Strictly inside: the end points are agents' positions, which may touch a wall's cell.
        return kernels.line_of_sight(np.asarray(ax), np.asarray(ay), np.asarray(bx), np.asarray(by),
                                     self.sight[0], max_samples, *self.lookup, self.flat_solid, self.flat_sdf)

    def cell_centers(self) -> np.ndarray:
        """(2, h*w) float64 centres of all cells, flat order."""
        return np.stack([self.centers_x.ravel(), self.centers_y.ravel()])


def field_is(field, meaning: str) -> bool:
    return field.meaning == code(LAYER_MEANINGS, meaning)


def generator_is(field, generator: str) -> bool:
    return field.generator == code(LAYER_GENERATORS, generator)
