"""Group-motion events: the groups of each frame followed over time.

Each frame's groups (:func:`usdcrowd.events.quadtree.find_groups`) are matched
to the running events by the overlap of member sets, greedily, largest
overlap first: a group continues the event it shares most members with, so
when a group splits the larger part keeps the event and the other part starts
a new one, and when two groups merge the event with more members in common
goes on while the other runs out of members and ends.

Per frame the state is a few arrays over the agents (who belongs to which
running event, when each was last seen in its group), so memory does not
grow with the number of frames, except for the events' own samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .params import EventParams
from .quadtree import find_groups


@dataclass
class GroupRecord:
    """A finished group-motion event, before it is numbered.

    Attributes
    ----------
    members : (k,) int32
        Agent rows of everyone who took part, ascending.
    times : (m,) float64
        Time codes, every frame of the event.
    active : (m, k) bool
        Member ``j`` is in the event's group at ``times[i]`` (gaps up to the
        membership hysteresis filled).
    center : (m, 3) float64
        Mean position of the members in the event's group at that frame (on
        a frame without a group: of its current members), metres.
    radius : (m,) float64
        Largest planar distance of those members from the centre, plus the
        margin, metres.
    """

    members: np.ndarray
    times: np.ndarray
    active: np.ndarray
    center: np.ndarray
    radius: np.ndarray


class _Track:
    """A running group-motion event: per-frame samples since its start."""

    __slots__ = ("key", "start", "last", "detected", "n_detected", "times", "rows", "center", "radius")

    def __init__(self, key: int, start: int):
        # Frames: first, last with a group (detected or coasting), last detected.
        self.key, self.start, self.last, self.detected = key, start, start, start
        self.n_detected = 0  # frames continued by a detected group
        self.times: list[float] = []
        self.rows: list[np.ndarray] = []  # members in the matched group, per frame
        self.center: list[np.ndarray] = []
        self.radius: list[float] = []


class GroupTracker:
    """Follows group motions over frames.

    Parameters
    ----------
    character_type : (n,) int
        Codes into CHARACTER_TYPES, per agent row.
    fps : float
    params : EventParams
    """

    def __init__(self, character_type: np.ndarray, fps: float, params: EventParams):
        self.p = params
        self.ctype = np.asarray(character_type, np.int64)
        n = len(self.ctype)
        self.member_gap = EventParams.frames(params.member_gap, fps)
        self.group_gap = EventParams.frames(params.group_gap, fps)
        self.coast = EventParams.frames(params.coast, fps)
        self.min_frames = max(EventParams.frames(params.group_min_duration, fps), 1)
        self.owner = np.full(n, -1, np.int64)  # key of the running event an agent belongs to
        self.last_seen = np.zeros(n, np.int64)  # last frame it was in that event's group
        self.running: dict[int, _Track] = {}  # by key, in creation order
        self.next_key = 0
        self.done: list[GroupRecord] = []

    def step(self, frame: int, time: float, position: np.ndarray, velocity: np.ndarray,
             eligible: np.ndarray) -> None:
        """Advance one frame.

        Parameters
        ----------
        frame : int
            Frame index since the first fed frame.
        time : float
            Its time code.
        position : (n, 3) float
        velocity : (n, 2) float
        eligible : (n,) bool
            Agents that may take part (visible, alive).
        """
        labels, sizes, small = self._groups(position, velocity, eligible)

        # Members not seen in their event's group for too long are let go.
        stale = (self.owner >= 0) & (frame - self.last_seen > self.member_gap)
        self.owner[stale] = -1

        matched_g = self._match(labels, sizes)
        self._continue_or_start(frame, labels, sizes, small, matched_g)

        # Events no group continues may go on, for a while, with their own
        # members that still move together: the grid misses a small group
        # cut by cell borders, or one whose cells passers-by spoil.
        coasting = [t for t in self.running.values()
                    if t.detected < frame and frame - t.detected <= self.coast
                    and t.n_detected >= self.min_frames]
        if coasting:
            self._coast(coasting, frame, velocity, eligible)

        # End the events with no group for too long, or with no members left.
        counts = np.bincount(self.owner[self.owner >= 0], minlength=self.next_key)
        for key in [k for k, t in self.running.items() if frame - t.last > self.group_gap or counts[k] == 0]:
            self._close(self.running.pop(key))

        if self.running:
            self._sample(frame, time, position)

    def _groups(self, position: np.ndarray, velocity: np.ndarray, eligible: np.ndarray):
        """Group label per agent ((n,) int, -1: none), group sizes, and which groups are too small."""
        p = self.p
        n = len(self.owner)
        idx = np.flatnonzero(eligible)
        labels = np.full(n, -1, np.int64)
        labels[idx] = find_groups(position[idx, :2], velocity[idx], self.ctype[idx], p)
        has = labels >= 0
        sizes = np.bincount(labels[has]) if has.any() else np.zeros(0, np.int64)
        # Groups too small to keep an event are no groups at all.
        small = sizes < p.min_members_keep
        labels[has] = np.where(small[labels[has]], -1, labels[has])
        return labels, sizes, small

    def _match(self, labels: np.ndarray, sizes: np.ndarray) -> dict[int, int]:
        """``{group label: event key}``, greedily by the overlap of groups with events' current members."""
        p = self.p
        matched_g: dict[int, int] = {}
        both = (labels >= 0) & (self.owner >= 0)
        if both.any():
            k = self.next_key
            pair, common = np.unique(labels[both] * k + self.owner[both], return_counts=True)
            g, e = pair // k, pair % k
            esize = np.bincount(self.owner[self.owner >= 0], minlength=k)
            ok = common >= p.match_overlap * np.minimum(sizes[g], esize[e])
            g, e, common = g[ok], e[ok], common[ok]
            taken_e: set[int] = set()
            # Largest overlap first; ties by older event, then by group's first agent.
            for i in np.lexsort((g, e, -common)):
                gi, ei = int(g[i]), int(e[i])
                if gi in matched_g or ei in taken_e:
                    continue
                matched_g[gi] = ei
                taken_e.add(ei)
        return matched_g

    def _continue_or_start(self, frame: int, labels: np.ndarray, sizes: np.ndarray, small: np.ndarray,
                           matched_g: dict[int, int]) -> None:
        """Each kept group continues its matched event, or starts one if it is big enough."""
        has = labels >= 0
        # Members of each group, by label.
        order = np.flatnonzero(has)[np.argsort(labels[has], kind="stable")]
        bounds = np.concatenate([[0], np.cumsum(np.bincount(labels[has], minlength=len(sizes)))])
        for gi in range(len(sizes)):
            if small[gi]:
                continue
            rows = order[bounds[gi]:bounds[gi + 1]]
            ei = matched_g.get(gi)
            if ei is None:
                if len(rows) < self.p.min_members_create:
                    continue
                ei = self.next_key
                self.next_key += 1
                self.running[ei] = _Track(ei, frame)
            self.running[ei].detected = frame
            self.running[ei].n_detected += 1
            self._support(self.running[ei], rows, frame)

    def _support(self, track: _Track, rows: np.ndarray, frame: int) -> None:
        """``rows`` (k,) are the event's group at ``frame``."""
        track.last = frame
        self.owner[rows] = track.key
        self.last_seen[rows] = frame
        # Pad to this frame (a frame without support records no rows).
        track.rows.extend([np.zeros(0, np.int64)] * (frame - track.start - len(track.rows)))
        track.rows.append(rows.astype(np.int64))

    def _coast(self, tracks: list[_Track], frame: int, velocity: np.ndarray, eligible: np.ndarray) -> None:
        """Continue ``tracks`` with their current members that move with their mean motion."""
        p = self.p
        keys = np.array([t.key for t in tracks], np.int64)  # ascending
        flag = np.zeros(self.next_key, bool)
        flag[keys] = True
        cur = np.flatnonzero((self.owner >= 0) & eligible)
        cur = cur[flag[self.owner[cur]]]
        if len(cur) == 0:
            return
        ev = np.searchsorted(keys, self.owner[cur])
        r = len(keys)
        v = velocity[cur].astype(np.float64)
        speed = np.hypot(v[:, 0], v[:, 1])
        moving = speed > 1e-6
        u = np.where(moving[:, None], v / np.maximum(speed, 1e-12)[:, None], 0.0)
        su = np.stack([np.bincount(ev, u[:, 0], r), np.bincount(ev, u[:, 1], r)], axis=1)
        d = su / np.maximum(np.hypot(su[:, 0], su[:, 1]), 1e-12)[:, None]
        ms = np.bincount(ev, speed, r) / np.maximum(np.bincount(ev, None, r), 1)
        cos = np.einsum("ij,ij->i", u, d[ev])
        ratio = p.member_speed_ratio
        ok = (moving & (cos >= np.cos(np.radians(p.member_angle)))
              & (speed * ratio >= ms[ev]) & (speed <= ratio * ms[ev]))
        n_ok = np.bincount(ev[ok], None, r)
        speed_ok = np.bincount(ev[ok], speed[ok], r) / np.maximum(n_ok, 1)
        alive = (n_ok >= p.min_members_keep) & (speed_ok >= p.min_speed)
        for i in np.flatnonzero(alive):
            self._support(tracks[i], cur[ok & (ev == i)], frame)

    def _sample(self, frame: int, time: float, position: np.ndarray) -> None:
        """Centre and radius of every running event, from its group at this
        frame, or from its current members on a frame without a group."""
        tracks = list(self.running.values())
        keys = np.array([t.key for t in tracks], np.int64)  # ascending
        who = np.full(len(self.owner), -1, np.int64)
        cur = self.owner >= 0
        who[cur] = np.searchsorted(keys, self.owner[cur])
        # Events with a group this frame: its members, not last second's stragglers.
        now = np.array([t.last == frame for t in tracks])
        who[cur] = np.where(now[who[cur]], -1, who[cur])
        if now.any():
            rows = [tracks[i].rows[-1] for i in np.flatnonzero(now)]
            who[np.concatenate(rows)] = np.repeat(np.flatnonzero(now), [len(r) for r in rows])
        sel = who >= 0
        ev = who[sel]
        pos = position[sel].astype(np.float64)
        r = len(keys)
        cnt = np.maximum(np.bincount(ev, minlength=r), 1)
        center = np.stack([np.bincount(ev, pos[:, c], r) for c in range(3)], axis=1) / cnt[:, None]
        d = np.hypot(*(pos[:, :2] - center[ev, :2]).T)
        far = np.zeros(r)
        np.maximum.at(far, ev, d)
        radius = far + self.p.group_margin
        for i, t in enumerate(tracks):
            t.times.append(time)
            t.center.append(center[i])
            t.radius.append(float(radius[i]))

    def _close(self, t: _Track) -> None:
        """Release the event's members; keep it if it lasted long enough."""
        self.owner[self.owner == t.key] = -1
        m = t.last - t.start + 1
        if m < self.min_frames:
            return
        rows = t.rows[:m]
        members = np.unique(np.concatenate(rows)) if rows else np.zeros(0, np.int64)
        active = np.zeros((m, len(members)), bool)
        fi = np.repeat(np.arange(len(rows)), [len(r) for r in rows])
        active[fi, np.searchsorted(members, np.concatenate(rows))] = True
        active = fill_gaps(active, self.member_gap)
        self.done.append(GroupRecord(members.astype(np.int32), np.asarray(t.times[:m], np.float64), active,
                                     np.asarray(t.center[:m], np.float64).reshape(m, 3),
                                     np.asarray(t.radius[:m], np.float64)))

    def finish(self) -> list[GroupRecord]:
        """End every running event; the kept events in the order they ended."""
        for key in list(self.running):
            self._close(self.running.pop(key))
        return self.done


def fill_gaps(active: np.ndarray, gap: int) -> np.ndarray:
    """Fill runs of False no longer than ``gap`` between two True, per column.

    Parameters
    ----------
    active : (m, k) bool
    gap : int
        Longest run filled, frames.

    Returns
    -------
    (m, k) bool
    """
    m = len(active)
    if m == 0 or gap <= 0:
        return active
    i = np.arange(m)[:, None]
    prev = np.maximum.accumulate(np.where(active, i, -1), axis=0)
    nxt = np.minimum.accumulate(np.where(active, i, m)[::-1], axis=0)[::-1]
    return active | ((prev >= 0) & (nxt < m) & (nxt - prev - 1 <= gap))
