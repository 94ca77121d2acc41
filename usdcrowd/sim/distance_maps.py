"""Geodesic distance maps over the walkable grid and their descent directions.

Two ways of computing the distance from a source to every cell, around
obstacles (occlusion):

``method="dijkstra"`` (default)
    Dijkstra on the 8-connected grid graph (scipy.sparse.csgraph). Exact
    shortest paths *on the graph*, so distances are octile: up to ~8 % longer
    than the Euclidean geodesic for directions between the axes and the
    diagonals. Fast: O(cells log cells), one call for many sources.

``method="rays"`` (seed 003, Algorithm 1)
    Light propagation: the source "illuminates" every cell it sees (straight
    rays, occluded by solid cells) with its distance plus the Euclidean
    distance; obstacle corners that get lit become new sources. The fixed
    point is the true Euclidean geodesic distance (shortest paths in a
    polygonal domain bend only at convex corners) up to the grid's line of
    sight resolution. Costs (cells x corners x ray samples): use it for small
    scenes. Corners are the obstacles' polygon vertices pushed slightly
    outward (forbidden areas painted on images add no corners, so rays
    around them fall back to the visible-source distance).

Both return ``inf`` where the source cannot be reached.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from . import params as P
from .grid import WalkGrid


class DistanceMaps:
    """Distance maps and direction fields on one :class:`WalkGrid` (cached).

    Parameters
    ----------
    grid : WalkGrid
    method : {"dijkstra", "rays"}
    clearance : float
        Cells with no point this far from a solid are left out of the graph,
        so paths keep bodies off the walls, metres. A cell's centre may lie
        half a cell off the line a path takes through it: with walls where
        their polygons stand, a 1.2 m door kept only its middle two rows of
        cells by their centres and a 0.8 m one none.
    """

    def __init__(self, grid: WalkGrid, method: str = "dijkstra", clearance: float = P.NAV_CLEARANCE):
        if method not in ("dijkstra", "rays"):
            raise ValueError(f"unknown distance method {method!r}")
        self.grid = grid
        self.method = method
        self.free = grid.sdf > clearance - 0.5 * grid.cell
        if not self.free.any():
            self.free = grid.sdf > 0
        self._graph = None
        self._nearest_free = None
        self._cache: dict = {}

    # -- graph ---------------------------------------------------------------
    def _build_graph(self):
        g = self.grid
        free = self.free
        idx = np.arange(g.h * g.w).reshape(g.h, g.w)
        rows, cols, wts = [], [], []
        c = g.cell
        # (dy, dx, weight): right, up, up-right, up-left.
        for dy, dx, wgt in ((0, 1, c), (1, 0, c), (1, 1, c * np.sqrt(2)), (1, -1, c * np.sqrt(2))):
            # Cell (i, j) -> (i + dy, j + dx); views of the valid sources and
            # their destinations.
            j0, j1 = max(0, -dx), g.w - max(0, dx)
            src = (slice(0, g.h - dy), slice(j0, j1))
            dst = (slice(dy, g.h), slice(j0 + dx, j1 + dx))
            ok = free[src] & free[dst]
            if dx != 0 and dy != 0:
                # Diagonals need both orthogonal neighbours free so paths
                # don't cut obstacle corners.
                ok &= free[dy:g.h, j0:j1] & free[0:g.h - dy, j0 + dx:j1 + dx]
            rows.append(idx[src][ok])
            cols.append(idx[dst][ok])
            wts.append(np.full(int(ok.sum()), wgt))
        n = g.h * g.w
        self._graph = coo_matrix((np.concatenate(wts), (np.concatenate(rows), np.concatenate(cols))),
                                 shape=(n, n)).tocsr()

    def _snap(self, xy: np.ndarray) -> np.ndarray:
        """Flat indices of the free cells nearest to points (k, 2)."""
        g = self.grid
        f = g.flat_index(xy[:, 0], xy[:, 1])
        if self._nearest_free is None:
            _, inds = ndimage.distance_transform_edt(~self.free, return_indices=True)
            self._nearest_free = (inds[0] * g.w + inds[1]).ravel()
        return self._nearest_free[f]

    # -- distance ------------------------------------------------------------
    def distance(self, sources: np.ndarray, key=None) -> np.ndarray:
        """Geodesic distance from the nearest of several source points.

        Parameters
        ----------
        sources : (k, 2) float
            Source points, metres.
        key : hashable, optional
            Cache key (e.g. ``("goal", 3)``).

        Returns
        -------
        (h, w) float64
            Distance of every cell, metres; inf where unreachable.
        """
        if key is not None and key in self._cache:
            return self._cache[key][0]
        sources = np.atleast_2d(np.asarray(sources, dtype=np.float64))
        if self.method == "rays" and self.grid.has_solid:
            d = self._rays(sources)
        else:
            d = self._dijkstra(sources)
        if key is not None:
            self._cache[key] = (d, None)
        return d

    def distance_to_mask(self, mask: np.ndarray, key=None) -> np.ndarray:
        """Geodesic distance to the nearest cell of a region (food, rest places).

        Parameters
        ----------
        mask : (h, w) bool
            Source cells.

        Returns
        -------
        (h, w) float64, inf where unreachable (or when the mask is empty)
        """
        if key is not None and key in self._cache:
            return self._cache[key][0]
        g = self.grid
        if not mask.any():
            d = np.full((g.h, g.w), np.inf)
        elif not g.has_solid or self.method == "rays":
            # Open ground: exact Euclidean distance transform. (With rays and
            # obstacles this ignores occlusion: regions are many sources.)
            d = ndimage.distance_transform_edt(~mask) * g.cell
        else:
            if self._graph is None:
                self._build_graph()
            src = np.unique(self._snap(np.stack([g.centers_x[mask], g.centers_y[mask]], axis=1)))
            d = dijkstra(self._graph, directed=False, indices=src, min_only=True).reshape(g.h, g.w)
        if key is not None:
            self._cache[key] = (d, None)
        return d

    def _dijkstra(self, sources):
        g = self.grid
        if not g.has_solid:
            cx, cy = g.centers_x, g.centers_y
            d2 = np.min((cx[None] - sources[:, 0, None, None]) ** 2 + (cy[None] - sources[:, 1, None, None]) ** 2,
                        axis=0)
            return np.sqrt(d2)
        if self._graph is None:
            self._build_graph()
        src = np.unique(self._snap(sources))
        d = dijkstra(self._graph, directed=False, indices=src, min_only=True)
        return d.reshape(g.h, g.w)

    def _rays(self, sources):
        """Seed 003's Algorithm 1 with obstacle corners as secondary sources."""
        g = self.grid
        corners = self._corners()
        cells = g.cell_centers()  # (2, m)
        m = cells.shape[1]
        D = np.full(m, np.inf)
        # Sources: the exhibit points (distance 0) then corners in order of
        # increasing distance (a Dijkstra over the corner visibility graph,
        # which is the order in which Algorithm 1's sources switch on).
        pts = np.concatenate([sources, corners]) if len(corners) else sources
        ns = len(sources)
        dist = np.full(len(pts), np.inf)
        dist[:ns] = 0.0
        done = np.zeros(len(pts), dtype=bool)
        while True:
            cand = np.where(~done & np.isfinite(dist))[0]
            if cand.size == 0:
                break
            s = cand[np.argmin(dist[cand])]
            done[s] = True
            sx, sy = pts[s]
            vis = self._visible_from(sx, sy, cells)
            d = dist[s] + np.hypot(cells[0] - sx, cells[1] - sy)
            np.minimum(D, np.where(vis, d, np.inf), out=D)
            # Light the other sources this one sees.
            others = np.where(~done)[0]
            if others.size:
                ok = g.line_of_sight(np.full(others.size, sx), np.full(others.size, sy),
                                     pts[others, 0], pts[others, 1], max_samples=4096)
                dd = dist[s] + np.hypot(pts[others, 0] - sx, pts[others, 1] - sy)
                upd = ok & (dd < dist[others])
                dist[others[upd]] = dd[upd]
        D[g.solid.ravel()] = np.inf
        return D.reshape(g.h, g.w)

    def _visible_from(self, sx, sy, cells, chunk=20000):
        g = self.grid
        m = cells.shape[1]
        out = np.empty(m, dtype=bool)
        for a in range(0, m, chunk):  # chunks of cells bound the memory
            b = min(m, a + chunk)
            out[a:b] = g.line_of_sight(np.full(b - a, sx), np.full(b - a, sy), cells[0, a:b], cells[1, a:b],
                                       max_samples=4096)
        return out

    def _corners(self):
        g = self.grid
        if len(g.polygons) == 0:
            return np.zeros((0, 2))
        v = g.polygons  # (o, K, 2)
        prev = np.roll(v, 1, axis=1)
        nxt = np.roll(v, -1, axis=1)
        e1 = v - prev
        e2 = nxt - v
        # Outward bisector of each convex CCW vertex: minus the sum of the
        # inward normals of its two edges.
        n1 = np.stack([e1[..., 1], -e1[..., 0]], axis=-1)
        n2 = np.stack([e2[..., 1], -e2[..., 0]], axis=-1)
        n1 /= np.maximum(np.linalg.norm(n1, axis=-1, keepdims=True), 1e-12)
        n2 /= np.maximum(np.linalg.norm(n2, axis=-1, keepdims=True), 1e-12)
        bis = n1 + n2
        bis /= np.maximum(np.linalg.norm(bis, axis=-1, keepdims=True), 1e-12)
        c = (v + bis * 0.75 * g.cell).reshape(-1, 2)
        c = np.unique(np.round(c, 6), axis=0)
        keep = ~g.is_solid(c[:, 0], c[:, 1])
        return c[keep]

    # -- directions ----------------------------------------------------------
    def direction(self, sources: np.ndarray, key=None, distance: np.ndarray | None = None):
        """Unit descent direction of a distance map (toward the sources).

        Solid and unreachable cells are filled with the distance of their
        nearest reachable cell plus twice the gap, so that the gradient there
        points back into the walkable region.

        Returns
        -------
        dist : (h, w) float64
        dir : (2, h, w) float32
            Unit vectors (x, y) pointing downhill (toward the sources).
        """
        if key is not None and key in self._cache and self._cache[key][1] is not None:
            return self._cache[key]
        D = self.distance(sources, key=key) if distance is None else distance
        g = self.grid
        finite = np.isfinite(D)
        if not finite.all() and finite.any():
            gap, inds = ndimage.distance_transform_edt(~finite, return_indices=True)
            Df = np.where(finite, D, D[inds[0], inds[1]] + 2.0 * gap * g.cell)
        else:
            Df = np.where(finite, D, 0.0)
        gy, gx = np.gradient(Df, g.cell)
        norm = np.hypot(gx, gy)
        ok = norm > 1e-9
        norm[~ok] = 1.0
        dirs = np.stack([-gx / norm, -gy / norm]).astype(np.float32)
        dirs[:, ~ok] = 0.0
        if key is not None:
            self._cache[key] = (D, dirs)
        return D, dirs


def sample_grid(grid: WalkGrid, arr: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Nearest-cell values of a (h, w) or (c, h, w) grid array at points.

    Returns
    -------
    (n,) or (c, n)
    """
    f = grid.flat_index(x, y)
    if arr.ndim == 2:
        return arr.ravel()[f]
    return arr.reshape(arr.shape[0], -1)[:, f]
