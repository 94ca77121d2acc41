"""How much each event matters at each frame.

A live director ranks what happens: the one arrival of the day before the
ninth group walking past (unique before repetitive), something that just
began before something that has gone on for minutes (new before
long-running), a crowd before a pair (size), and whatever the user says
matters (weights by kind or by event).
"""

from __future__ import annotations

from collections import Counter

import numpy as np

from ..core import model
from .params import EditParams


def importance(events: model.EventTable, times: np.ndarray, fps: float, params: EditParams,
               visible: np.ndarray | None = None) -> np.ndarray:
    """(e, t) float64 importance of each event at each time code (0 where it is not under way).

    Parameters
    ----------
    events : EventTable
    times : (t,) float
        The shot's time codes.
    fps : float
        Frames per second (ages in seconds).
    params : EditParams
    visible : (n,) bool, optional
        Rendered agents: an event with nobody visible taking part is not filmable.

    Notes
    -----
    ``weight x uniqueness x novelty x size``, where uniqueness is
    ``1 / sqrt(events of the same kind in the shot)``, novelty falls from 1
    to 1/2 as ``0.5 + 0.5 exp(-age / novelty_seconds)``, and size is
    ``1 + 0.25 log2(members taking part)``.
    """
    times = np.asarray(times, dtype=np.float64)
    out = np.zeros((len(events), len(times)))
    per_kind = Counter(e.kind for e in events)
    for k, e in enumerate(events):
        frames, samples = e.on_frames(times)
        active = e.active if visible is None else e.active & np.asarray(visible, bool)[e.members][None]
        n = active.sum(axis=1)[samples]
        age = (e.times[samples] - e.start) / fps
        novelty = 0.5 + 0.5 * np.exp(-age / params.novelty_seconds)
        size = np.where(n > 0, 1.0 + 0.25 * np.log2(np.maximum(n, 1)), 0.0)
        out[k, frames] = weight_of(e, params) / np.sqrt(per_kind[e.kind]) * novelty * size
    return out


def weight_of(event: model.Event, params: EditParams) -> float:
    """The user's weight of ``event``: by its path or name, else by its kind, else 1."""
    name = event.path.rsplit("/", 1)[-1]
    for key in (event.path, name):
        if key in params.event_weights:
            return float(params.event_weights[key])
    return float(params.kind_weights.get(model.EVENT_KINDS[event.kind], 1.0))
