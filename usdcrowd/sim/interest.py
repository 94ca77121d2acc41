"""Interest fields (seed 003): where museum-like visitors go next.

Each interest point (exhibit) ``i`` gets a geodesic distance map ``D_i``
over the walkable grid, occluded by obstacles (see
:mod:`usdcrowd.sim.distance_maps` for Dijkstra versus the seed's Algorithm
1). Its attraction at ``x`` for a visiting group is

    E_i(x, t) = alpha_i(t) * beta_i(x) / (1 + D_i(x))

The extracted text of the seed garbles this formula (``alpha / (1 + D
beta)``); we read ``beta_i in (0, 1]`` as a *gain* ("accounts for exhibit
visibility and prior knowledge"): ``beta_i(x) = max(BETA_MIN, prior + (1 -
prior) * visibility * seen_i(x))`` where ``seen_i(x)`` is 1 when the exhibit
is in direct line of sight from ``x`` (the geodesic distance equals the
straight one). An exhibit one knows about or can see attracts more.

Interest decays while the group is near the exhibit (experience
accumulation): ``alpha_i -= lambda_i exp(-D_i(x_l)^2 / (2 sigma_i^2)) dt``
with ``lambda_i`` the decay (fruition) rate and ``sigma_i`` the exhibit's
radius. The leader walks down the gradient of the dominant field
``argmax_i E_i(x_l)``, i.e. along ``-grad D_i``, and stops near it while its
interest lasts. Visiting profiles change ``alpha(0)`` and ``lambda``
(:data:`params.PROFILE_INTEREST`); ``timeLimited`` groups drop all interest
once their group's ``visit_budget`` seconds are spent.
"""

from __future__ import annotations

import numpy as np

from ..core.model import Scenario, VISIT_PROFILES
from . import params as P
from .distance_maps import DistanceMaps


class InterestFields:
    """Distance maps of every exhibit and the interest state of visitors.

    Parameters
    ----------
    scenario : Scenario
    dmaps : DistanceMaps
    visitors : (v,) int
        Agent rows steered by interest (leaders / lone visitors).
    rng : numpy.random.Generator
        Draws of the casual profile's initial interest.

    Attributes
    ----------
    alpha : (v, m) float32
        Current interest of each visitor in each exhibit.
    dominant : (v,) int64
        Dominant exhibit of each visitor, -1 when none attracts any more.
    """

    def __init__(self, scenario: Scenario, dmaps: DistanceMaps, visitors: np.ndarray, rng):
        it = scenario.interest
        grid = dmaps.grid
        self.grid = grid
        self.m = m = len(it)
        self.visitors = np.asarray(visitors, dtype=np.int64)
        v = len(self.visitors)
        self.position = np.asarray(it.position, dtype=np.float64).reshape(m, 3)
        self.radius = np.maximum(np.asarray(it.radius, dtype=np.float64), 0.1)
        cells = grid.h * grid.w
        self.D = np.empty((m, cells), np.float32)
        self.dirs = np.empty((m, 2, cells), np.float32)
        self.beta = np.empty((m, cells), np.float32)
        cx, cy = grid.cell_centers()
        for i in range(m):  # once per exhibit
            src = self.position[i:i + 1, :2]
            D, dirs = dmaps.direction(src, key=("interest", i))
            D = D.ravel()
            self.D[i] = np.where(np.isfinite(D), D, 1e6)
            self.dirs[i] = dirs.reshape(2, -1)
            straight = np.hypot(cx - src[0, 0], cy - src[0, 1])
            seen = np.isfinite(D) & (D <= straight * 1.02 + 1.5 * grid.cell)
            prior = float(np.clip(it.prior_knowledge[i], 0.0, 1.0))
            vis = float(np.clip(it.visibility[i], 0.0, 1.0))
            self.beta[i] = np.maximum(P.BETA_MIN, prior + (1.0 - prior) * vis * seen)
        # Visiting profiles.
        prof = np.asarray(scenario.agents.visit_profile, dtype=np.int64)[self.visitors]
        lo = np.array([P.PROFILE_INTEREST[p][0] for p in VISIT_PROFILES])
        hi = np.array([P.PROFILE_INTEREST[p][1] for p in VISIT_PROFILES])
        mult = np.array([P.PROFILE_INTEREST[p][2] for p in VISIT_PROFILES])
        scale = rng.uniform(lo[prof][:, None], hi[prof][:, None], size=(v, m))
        base = np.asarray(it.interest, dtype=np.float64)[None, :]
        self.alpha = (base * scale).astype(np.float32)
        rate = np.asarray(it.decay_rate, dtype=np.float64)
        view = np.maximum(np.asarray(it.view_duration, dtype=np.float64), 1e-3)
        # No decay rate authored: spend about view_duration looking.
        rate = np.where(rate > 0, rate, np.asarray(it.interest, dtype=np.float64) / view)
        self.decay = (rate[None, :] * mult[prof][:, None]).astype(np.float32)
        self.time_limited = prof == VISIT_PROFILES.index("timeLimited")
        g = np.asarray(scenario.agents.group, dtype=np.int64)[self.visitors]
        budget = np.asarray(scenario.groups.visit_budget, dtype=np.float64)
        self.budget = budget[g] if len(budget) else np.full(v, np.inf)
        self.inv_two_sigma2 = (1.0 / (2.0 * self.radius ** 2)).astype(np.float32)
        self.dominant = np.full(v, -1, dtype=np.int64)

    def step(self, pos: np.ndarray, dt: float, time: float):
        """Decay interests and return the visitors' walking directions.

        Parameters
        ----------
        pos : (2, n + 1) float32
        dt : float, s
        time : float, s since the start

        Returns
        -------
        direction : (2, v) float32
            Unit descent direction toward the dominant exhibit (0 when none).
        pace : (v,) float32
            Speed factor: slows to 0 while standing at the exhibit.
        dominant : (v,) int64
            Dominant exhibit index, -1 when none.
        """
        vr = self.visitors
        f = self.grid.flat_index(pos[0, vr], pos[1, vr])
        Dn = self.D[:, f].T  # (v, m)
        E = self.alpha * self.beta[:, f].T / (1.0 + Dn)
        dom = np.argmax(E, axis=1)
        r = np.arange(len(vr))
        alive = self.alpha[r, dom] > P.INTEREST_MIN
        self.alpha -= self.decay * np.exp(-(Dn * Dn) * self.inv_two_sigma2[None, :]) * np.float32(dt)
        np.maximum(self.alpha, 0.0, out=self.alpha)
        over = self.time_limited & (time > self.budget)
        if over.any():
            self.alpha[over] = 0.0
        dom = np.where(alive, dom, -1)
        self.dominant = dom
        dsel = np.where(alive, dom, 0)
        direction = self.dirs[dsel, :, f].T * alive  # (2, v)
        rad = self.radius[dsel].astype(np.float32)
        pace = np.clip((Dn[r, dsel] - 0.5 * rad) / rad, 0.0, 1.0) * alive
        return direction.astype(np.float32), pace.astype(np.float32), dom
