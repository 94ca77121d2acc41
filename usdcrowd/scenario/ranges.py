"""The crowd schema's documented value constraints, one check shared by the reader, events and validate.

Besides the schema's own constraints (speeds >= 0, heights > 0...), values are
held to physical ranges, so that an absurd one (a body 1e30 m tall, an
interest point a light-year away) is refused before it produces a NaN shot or
a grid that cannot be allocated.
"""

from __future__ import annotations

import math

from ..core.shading import SCENERY_ID_BASE

# Body heights (crowd:height, crowd:heightRange), metres: from an ant to a giraffe.
HEIGHT_RANGE = (0.001, 10.0)
# Preferred speeds (crowd:speed, crowd:speedRange), m/s: a galloping horse is 20.
MAX_SPEED = 50.0
# The scene's extent: every position within this many metres of the origin
# (on each axis), every length below it. It bounds the grids the simulation
# allocates over the scene.
MAX_EXTENT = 100_000.0
# Track ids an agent can have (crowd:agentId), clones included: ids from 2^24
# up are the scenery's in the renderers' id buffers.
MAX_AGENT_ID = SCENERY_ID_BASE - 1
# Seeds (customLayerData usdcrowd.seed, --seed): what numpy's generators take.
MAX_SEED = (1 << 32) - 1


def range_problem(name: str, v) -> str | None:
    """What is wrong with value ``v`` of crowd:``name`` (the schema's documented
    constraints, then the physical ranges above), or None."""
    if isinstance(v, str):
        return None                 # tokens: checked against the schema's allowedTokens (_Reader.check_type)
    values = v if isinstance(v, (tuple, list)) else (v,)
    if any(isinstance(x, float) and not math.isfinite(x) for x in values):
        return f"not a finite number: {v}"
    return _schema_problem(name, v) or _physical_problem(name, v, values)


def _schema_problem(name: str, v) -> str | None:
    if name in ("speedRange", "heightRange", "elevationRange"):
        low_ok = v[0] > 0 if name == "heightRange" else v[0] >= 0
        if not low_ok or v[1] < v[0]:
            need = "0 < min <= max" if name == "heightRange" else "0 <= min <= max"
            return f"{tuple(v)} is not a valid range (need {need})"
    elif name == "speed" and v < 0:
        return f"negative speed {v}"
    elif name in ("height", "visitBudget", "radius", "viewDuration", "camera:maxSpeed", "camera:maxForce",
                  "camera:maxAngularSpeed", "camera:arrivalDistance", "camera:aimAngleThreshold") and v <= 0:
        return f"must be > 0, got {v}"
    elif name in ("maxSlope", "spawnRadius", "decayRate", "clones", "interest", "camera:separationDistance") and v < 0:
        return f"must be >= 0, got {v}"
    elif name == "subclones" and v < 1:
        return f"must be >= 1, got {v}"
    elif name in ("behaviorMapInfluence", "influence", "visibility", "priorKnowledge") and not 0 <= v <= 1:
        return f"must be in [0, 1], got {v}"
    elif name == "camera:viewAngle" and not 0 < v < 1:
        return f"must be in (0, 1), got {v}"
    return None


def _physical_problem(name: str, v, values) -> str | None:
    shown = ", ".join(f"{x:g}" for x in values)
    shown = f"({shown})" if isinstance(v, (tuple, list)) else shown
    if name in ("height", "heightRange") and not all(HEIGHT_RANGE[0] <= x <= HEIGHT_RANGE[1] for x in values):
        return f"{shown} m is not a body height: heights are {HEIGHT_RANGE[0]:g} to {HEIGHT_RANGE[1]:g} m"
    if name in ("speed", "speedRange") and any(x > MAX_SPEED for x in values):
        return f"{shown} m/s is not a walking speed: speeds are 0 to {MAX_SPEED:g} m/s"
    if name == "agentId" and v != -1 and not 1 <= v <= MAX_AGENT_ID:
        return f"agent ids are 1 to {MAX_AGENT_ID:,} (or -1: numbered automatically), got {v}"
    return None


def extent_problem(values, what: str = "position") -> str | None:
    """What is wrong with positions or lengths in canonical metres (any shape): not finite, or beyond the
    scene's extent (:data:`MAX_EXTENT`); None when they are fine."""
    import numpy as np

    p = np.asarray(values, dtype=np.float64)
    if not np.isfinite(p).all():
        return f"not a finite {what}"
    if p.size and float(np.abs(p).max()) > MAX_EXTENT:
        return (f"{what} reaches {float(np.abs(p).max()):.3g} m: usdcrowd's scenes lie within "
                f"{MAX_EXTENT / 1000:g} km of the origin")
    return None
