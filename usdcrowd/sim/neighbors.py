"""Neighbour lists through a spatial index (never all pairs).

A Verlet-style list: the k nearest agents within ``radius + skin`` are found
through a grid of cells (:func:`.kernels.nearest_within`, on all cores) and
kept for several steps.
The list is rebuilt when some agent has moved more than half the skin since
the last build, or after ``max_age`` steps. Rows are padded with the index
``n`` of a far-away "ghost" agent, so that the force code needs no masks for
missing neighbours.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from . import params as P
from .kernels import moved_beyond, nearest_within


class NeighborList:
    """Fixed-k neighbour table over a subset of agents.

    Parameters
    ----------
    n : int
        Number of agents (the ghost row is ``n``).
    members : (m,) int
        Rows that take part (others neither have nor are neighbours; used
        for invisible leaders, which nobody collides with).
    k, radius, skin, max_age
        See :mod:`usdcrowd.sim.params`.

    Attributes
    ----------
    idx : (n, k) int32
        Neighbour rows, nearest first, ``n`` where none.
    rebuilds : int
        How many times the tree was built (for the benchmark).
    """

    def __init__(self, n: int, members: np.ndarray, k: int = P.NEIGHBOR_K,
                 radius: float = P.NEIGHBOR_RADIUS, skin: float = P.NEIGHBOR_SKIN,
                 max_age: int = P.NEIGHBOR_MAX_AGE):
        self.n = n
        self.members = np.asarray(members, dtype=np.int64)
        self.k = int(min(k, max(len(self.members) - 1, 1)))
        self.radius = radius
        self.skin = skin
        self.max_age = max_age
        self.idx = np.full((n, self.k), n, dtype=np.int32)
        self.age = max_age  # force a build on the first update
        self._ref = None
        self.rebuilds = 0

    def update(self, pos: np.ndarray) -> bool:
        """Rebuild the table if needed.

        Parameters
        ----------
        pos : (2, n + 1) float32
            Positions, ghost last.

        Returns
        -------
        bool
            True when the table was rebuilt (masks derived from it must be
            refreshed).
        """
        self.age += 1
        if self._ref is not None and self.age < self.max_age:
            if not moved_beyond(pos, self.members, self._ref, (0.5 * self.skin) ** 2):
                return False
        self._build(pos)
        return True

    def _build(self, pos: np.ndarray) -> None:
        m = self.members
        self.age = 0
        self.rebuilds += 1
        self._ref = pos[:, m].copy()
        if len(m) < 2:
            return
        j = nearest_within(pos[0, m].astype(np.float64), pos[1, m].astype(np.float64), self.k,
                           self.radius + self.skin)
        # Map point indices to agent rows; "none" (-1) to the ghost.
        lut = np.append(m, self.n).astype(np.int32)
        self.idx[m] = lut[j]


def nearest_of(pos: np.ndarray, rows: np.ndarray, targets: np.ndarray, max_dist: float):
    """Nearest target agent of each agent in ``rows`` (kd-tree over targets).

    Parameters
    ----------
    pos : (2, n + 1) float32
    rows, targets : (a,), (b,) int
    max_dist : float
        Farther targets are ignored, metres.

    Returns
    -------
    (a,) int64
        Target agent row, -1 where none within ``max_dist``.
    """
    out = np.full(len(rows), -1, dtype=np.int64)
    if len(rows) == 0 or len(targets) == 0:
        return out
    tree = cKDTree(pos[:, targets].T.astype(np.float64))
    d, j = tree.query(pos[:, rows].T.astype(np.float64), k=1, distance_upper_bound=max_dist, workers=-1)
    ok = np.isfinite(d)
    out[ok] = targets[j[ok]]
    return out
