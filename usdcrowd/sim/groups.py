"""Groups: leader following with memory, flocking and velocity matching.

Seed 003 keeps groups together with an (invisible) leader:
``grad E_L = -(x - x_hat_l(x, t))``, where ``x_hat_l`` is *the most recent
position of the leader visible from where the character stands*, so that a
member who loses sight of the guide behind a wall walks to where it last saw
it instead of into the wall. Here each leader leaves a trail of breadcrumbs
(:data:`params.TRAIL_LENGTH` positions, one every
:data:`params.TRAIL_INTERVAL` s); a member re-checks line of sight every
:data:`params.LOS_EVERY` steps (members staggered) to the leader and then to
breadcrumbs from newest to oldest, and remembers the first one it sees.

The radial field is saturated with Reynolds' *arrive* (full speed far away,
stopping at a follow distance growing with the group size) so that a far
member does not accelerate without bound. Leaders slow down while their group
lags behind (a common guide's courtesy, which keeps members within a bounded
distance).

Flocking (E_F: attraction to the centre of visible group-mates) and velocity
matching (E_V) use the neighbour table: group-mates among the k nearest,
within :data:`params.FLOCK_RADIUS` and in line of sight.
"""

from __future__ import annotations

import numpy as np

from ..core.model import AgentTable, GroupTable, ROLES, CONDITIONS, code
from . import params as P
from .grid import WalkGrid
from .kernels import follow_leaders, group_spread, remember_leaders
from .steering import cohesion, alignment


class Groups:
    """Leader/follower bookkeeping.

    Parameters
    ----------
    agents : AgentTable
    groups : GroupTable
    pos : (2, n + 1) float32
        Start positions (ghost last).

    Attributes
    ----------
    followers : (f,) int64
        Agent rows that follow a leader.
    leader_of : (f,) int64
        Their leader's row.
    leaders : (l,) int64
        Distinct leader rows.
    memory : (2, f) float32
        Remembered leader position of each follower, metres.
    """

    def __init__(self, agents: AgentTable, groups: GroupTable, pos: np.ndarray):
        n = len(agents)
        self.n = n
        leader = np.asarray(agents.leader, dtype=np.int64).copy()
        # Members without an explicit leader follow their group's leader.
        if len(groups):
            gl = np.asarray(groups.leader, dtype=np.int64)[np.asarray(agents.group, dtype=np.int64)]
            fill = (leader < 0) & (agents.role == code(ROLES, "member")) & (gl >= 0)
            leader[fill] = gl[fill]
        rows = np.arange(n)
        leader[leader == rows] = -1
        self.leader = leader
        self.followers = np.where(leader >= 0)[0]
        self.leader_of = leader[self.followers]
        self.leaders, self.slot = np.unique(self.leader_of, return_inverse=True)
        count = np.bincount(self.slot, minlength=len(self.leaders)).astype(np.float32)
        self.follow_dist = (P.FOLLOW_DISTANCE + P.FOLLOW_DISTANCE_PER_MATE * np.sqrt(count))[self.slot]
        self.follow_dist = self.follow_dist.astype(np.float32)
        self._count = np.maximum(count, 1.0)
        self._mean_follow_dist = np.bincount(self.slot, weights=self.follow_dist,
                                             minlength=len(self.leaders)) / self._count
        self.memory = pos[:, self.leader_of].copy()
        self.trail = np.repeat(pos[:, self.leaders][:, :, None], P.TRAIL_LENGTH, axis=2)  # (2, l, T)
        self.head = 0
        self._next_trail = 0.0
        self.isolated = agents.condition == code(CONDITIONS, "isolated")

    # -- leader trails and members' memory -------------------------------------
    def record_trail(self, time: float, pos: np.ndarray) -> None:
        """Append a breadcrumb for every leader every TRAIL_INTERVAL seconds."""
        if len(self.leaders) == 0 or time < self._next_trail:
            return
        self._next_trail = time + P.TRAIL_INTERVAL
        self.head = (self.head + 1) % P.TRAIL_LENGTH
        self.trail[:, :, self.head] = pos[:, self.leaders]

    def update_memory(self, step: int, pos: np.ndarray, grid: WalkGrid) -> None:
        """Refresh the remembered leader positions (line of sight, seed 003).

        Parameters
        ----------
        step : int
            Step counter (members are re-checked in LOS_EVERY staggered sets).
        pos : (2, n + 1) float32
        grid : WalkGrid
        """
        f = len(self.followers)
        if f == 0:
            return
        if not grid.has_solid:
            sub = np.arange(f)
        else:
            sub = np.arange(step % P.LOS_EVERY, f, P.LOS_EVERY)
        if sub.size == 0:
            return
        remember_leaders(pos, sub, self.followers, self.leader_of, self.slot, self.trail,
                         (self.head - np.asarray(P.TRAIL_PROBES)) % P.TRAIL_LENGTH,
                         np.float32(P.PERCEPTION_RANGE ** 2), self.memory, grid.has_solid, *grid.sight)

    def follow(self, pos: np.ndarray, speed: np.ndarray, was: np.ndarray, run: int, v: np.ndarray,
               behavior: np.ndarray) -> None:
        """Followers' intent, in place: arrive at the remembered leader position (``v`` (2, n) float32),
        and run where their leader ran last step (``was`` (n,) behaviors; ``behavior`` (n,) int8).

        Parameters
        ----------
        pos : (2, n + 1) float32
        speed : (n,) float32
            Preferred speeds.
        """
        follow_leaders(pos, self.followers, self.memory, speed, np.float32(P.FOLLOW_SPEED_FACTOR),
                       np.float32(P.FOLLOW_SLOW_RADIUS), self.follow_dist, self.leader_of, was, run, v, behavior)

    def leader_pace(self, pos: np.ndarray) -> np.ndarray:
        """Speed factor of each leader, < 1 while its group lags behind.

        Returns
        -------
        (l,) float32 in [LEADER_MIN_PACE, 1]
        """
        if len(self.leaders) == 0:
            return np.ones(0, np.float32)
        mean = group_spread(pos, self.followers, self.leader_of, self.slot, len(self.leaders)) / self._count
        pace = 1.0 - (mean - self._mean_follow_dist - 1.0) / P.LEADER_WAIT_SPREAD
        return np.minimum(np.maximum(pace, P.LEADER_MIN_PACE), 1.0).astype(np.float32)


def mate_mask(group: np.ndarray, idx: np.ndarray, isolated: np.ndarray) -> np.ndarray:
    """(n, k) float32: 1 where the neighbour is a group-mate (ghost excluded).

    Parameters
    ----------
    group : (n + 1,) int32
        Group row of each agent, -1 for the ghost.
    idx : (n, k) int32
        Neighbour table.
    isolated : (n,) bool
        Agents with condition "isolated" do not flock.
    """
    n = idx.shape[0]
    m = (group[idx] == group[:n, None]) & (group[idx] >= 0)
    m &= ~isolated[:, None]
    return m.astype(np.float32)


def flocking(dx, dv, dist, mates):
    """Cohesion (E_F) + velocity matching (E_V) with visible group-mates.

    Parameters
    ----------
    dx, dv : (2, n, k) float32
    dist : (n, k) float32
    mates : (n, k) float32
        Group-mate (and line-of-sight) mask from the last neighbour rebuild.

    Returns
    -------
    (2, n) float32 force
    """
    w = mates * (dist < P.FLOCK_RADIUS)
    count = w.sum(axis=1)
    return cohesion(dx, w, count) + alignment(dv, w, count)
