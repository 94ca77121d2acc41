"""Minimal checks of a Scenario before simulating it.

The stage reader (:mod:`usdcrowd.scenario`) validates authored values with
precise prim/attribute locations; this only guards the simulation against
values that would make it meaningless (negative speeds, empty groups, NaN
starts), for Scenarios built directly in code.
"""

from __future__ import annotations

import numpy as np

from ..core.model import Scenario

try:  # the project's error type when present
    from ..core.errors import ScenarioError as _Error
except ImportError:  # pragma: no cover
    _Error = ValueError


def _fail(scenario: Scenario, message: str, prim: str | None = None, attribute: str | None = None):
    if _Error is ValueError:  # pragma: no cover
        raise ValueError(message)
    raise _Error(message, file=scenario.source or None, prim=prim, attribute=attribute)


def validate(scenario: Scenario) -> None:
    """Raise ScenarioError on values the simulation cannot use.

    Checks: at least one agent; array lengths; finite start positions;
    speeds >= 0; max_slope >= 0; fps > 0; every group has at least one agent
    in its subtree; leader / group rows in range.
    """
    a = scenario.agents
    g = scenario.groups
    n = len(a)
    if n == 0:
        _fail(scenario, "the scenario has no agents; add agents or clones to a CrowdGroup")
    if scenario.time.fps <= 0:
        _fail(scenario, f"timeCodesPerSecond must be > 0 (got {scenario.time.fps})")
    for name in ("agent_id", "group", "leader", "role", "character_type", "personality", "behavior",
                 "condition", "fear_response", "visit_profile", "speed", "height", "max_slope",
                 "map_influence", "start_heading"):
        if len(np.asarray(getattr(a, name))) != n:
            _fail(scenario, f"agent attribute {name} has {len(getattr(a, name))} rows for {n} agents")
    if np.asarray(a.start).shape != (n, 3):
        _fail(scenario, f"agent start positions must be ({n}, 3), got {np.asarray(a.start).shape}")
    if not np.all(np.isfinite(a.start)):
        bad = int(np.where(~np.isfinite(a.start).all(axis=1))[0][0])
        _fail(scenario, "start position is not finite", prim=a.path[bad], attribute="start")
    speed = np.asarray(a.speed, dtype=np.float64)
    if np.any(~np.isfinite(speed) | (speed < 0)):
        bad = int(np.where(~np.isfinite(speed) | (speed < 0))[0][0])
        _fail(scenario, f"speed must be a finite value >= 0 m/s (got {speed[bad]})", prim=a.path[bad],
              attribute="speed")
    slope = np.asarray(a.max_slope, dtype=np.float64)
    if np.any(~(slope >= 0)):
        bad = int(np.where(~(slope >= 0))[0][0])
        _fail(scenario, f"maxSlope must be >= 0 (got {slope[bad]})", prim=a.path[bad], attribute="maxSlope")
    grp = np.asarray(a.group, dtype=np.int64)
    if np.any((grp < 0) | (grp >= max(len(g), 1))) and len(g):
        _fail(scenario, "agent group row out of range")
    lead = np.asarray(a.leader, dtype=np.int64)
    if np.any((lead < -1) | (lead >= n)):
        bad = int(np.where((lead < -1) | (lead >= n))[0][0])
        _fail(scenario, f"leader row {lead[bad]} out of range", prim=a.path[bad], attribute="leader")
    if len(g):
        # Agents in each group's subtree: count direct members, then add each
        # group's count to its ancestors (bounded by the hierarchy's depth).
        count = np.bincount(grp, minlength=len(g)).astype(np.int64)
        total = count.copy()
        parent = np.asarray(g.parent, dtype=np.int64)
        up = parent.copy()
        carry = count.copy()
        for _ in range(len(g)):
            ok = up >= 0
            if not ok.any():
                break
            np.add.at(total, up[ok], carry[ok])
            up = np.where(ok, parent[np.maximum(up, 0)], -1)
        empty = np.where(total == 0)[0]
        if empty.size:
            _fail(scenario, "group has no agents (set a clone count or add agents)", prim=g.path[int(empty[0])])
