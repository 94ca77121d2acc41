"""Events the scenario itself causes: an explosion or an eruption (seed 004's generated layers).

A generated damage layer (BehaviorLayer with ``crowd:generator`` explosion or
volcano) becomes an event of kind explosion or eruption from its start time:
its members at each frame are the visible characters within ``reach`` times
the layer's radius of its origin (those hurt and those fleeing), its centre
is the origin and its radius that reach. It ends at the last frame anyone
is within reach; a blast nobody is near is no event.
"""

from __future__ import annotations

import numpy as np

from ..core import model
from ..core.framestore import frame_blocks

# Members are within this many layer radii of the origin.
REACH = 2.0
_KIND = {"explosion": "explosion", "volcano": "eruption"}


def layer_events(fields: list[model.BehaviorField], positions: np.ndarray, times: np.ndarray,
                 visible: np.ndarray, scope: str = "/World/Events", reach: float = REACH) -> list[model.Event]:
    """Explosion and eruption events of a scenario's generated layers.

    Parameters
    ----------
    fields : list[BehaviorField]
    positions : (t, n, 3) float array or FrameStore
        The crowd over the shot, metres.
    times : (t,) float
        Time codes.
    visible : (n,) bool
    reach : float
        Members are within ``reach`` x the layer's radius of its origin.

    Returns
    -------
    list[Event]
        One per generated layer that anyone comes near, in layer order.
    """
    out = []
    used: set[str] = set()
    times = np.asarray(times, dtype=np.float64)
    vis = np.flatnonzero(visible)
    for f in fields:
        generator = model.LAYER_GENERATORS[f.generator]
        if generator not in _KIND:
            continue
        first = int(np.searchsorted(times, f.start_time - 1e-6))
        if first >= len(times) or len(vis) == 0:
            continue
        r = reach * float(f.radius)
        origin = np.asarray(f.origin, dtype=np.float64)[:2]
        # In blocks of frames: positions may be a FrameStore on disk.
        near = np.concatenate([np.linalg.norm(block[:, vis, :2] - origin, axis=2) <= r
                               for block in frame_blocks(positions, first)])          # (m, v)
        frames = np.flatnonzero(near.any(axis=1))
        if len(frames) == 0:
            continue
        last = first + int(frames[-1])
        near = near[: last - first + 1]
        ever = near.any(axis=0)
        members = vis[ever].astype(np.int32)
        m = last - first + 1
        base = name = f"{scope}/{_KIND[generator].capitalize()}_{f.path.rstrip('/').rsplit('/', 1)[-1]}"
        k = 1
        while name in used:                    # two layers with one leaf name under different parents
            k += 1
            name = f"{base}_{k}"
        used.add(name)
        out.append(model.Event(name,
                               model.code(model.EVENT_KINDS, _KIND[generator]), float(times[first]),
                               float(times[last]), members, times[first:last + 1].copy(), near[:, ever],
                               np.tile(np.asarray(f.origin, dtype=np.float64), (m, 1)), np.full(m, r)))
    return out
