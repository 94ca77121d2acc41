"""The streaming event detector: chunks of frames in, an :class:`EventTable` out."""

from __future__ import annotations

import numpy as np

from ..core.model import EVENT_KINDS, HEALTH_STATES, CrowdFrames, Event, EventTable, code
from .groups import GroupRecord, GroupTracker
from .interactions import InteractionRecord, InteractionTracker
from .params import EventParams

_INTERACTION = code(EVENT_KINDS, "interaction")
_GROUP_MOTION = code(EVENT_KINDS, "groupMotion")
_DEAD = code(HEALTH_STATES, "dead")


class EventDetector:
    """Detects one-to-one interactions and group motions (seed 000, section 4.1).

    Feed the shot's frames in time order, in chunks of any size, then call
    :meth:`finish`. Memory is constant in the number of frames except for the
    samples of the events themselves; the result does not depend on how the
    frames were cut into chunks.

    Parameters
    ----------
    agents_character_type : (n,) int8
        Codes into CHARACTER_TYPES, per agent row.
    visible : (n,) bool
        Agents that are rendered; the others (invisible leaders) take part in
        nothing.
    fps : float
        Frames per second of the shot (turns the parameters' seconds into
        frames).
    params : EventParams, optional
        Thresholds; defaults suit pedestrians.
    scope : str
        Prim path under which the events are named.
    """

    def __init__(self, agents_character_type: np.ndarray, visible: np.ndarray, fps: float,
                 params: EventParams | None = None, scope: str = "/World/Events"):
        self.character_type = np.asarray(agents_character_type, np.int64).ravel()
        self.visible = np.asarray(visible, bool).ravel()
        if self.visible.shape != self.character_type.shape:
            raise ValueError(f"visible has {self.visible.size} agents, character types "
                             f"{self.character_type.size}")
        if not fps > 0:
            raise ValueError(f"fps must be > 0, got {fps!r}")
        self.fps = float(fps)
        self.params = params or EventParams()
        self.scope = scope.rstrip("/")
        n = self.n_agents
        self._interactions = InteractionTracker(n, self.fps, self.params)
        self._groups = GroupTracker(self.character_type, self.fps, self.params)
        self.frames_fed = 0
        self._last_time = -np.inf
        self._last_position = None
        self._last_present = None       # who was in the scene at the last frame fed (replays)
        self._finished = False

    @property
    def n_agents(self) -> int:
        return len(self.character_type)

    def feed(self, chunk: CrowdFrames) -> None:
        """Process the next frames.

        Parameters
        ----------
        chunk : CrowdFrames
            ``position`` (t, n, 3), ``heading`` (t, n), ``health`` (t, n) and
            ``times`` (t,), following the frames fed before.

        Notes
        -----
        Velocities are the positions' backward differences times fps (unknown
        at the first frame fed, where nobody takes part, however the frames are
        cut), not ``chunk.velocity``: that is exactly what can be recovered
        from a written shot (:func:`usdcrowd.scenario.crowd.read_crowd`), so
        detecting on a shot read back gives the events detected while it was
        simulated.
        """
        if self._finished:
            raise RuntimeError("EventDetector.feed after finish()")
        if chunk.position.shape[1:] != (self.n_agents, 3):
            raise ValueError(f"chunk has position {chunk.position.shape}, expected (t, {self.n_agents}, 3)")
        times = np.asarray(chunk.times, np.float64)
        if len(times) and (times[0] <= self._last_time or np.any(np.diff(times) <= 0)):
            raise ValueError("chunks must arrive in time order")
        velocity = self._velocity(np.asarray(chunk.position, np.float64)[..., :2])
        if chunk.present is not None and len(times):
            # Someone coming (back) into the scene moved from where they were held: no speed known yet.
            before = np.vstack([self._last_present[None] if self._last_present is not None
                                else np.zeros((1, chunk.present.shape[1]), bool), chunk.present[:-1]])
            velocity[chunk.present & ~before] = np.nan
            self._last_present = chunk.present[-1].copy()
        for i in range(len(times)):
            pos = chunk.position[i]
            vel = velocity[i]
            # The dead, and rows with no valid state, take part in nothing.
            ok = self.visible & np.isfinite(pos).all(axis=1) & np.isfinite(vel).all(axis=1)
            if chunk.health is not None:
                ok &= chunk.health[i] != _DEAD
            if chunk.present is not None:           # a replay's people before they come, after they go
                ok &= chunk.present[i]
            speed = np.hypot(vel[:, 0], vel[:, 1])
            t = float(times[i])
            self._interactions.step(self.frames_fed, t, pos, chunk.heading[i], speed, ok)
            self._groups.step(self.frames_fed, t, pos, vel, ok)
            self.frames_fed += 1
        if len(times):
            self._last_time = float(times[-1])

    def _velocity(self, xy: np.ndarray) -> np.ndarray:
        """(t, n, 2) velocities of a chunk's positions (see :meth:`feed`)."""
        prev = self._last_position
        self._last_position = xy[-1].copy() if len(xy) else prev
        if len(xy) == 0:
            return np.zeros((0,) + xy.shape[1:])
        before = np.concatenate([xy[:1] if prev is None else prev[None], xy[:-1]], axis=0)
        v = (xy - before) * self.fps
        if prev is None:
            v[0] = np.nan              # no motion known yet: not "standing still" either
        return v

    def finish(self) -> EventTable:
        """End the running events and return every event kept.

        Returns
        -------
        EventTable
            Detected events ordered by start time, then first member, then
            kind; ids count from 1 in that order over both kinds, paths are
            ``{scope}/Interaction_{id:04d}`` and ``{scope}/GroupMotion_{id:04d}``.
        """
        if self._finished:
            raise RuntimeError("EventDetector.finish called twice")
        self._finished = True
        events = [_interaction_event(r) for r in self._interactions.finish()]
        events += [_group_event(r) for r in self._groups.finish()]
        events.sort(key=lambda e: (e.start, int(e.members[0]) if len(e.members) else -1, e.kind))
        for i, e in enumerate(events, start=1):
            name = "Interaction" if e.kind == _INTERACTION else "GroupMotion"
            e.path = f"{self.scope}/{name}_{i:04d}"
        return EventTable(events)


def _interaction_event(r: InteractionRecord) -> Event:
    m = len(r.times)
    return Event(path="", kind=_INTERACTION, start=float(r.times[0]), end=float(r.times[-1]),
                 members=np.array([r.a, r.b], np.int32), times=r.times, active=np.ones((m, 2), bool),
                 center=r.center, radius=r.radius)


def _group_event(r: GroupRecord) -> Event:
    return Event(path="", kind=_GROUP_MOTION, start=float(r.times[0]), end=float(r.times[-1]),
                 members=r.members, times=r.times, active=r.active, center=r.center, radius=r.radius)


def detect_events(frames: CrowdFrames, character_type: np.ndarray, visible: np.ndarray, fps: float,
                  params: EventParams | None = None, scope: str = "/World/Events") -> EventTable:
    """Detect the events of a whole shot at once (see :class:`EventDetector`).

    Parameters
    ----------
    frames : CrowdFrames
        The shot, (t, n, ...) arrays.
    character_type : (n,) int8
    visible : (n,) bool
    fps : float
    params : EventParams, optional
    scope : str

    Returns
    -------
    EventTable
    """
    det = EventDetector(character_type, visible, fps, params, scope)
    det.feed(frames)
    return det.finish()
