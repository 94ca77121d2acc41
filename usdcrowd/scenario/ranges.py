"""The crowd schema's documented value constraints, one check shared by the reader, events and validate."""

from __future__ import annotations

import math


def range_problem(name: str, v) -> str | None:
    """What is wrong with value ``v`` of crowd:``name`` (the schema's documented
    constraints), or None."""
    if isinstance(v, str):
        return None                 # tokens: checked against the schema's allowedTokens (_Reader.check_type)
    values = v if isinstance(v, (tuple, list)) else (v,)
    if any(isinstance(x, float) and not math.isfinite(x) for x in values):
        return f"not a finite number: {v}"
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
