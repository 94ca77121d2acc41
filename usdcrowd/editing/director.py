"""The edited cut: which camera is on air at each frame, planned over the whole shot.

Every camera is worth, at every frame, what it shows: for each event under
way its importance (:mod:`.importance`) times how well the camera frames it
(:mod:`.coverage`); the most valuable event is why it would be on air.
The cut is the sequence of shots with the most value in total, less a cost
per cut, such that every shot lasts ``min_hold`` to ``max_hold`` seconds,
consecutive shots come from different cameras, and no cut between two shots
of one event breaks the 30-degree or the 180-degree rule (:mod:`.rules`).

An editor sees the whole take; so does this director: the plan is the
optimum of a semi-Markov dynamic programme over cut instants every
``decision_step`` seconds (O(instants x holds x cameras^2)), not a greedy
choice frame by frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .coverage import Coverage
from .importance import importance
from .params import EditParams
from .rules import OK, broken_rule


@dataclass
class Shot:
    """One shot of the cut: camera ``camera`` on air for frames ``start`` to ``end`` - 1 (indices).

    Attributes
    ----------
    event : int
        The event the shot is for (the one worth most over it), -1 for none.
    held_long : bool
        Held past ``max_hold`` because no allowed cut existed (say, one camera).
    """

    camera: int
    start: int
    end: int
    event: int
    held_long: bool = False

    @property
    def frames(self) -> int:
        return self.end - self.start


@dataclass
class Cut:
    """The planned cut and why.

    Attributes
    ----------
    shots : list[Shot]
        In order, covering every frame once.
    camera : (t,) int
        Camera on air per frame.
    event : (t,) int
        The event it is on air for, per frame (-1: none; the frame's own best).
    value : (c, t) float64
        Each camera's worth per frame.
    best_event : (c, t) int
        The event each camera's worth comes from (-1: none).
    importance : (e, t) float64
    framing : (c, e, t) float32
    refused : dict
        Cuts the rules refused at the instants considered: rule -> count.
    """

    shots: list
    camera: np.ndarray
    event: np.ndarray
    value: np.ndarray
    best_event: np.ndarray
    importance: np.ndarray
    framing: np.ndarray
    refused: dict


def camera_values(cov: Coverage, imp: np.ndarray, params: EditParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each camera's worth per frame, the event it comes from, and the framing.

    Returns
    -------
    value : (c, t) float64
        The best event's importance x framing, plus a quarter of the others',
        plus ``idle_weight`` x the legible people shown (up to five).
    best : (c, t) int
        The best event (-1 where none is framed at all).
    framing : (c, e, t) float32
    """
    framing = cov.framing(params)
    c, e, t = framing.shape
    if e == 0:
        per = np.zeros((c, 0, t))
        best = np.full((c, t), -1)
        top = np.zeros((c, t))
        rest = np.zeros((c, t))
    else:
        per = framing * imp[None]
        best = per.argmax(axis=1)
        top = per.max(axis=1)
        rest = per.sum(axis=1) - top
        best = np.where(top > 0, best, -1)
    idle = params.idle_weight * np.minimum(cov.shown, 5.0) / 5.0
    return top + 0.25 * rest + idle, best, framing


def plan_cut(cov: Coverage, events, fps: float, params: EditParams | None = None,
             visible: np.ndarray | None = None) -> Cut:
    """Plan the cut of a shot (see the module).

    Parameters
    ----------
    cov : Coverage
        Every camera's view of every event.
    events : EventTable
    fps : float
    params : EditParams, optional
    visible : (n,) bool, optional
        Rendered agents (for the events' sizes).
    """
    params = params or EditParams()
    imp = importance(events, cov.times, fps, params, visible)
    value, best, framing = camera_values(cov, imp, params)
    c, t = value.shape
    step = max(1, int(round(params.decision_step * fps)))
    starts = np.append(np.arange(0, t, step), t)
    k_blocks = len(starts) - 1
    cost = params.cut_cost * fps * max(float(value.max(axis=0).mean()) if t else 0.0, 1e-6)
    allowed, refused = _allowed_cuts(cov, best, starts, params, fps)
    lo, hi = params.min_hold * fps, params.max_hold * fps
    cum = _cumulative(value, starts)
    plan = _best_partition(cum, starts, allowed, cost, lo, hi)
    held_long = False
    if plan is None:                            # no cut the cameras and rules allow: hold longer
        plan = _best_partition(cum, starts, allowed, cost, min(lo, t), float(t))
        held_long = True
    if plan is None:                            # shorter than a shot: the best camera throughout
        plan = [(int(np.argmax(value.sum(axis=1))), 0, k_blocks)]
        held_long = False
    elif not held_long and params.fatigue_seconds > 0 and len(events) > 1:
        plan, imp, value, best = _worn_plan(cov, imp, params, fps, starts, plan, cost, lo, hi)
    shots = []
    on_air = np.zeros(t, np.int64)
    for cam, s, k in plan:
        a, b = int(starts[s]), int(starts[k])
        on_air[a:b] = cam
        ev = best[cam, a:b]
        worth = np.bincount(ev[ev >= 0], weights=value[cam, a:b][ev >= 0], minlength=max(len(events), 1))
        event = int(np.argmax(worth)) if (ev >= 0).any() else -1
        shots.append(Shot(cam, a, b, event, held_long and (b - a) > hi + 1e-9))
    event = best[on_air, np.arange(t)] if t else np.zeros(0, np.int64)
    return Cut(shots, on_air, event, value, best, imp, framing, refused)


def _cumulative(value: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """(c, K + 1) each camera's worth summed over the blocks before each instant."""
    c, t = value.shape
    block = np.add.reduceat(value, starts[:-1], axis=1) if t else np.zeros((c, 0))
    return np.concatenate([np.zeros((c, 1)), np.cumsum(block, axis=1)], axis=1)


def _worn_plan(cov: Coverage, imp: np.ndarray, params: EditParams, fps: float, starts: np.ndarray, plan: list,
               cost: float, lo: float, hi: float):
    """The cut planned shot by shot with screen time wearing events out (``fatigue_seconds``).

    An event's importance is divided by 1 + (seconds the cut has shown it) / fatigue_seconds. That is
    not known before the cut is, so the director commits one shot at a time: it plans the rest of the
    shot from there with the screen time of the shots committed so far (a receding horizon), keeping
    the first shot of that plan. Returns the plan, the worn importance and the values it was planned on.
    """
    e, t = imp.shape
    screen = np.zeros(e)                         # seconds on air so far, per event
    worn = imp.copy()
    out, s0, prev = [], 0, -1
    k_blocks = len(starts) - 1
    rest = plan
    while s0 < k_blocks:
        a = int(starts[s0])
        worn[:, a:] = imp[:, a:] / (1.0 + screen[:, None] / params.fatigue_seconds)
        value, best, _ = camera_values(cov, worn, params)
        allowed, _ = _allowed_cuts(cov, best, starts, params, fps)
        first = np.ones(len(value), bool) if prev < 0 else allowed[s0, prev]
        cum = _cumulative(value, starts)[:, s0:]
        new = _best_partition(cum - cum[:, :1], starts[s0:] - starts[s0], allowed[s0:], cost, lo, hi, first)
        if new is not None:
            rest = [(cam, s + s0, k + s0) for cam, s, k in new]
        cam, s, k = rest[0]
        out.append((cam, s, k))
        b = int(starts[k])
        ev = best[cam, a:b]
        screen += np.bincount(ev[ev >= 0], minlength=e)[:e] / fps
        rest, s0, prev = rest[1:], k, cam
    # ``worn`` was last changed before the last pass: its values are that pass's.
    return out, worn, value, best


def _allowed_cuts(cov: Coverage, best: np.ndarray, starts: np.ndarray, params: EditParams, fps: float):
    """(K, c, c) bool: a cut from camera a to b at instant ``starts[k]`` is allowed; and the refusals counted.

    The shots on either side are taken to be of the event each camera framed last before the cut (within
    a shortest shot's length) and first after it: a camera that has just lost its event is still on a
    shot of it.
    """
    c = best.shape[0]
    t = best.shape[1]
    k_blocks = len(starts) - 1
    window = max(1, int(round(params.min_hold * fps)))
    allowed = np.ones((k_blocks, c, c), bool)
    allowed[:, np.arange(c), np.arange(c)] = False          # a cut to the same camera is no cut
    refused: dict[str, int] = {}
    for k in range(1, k_blocks):
        f = int(starts[k])
        ea = np.array([_last_event(best[a, max(0, f - window):f]) for a in range(c)])
        eb = np.array([_first_event(best[b, f:min(t, f + window)]) for b in range(c)])
        same = (ea[:, None] == eb[None]) & (ea[:, None] >= 0)
        same[np.arange(c), np.arange(c)] = False
        for a, b in zip(*np.nonzero(same)):
            e = int(ea[a])
            if not np.isfinite(cov.centre[e, f]).all():
                continue
            rule = str(broken_rule(cov.eye[a, f - 1], cov.eye[b, f], cov.centre[e, f], cov.line[e, f],
                                   cov.size[a, e, f - 1], cov.size[b, e, f], params).item())
            if rule != OK:
                allowed[k, a, b] = False
                refused[rule] = refused.get(rule, 0) + 1
    return allowed, refused


def _last_event(events: np.ndarray) -> int:
    found = events[events >= 0]
    return int(found[-1]) if len(found) else -1


def _first_event(events: np.ndarray) -> int:
    found = events[events >= 0]
    return int(found[0]) if len(found) else -1


def _best_partition(cum: np.ndarray, starts: np.ndarray, allowed: np.ndarray, cost: float, lo: float, hi: float,
                    first: np.ndarray | None = None):
    """The best sequence of (camera, first block, end block) with every shot lo..hi frames long, or None.

    ``best[k, c]``: the most value of a cut of blocks [0, k) whose last shot
    is on camera c; a shot [s, k) on c adds ``cum[c, k] - cum[c, s]``, and a
    cut into it from c' at s is allowed by ``allowed[s, c', c]`` and costs ``cost``; ``first`` (c,) bool,
    if given, the cameras the first shot may be on (a cut from the shot before the plan).
    """
    c, k1 = cum.shape
    k_blocks = k1 - 1
    best = np.full((k1, c), -np.inf)
    back_s = np.full((k1, c), -1)
    back_c = np.full((k1, c), -1)
    frames = starts.astype(np.float64)
    for k in range(1, k1):
        length = frames[k] - frames[:k]                        # frames of a shot [s, k), s = 0..k-1
        for s in np.flatnonzero((length >= lo - 1e-9) & (length <= hi + 1e-9)):
            gain = cum[:, k] - cum[:, s]
            if s == 0:
                cand, prev = (gain if first is None else np.where(first, gain, -np.inf)), np.full(c, -1)
            else:
                trans = np.where(allowed[s], best[s][:, None], -np.inf)     # (c', c)
                prev = np.argmax(trans, axis=0)
                cand = trans[prev, np.arange(c)] - cost + gain
            better = cand > best[k]
            best[k, better] = cand[better]
            back_s[k, better] = s
            back_c[k, better] = prev[better]
    if not np.isfinite(best[k_blocks]).any():
        return None
    plan = []
    cam, k = int(np.argmax(best[k_blocks])), k_blocks
    while k > 0:
        s = int(back_s[k, cam])
        plan.append((cam, s, k))
        cam, k = int(back_c[k, cam]), s
    return plan[::-1]
