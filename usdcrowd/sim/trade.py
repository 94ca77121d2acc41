"""Market trading: wanderers stop face to face with resting sellers (seed 000's residents).

In seed 000's Weld Quay, residents sell their products to people of the other
group, which makes the one-to-one interactions its cameras film. Here an
agent with ``crowd:trades`` that wanders and passes within TRADE_NOTICE of a
resting agent with ``crowd:trades`` of another top-level group walks up to
them and stops TRADE_DISTANCE away; both face each other for TRADE_SECONDS
(a buyer who has not arrived after TRADE_APPROACH gives up), then each waits
TRADE_COOLDOWN before trading again. Fear reactions (behavior maps) still
override a trade: they are applied after it.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..core.model import AgentTable, GroupTable
from . import params as P

# Eye height a trader looks at, metres.
_EYE = 1.6


def top_groups(agents: AgentTable, groups: GroupTable) -> np.ndarray:
    """(n,) row of each agent's top-level group."""
    top = np.arange(len(groups))
    for g in range(len(groups)):            # parents come first
        if groups.parent[g] >= 0:
            top[g] = top[groups.parent[g]]
    return top[np.asarray(agents.group)]


class Trading:
    """Who trades with whom, and until when.

    Parameters
    ----------
    wanderers : (w,) int
        Rows of agents that wander (the buyers, among those that trade).
    resting : (r,) int
        Rows of agents that rest (the sellers, among those that trade).
    trades : (n,) bool
    top_group : (n,) int
    rng : numpy Generator
    """

    def __init__(self, wanderers: np.ndarray, resting: np.ndarray, trades: np.ndarray, top_group: np.ndarray,
                 rng: np.random.Generator):
        self.buyers = np.asarray(wanderers)[trades[wanderers]]
        self.sellers = np.asarray(resting)[trades[resting]]
        self.top = np.asarray(top_group)
        n = len(trades)
        self.partner = np.full(n, -1, np.int64)
        self.until = np.zeros(n)
        self.talking = np.zeros(n, bool)
        self.free_at = np.zeros(n)
        self.rng = rng

    @property
    def active(self) -> bool:
        return len(self.buyers) > 0 and len(self.sellers) > 0

    def apply(self, it, pos: np.ndarray, time: float, speed: np.ndarray) -> None:
        """Start and end trades at ``time`` (seconds) and set the traders' intent.

        Parameters
        ----------
        it : Intent
            ``v`` (2, n), ``look`` (3, n), ``face`` (n,) are written for traders.
        pos : (2, n + 1) float32
            Positions (the simulation's layout).
        speed : (n,) float
            Preferred speeds, m/s (a buyer walks up at its own).
        """
        # Trades that are over (or approaches given up) free both sides, after a cooldown.
        done = (self.partner >= 0) & (self.until <= time)
        self.partner[done] = -1
        self.talking[done] = False
        self.free_at[done] = time + P.TRADE_COOLDOWN
        buyers = self.buyers[(self.partner[self.buyers] < 0) & (self.free_at[self.buyers] <= time)]
        sellers = self.sellers[(self.partner[self.sellers] < 0) & (self.free_at[self.sellers] <= time)]
        if len(buyers) and len(sellers):
            tree = cKDTree(pos[:, sellers].T)
            d, k = tree.query(pos[:, buyers].T, distance_upper_bound=P.TRADE_NOTICE)
            for b, dist, j in zip(buyers, d, k):          # few at a time: one per passing buyer
                if not np.isfinite(dist):
                    continue
                s = sellers[j]
                if self.partner[s] >= 0 or self.top[s] == self.top[b]:
                    continue
                self.partner[[b, s]] = [s, b]
                self.until[[b, s]] = time + P.TRADE_APPROACH
        traders = np.flatnonzero(self.partner >= 0)
        if not len(traders):
            return
        other = self.partner[traders]
        # Buyers walk up and stop; once face to face the trade's own clock starts.
        walking = traders[np.isin(traders, self.buyers)]
        seller = self.partner[walking]
        d = pos[:, seller] - pos[:, walking]
        dist = np.sqrt((d * d).sum(axis=0))
        arrived = dist <= P.TRADE_DISTANCE + 0.05
        start = walking[arrived & ~self.talking[walking]]
        if len(start):
            end = time + self.rng.uniform(*P.TRADE_SECONDS, len(start))
            self.talking[start] = self.talking[self.partner[start]] = True
            self.until[start] = self.until[self.partner[start]] = end
        pace = np.clip((dist - P.TRADE_DISTANCE) / 1.0, 0.0, 1.0) * speed[walking]
        it.v[:, walking] = d / np.maximum(dist, 1e-6) * pace
        it.look[0, traders] = pos[0, other]
        it.look[1, traders] = pos[1, other]
        it.look[2, traders] = _EYE
        it.face[traders] = True
