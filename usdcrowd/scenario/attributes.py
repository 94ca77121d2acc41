"""Attribute resolution down the group hierarchy (seed 004, section 2).

An agent takes its own authored value, else the value authored on its
nearest enclosing group, else a value drawn from the distribution documented
in the schema. The token "random" authored anywhere asks for a draw. Draws use
one generator per group, seeded from the run's seed and the group's path, so
adding agents to one group leaves every other group's agents unchanged.

This module knows nothing of USD: the reader hands it plain dicts of the
authored values.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, field

import numpy as np

from ..core import model
from ..character import appearance

# Distributions of the "random" tokens, per character type (schema docs).
_PERSONALITY = {
    "human": {"civilian": 0.85, "security": 0.15},
    "herbivore": {"herbivore": 1.0},
    "ant": {"herbivore": 1.0},
    "bird": {"herbivore": 1.0},
}
_BEHAVIOR = {
    "human": {"walk": 0.6, "wander": 0.25, "rest": 0.15},
    "herbivore": {"graze": 1.0},
    "ant": {"wander": 1.0},
    "bird": {"flock": 1.0},
}
_CONDITION = {"grouped": 0.7, "isolated": 0.3}
_FEAR = {"flee": 0.8, "freeze": 0.2}
_VISIT_PROFILE = {"detailed": 0.3, "casual": 0.5, "timeLimited": 0.2}

# Clothing palette for unauthored colours: muted linear-RGB tones, so crowds
# look like crowds rather than confetti.
_PALETTE = np.array([
    [0.05, 0.06, 0.10], [0.40, 0.05, 0.04], [0.06, 0.15, 0.35], [0.30, 0.30, 0.28],
    [0.55, 0.45, 0.25], [0.08, 0.22, 0.10], [0.60, 0.60, 0.62], [0.35, 0.18, 0.08],
    [0.50, 0.28, 0.40], [0.12, 0.30, 0.40], [0.70, 0.55, 0.10], [0.03, 0.03, 0.03],
])

# Attributes shared by CrowdGroup and CrowdAgentAPI and inherited downward.
INHERITED = (
    "characterType", "personality", "behavior", "condition", "fearResponse",
    "visitProfile", "visitBudget", "maxSlope", "behaviorMapInfluence", "trades",
    "speedRange", "heightRange", "color", "spawnCenter", "spawnRadius", "goal",
)

# Schema fallbacks of the non-random attributes.
FALLBACKS = {
    "characterType": "human",
    "visitBudget": 300.0,
    "maxSlope": 0.35,
    "behaviorMapInfluence": 1.0,
    "speedRange": (1.1, 1.5),
    "heightRange": (1.6, 1.9),
    "spawnCenter": (0.0, 0.0, 0.0),
    "spawnRadius": 5.0,
}


def appearance_rng(seed: int, group_path: str) -> np.random.Generator:
    """The group's generator for what its members wear (apart from the draws of :func:`group_rng`)."""
    return np.random.default_rng([seed & 0xFFFFFFFF, zlib.crc32(group_path.encode()), 0xA99E])


def _first_of_run(expand) -> np.ndarray:
    """(runs,) the first member of each draw run (``expand`` maps members to runs)."""
    runs, first = np.unique(np.asarray(expand, dtype=np.int64), return_index=True)
    assert np.array_equal(runs, np.arange(len(runs))), "draw runs are numbered 0, 1, ... in order"
    return first


def group_rng(seed: int, group_path: str) -> np.random.Generator:
    """The generator for one group's draws: stable under edits elsewhere."""
    return np.random.default_rng([seed & 0xFFFFFFFF, zlib.crc32(group_path.encode())])


@dataclass
class GroupSpec:
    """A group as authored: its path, parent row and authored values only."""

    path: str
    parent: int
    authored: dict = field(default_factory=dict)
    clones: int = 0
    subclones: int = 1


@dataclass
class AgentSpec:
    """An authored agent: path, group row and authored values only."""

    path: str
    group: int
    authored: dict = field(default_factory=dict)
    agent_id: int = -1
    role: str = "member"
    leader_path: str | None = None
    position: tuple | None = None      # canonical metres, from the prim's transform
    heading: float | None = None


def inherited_values(groups: list[GroupSpec]) -> list[dict]:
    """Per group, the values authored on it or its nearest ancestor that has them."""
    out: list[dict] = []
    for g in groups:
        values = dict(out[g.parent]) if g.parent >= 0 else {}
        values.update(g.authored)
        out.append(values)
    return out


def _draw(rng: np.random.Generator, dist: dict[str, float], n: int) -> list[str]:
    names = list(dist)
    p = np.array([dist[k] for k in names])
    return [names[i] for i in rng.choice(len(names), size=n, p=p / p.sum())]


def _categorical(values: list, dist_for, rng, n_draws, expand, vocab) -> np.ndarray:
    """Codes for one categorical attribute: authored tokens kept, the rest drawn."""
    need = [i for i, v in enumerate(values) if v in (None, "random")]
    resolved = list(values)
    if need:
        # Draw once per "clone run" (subclones share), then expand to agents.
        draws = {}
        for k in sorted({expand[i] for i in need}):
            idx = [i for i in need if expand[i] == k]
            draws[k] = _draw(rng, dist_for(idx[0]), 1)[0]
        for i in need:
            resolved[i] = draws[expand[i]]
    return np.array([vocab.index(v) for v in resolved], dtype=np.int8)


def resolve_group_members(seed: int, group: GroupSpec, group_values: dict,
                          members: list[AgentSpec], palette_name: str = "everyday") -> dict[str, np.ndarray]:
    """Resolve every attribute of one group's agents, authored and cloned.

    Parameters
    ----------
    seed : int
        The run's seed.
    group : GroupSpec
    group_values : dict
        Values inherited by the group (see :func:`inherited_values`).
    members : list[AgentSpec]
        The group's authored agents, followed by its clones (specs with an
        empty ``authored`` dict).
    palette_name : str
        What people wear: a name of ``character.appearance.PALETTES``.

    Returns
    -------
    dict of arrays, one row per member, keyed by AgentTable field names.
    """
    rng = group_rng(seed, group.path)
    n = len(members)
    expand = _draw_runs(members, group.subclones)
    out = _categorical_attributes(rng, members, group_values, expand)
    out["max_slope"] = _numeric(members, group_values, "maxSlope")
    out["map_influence"] = _numeric(members, group_values, "behaviorMapInfluence")
    out["trades"] = np.array([bool(v or False) for v in _values(members, group_values, "trades")], dtype=bool)

    # Continuous draws, one per clone run, in a fixed order for reproducibility.
    n_runs = max(expand) + 1 if n else 0
    u_speed, u_height, u_color = rng.random(n_runs), rng.random(n_runs), rng.integers(0, len(_PALETTE), n_runs)
    u_angle, u_radius, u_heading = rng.random(n), rng.random(n), rng.random(n)
    run = np.asarray(expand, dtype=np.int64)

    out["speed"], out["height"] = _speed_and_height(members, group_values, u_speed, u_height, run)
    out["palette"], out["color"] = _clothes(seed, group.path, members, group_values, u_color, run, palette_name)
    out["start"], out["start_heading"] = _starts(members, group_values, u_angle, u_radius, u_heading)
    return out


def _draw_runs(members: list[AgentSpec], subclones: int) -> list[int]:
    """The draw run of each member: members of one run share every drawn attribute."""
    # Authored agents each form their own draw; clones come in runs of
    # `subclones` that share every drawn attribute (seed 004 subclones).
    n = len(members)
    n_authored = sum(1 for m in members if not m.path.rsplit("/", 1)[-1].startswith("clone_"))
    return [i if i < n_authored else n_authored + (i - n_authored) // max(subclones, 1) for i in range(n)]


def _values(members: list[AgentSpec], group_values: dict, name: str) -> list:
    """Each member's value of ``name``: its own, else its group's, else None."""
    return [m.authored.get(name, group_values.get(name)) for m in members]


def _categorical_attributes(rng, members: list[AgentSpec], group_values: dict, expand) -> dict[str, np.ndarray]:
    """(n,) int8 codes of the character type and the token attributes, drawing the unauthored ones."""
    n = len(members)
    ctype_vals = [v or FALLBACKS["characterType"] for v in _values(members, group_values, "characterType")]
    out: dict[str, np.ndarray] = {
        "character_type": np.array([model.CHARACTER_TYPES.index(v) for v in ctype_vals], dtype=np.int8)
    }
    out["personality"] = _categorical(_values(members, group_values, "personality"),
                                      lambda i: _PERSONALITY[ctype_vals[i]], rng, n, expand,
                                      model.PERSONALITIES)
    out["behavior"] = _categorical(_values(members, group_values, "behavior"),
                                   lambda i: _BEHAVIOR[ctype_vals[i]], rng, n, expand, model.BEHAVIORS)
    out["condition"] = _categorical(_values(members, group_values, "condition"),
                                    lambda i: _CONDITION, rng, n, expand, model.CONDITIONS)
    out["fear_response"] = _categorical(_values(members, group_values, "fearResponse"),
                                        lambda i: _FEAR, rng, n, expand, model.FEAR_RESPONSES)
    # The visit profile belongs to the group: one draw for all its members.
    profile = group_values.get("visitProfile")
    if profile in (None, "random"):
        profile = _draw(rng, _VISIT_PROFILE, 1)[0]
    out["visit_profile"] = np.full(n, model.VISIT_PROFILES.index(profile), dtype=np.int8)
    return out


def _numeric(members: list[AgentSpec], group_values: dict, name: str) -> np.ndarray:
    """(n,) float64 value of ``name``: the member's, else its group's, else the schema fallback."""
    return np.array([m.authored.get(name, group_values.get(name, FALLBACKS.get(name))) for m in members],
                    dtype=np.float64)


def _speed_and_height(members: list[AgentSpec], group_values: dict, u_speed, u_height, run):
    """(n,) speeds and heights: drawn per run (``u_*`` (runs,) in [0, 1)) in each member's range, else authored."""
    n = len(members)
    speed_range = np.array([v or FALLBACKS["speedRange"] for v in _values(members, group_values, "speedRange")],
                           dtype=np.float64).reshape(n, 2)
    height_range = np.array([v or FALLBACKS["heightRange"] for v in _values(members, group_values, "heightRange")],
                            dtype=np.float64).reshape(n, 2)
    speed = speed_range[:, 0] + (speed_range[:, 1] - speed_range[:, 0]) * u_speed[run] if n else np.zeros(0)
    height = height_range[:, 0] + (height_range[:, 1] - height_range[:, 0]) * u_height[run] if n else np.zeros(0)
    for i, m in enumerate(members):
        if "speed" in m.authored:
            speed[i] = m.authored["speed"]
        if "height" in m.authored:
            height[i] = m.authored["height"]
    return speed, height


def _clothes(seed: int, group_path: str, members: list[AgentSpec], group_values: dict, u_color, run,
             palette_name: str):
    """(n, regions, 3) clothing palettes and (n, 3) top colours: drawn per run, authored colours tint the top."""
    n = len(members)
    color = _PALETTE[u_color[run]] if n else np.zeros((0, 3))
    drawn_top = color.reshape(-1, 3)[_first_of_run(run)]
    # Clothes, skin and hair come from their own generator, so adding them
    # changed none of the group's other draws; subclones dress alike.
    palette = appearance.draw_palettes(appearance_rng(seed, group_path), drawn_top, palette_name)
    palette = palette[run] if n else np.zeros((0, len(appearance.REGIONS), 3))
    for i, c in enumerate(_values(members, group_values, "color")):
        if c is not None:
            color[i] = c
            palette[i, 0] = appearance.tint(palette[i, 0], c)
    return palette, np.asarray(color, dtype=np.float64).reshape(n, 3)


def _starts(members: list[AgentSpec], group_values: dict, u_angle, u_radius, u_heading):
    """(n, 3) start positions and (n,) headings: authored, else the prim's transform, else drawn in the spawn disc."""
    n = len(members)
    center = np.asarray(group_values.get("spawnCenter", FALLBACKS["spawnCenter"]), dtype=np.float64)
    radius = float(group_values.get("spawnRadius", FALLBACKS["spawnRadius"]))
    r = radius * np.sqrt(u_radius)
    a = 2 * np.pi * u_angle
    start = np.stack([center[0] + r * np.cos(a), center[1] + r * np.sin(a), np.full(n, center[2])], axis=1)
    heading = 2 * np.pi * u_heading - np.pi
    for i, m in enumerate(members):
        if "startPosition" in m.authored:
            start[i] = m.authored["startPosition"]
        elif m.position is not None:
            start[i] = m.position
        if m.heading is not None:
            heading[i] = m.heading
    return start.reshape(n, 3), heading
