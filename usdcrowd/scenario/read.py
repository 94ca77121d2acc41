"""Read a scenario stage once into a :class:`usdcrowd.core.model.Scenario`.

Groups, agents (authored and cloned), behavior layers (images sampled),
interest points and scenery obstacles are read, checked and converted into
canonical units (Z up, metres). Every problem is a one-line
:class:`~usdcrowd.core.errors.ScenarioError` naming the file, prim and attribute:
:func:`load_scenario` raises the first, :func:`scenario_errors` (what
``usdcrowd validate`` reports) collects them all.
"""

from __future__ import annotations

import contextlib
import math
import os

import numpy as np

from ..core import model
from .. import schema
from ..core.errors import ScenarioError, StageError, UsdcrowdError
from ..core.limits import DEFAULT as DEFAULT_LIMITS
from ..core.limits import MAX_PRIM_DEPTH, Limits
from .attributes import FALLBACKS, INHERITED, AgentSpec, GroupSpec, inherited_values, resolve_group_members
from .events import read_camera_agents, read_events
from .ranges import MAX_AGENT_ID, MAX_SEED, extent_problem, range_problem
from .stageio import DEFAULT_TIME, StageFrame, open_stage, stage_frame, time_range

# Scenery lower than this is ground or markings, not an obstacle (metres).
OBSTACLE_MIN_HEIGHT = 0.05
# Scenery whose bottom is above this does not block walking (roofs, signs).
OBSTACLE_MAX_BOTTOM = 2.0
# Margin around everything when no ground tells the walkable bounds.
BOUNDS_MARGIN = 5.0
# Attributes whose values are positions or lengths in stage units.
_POINTS = ("spawnCenter", "goal", "startPosition")
_LENGTHS = ("spawnRadius",)


class _Reader:
    """Reads one stage. With ``problems`` (a list), :meth:`checking` records each prim's first problem there
    and goes on with the next prim; without, the first problem is raised."""

    def __init__(self, stage, source: str, limits: Limits = DEFAULT_LIMITS, problems: list | None = None):
        self.stage = stage
        self.source = source
        self.frame = StageFrame()
        from pxr import Usd, UsdGeom

        self.xcache = UsdGeom.XformCache(Usd.TimeCode.Default())
        self.limits = limits
        self.problems = problems

    def fail(self, msg, prim=None, attr=None):
        raise ScenarioError(msg, file=self.source, prim=str(prim.GetPath()) if prim else None, attribute=attr)

    @contextlib.contextmanager
    def checking(self):
        """The block reads one thing (a prim, a group's members): a problem in it is raised, or recorded
        (the rest of the block skipped) when problems are collected."""
        try:
            yield
        except UsdcrowdError as exc:
            if self.problems is None:
                raise
            self.problems.append(exc)

    def each(self, prims, read) -> list:
        """``read(prim)`` of every prim, without those whose problem was recorded."""
        out = []
        for prim in prims:
            with self.checking():
                out.append(read(prim))
        return out

    def check_extent(self, prim, attr: str, values, what: str = "position"):
        """Canonical positions or lengths (metres) must be finite and within the scene's extent."""
        problem = extent_problem(values, what)
        if problem:
            self.fail(problem, prim, attr)

    # ----------------------------------------------------------- attributes
    def authored(self, prim, names) -> dict:
        """Authored values of the crowd: attributes in ``names``, converted."""
        out = {}
        for name in names:
            attr = prim.GetAttribute(f"crowd:{name}")
            if not attr or not attr.HasAuthoredValue():
                continue
            self.check_type(prim, attr)
            value = attr.Get()
            if isinstance(value, bool):
                pass
            elif hasattr(value, "__len__") and not isinstance(value, str):
                value = tuple(float(v) for v in value)
            elif not isinstance(value, (int, float)):
                value = str(value)          # tokens
            self.check(prim, name, value)      # as authored: the words `usdcrowd validate` uses
            if name in _POINTS:
                value = tuple(self.frame.points_to_canonical(np.array(value)))
            elif name in _LENGTHS:
                value = float(self.frame.length_to_canonical(value))
            if name in _POINTS or name in _LENGTHS:
                self.check_extent(prim, f"crowd:{name}", value, "position" if name in _POINTS else "length")
            out[name] = value
        return out

    def check(self, prim, name, v):
        problem = range_problem(name, v)
        if problem:
            self.fail(problem, prim, f"crowd:{name}")

    def check_type(self, prim, attr):
        """An attribute authored with another type than the schema's (clones as a string) is refused."""
        spec = prim.GetPrimDefinition().GetSchemaAttributeSpec(attr.GetName())
        if spec is None:
            return
        # The composed attribute reports the schema's type; what was authored is in its specs.
        for authored in attr.GetPropertyStack():
            if authored.typeName != spec.typeName:
                self.fail(f"authored as {authored.typeName}, the schema's type is {spec.typeName}", prim,
                          attr.GetName())
        allowed = spec.GetInfo("allowedTokens") if spec.typeName == "token" else None
        value = attr.Get()
        if allowed and value is not None and str(value) not in [str(t) for t in allowed]:
            # The words `usdcrowd validate` uses for the same problem.
            self.fail(f"{str(value)!r} is not one of {', '.join(str(t) for t in allowed)}", prim, attr.GetName())

    def goal_waypoints(self, prim, start: float):
        """(times, points, goal at ``start``) of a time-sampled crowd:goal, canonical metres; else None."""
        attr = prim.GetAttribute("crowd:goal")
        times = attr.GetTimeSamples() if attr else []
        if not times:
            return None
        pts = self.frame.points_to_canonical(np.array([tuple(attr.Get(t)) for t in times], dtype=np.float64))
        self.check_extent(prim, "crowd:goal", pts)
        times = np.asarray(times, dtype=np.float64)
        current = pts[max(int(np.searchsorted(times, start, side="right")) - 1, 0)]
        return times, pts, tuple(current)

    def get(self, prim, name):
        """Value (authored or fallback) of crowd:name, type- and range-checked."""
        attr = prim.GetAttribute(f"crowd:{name}")
        if attr and attr.HasAuthoredValue():
            self.check_type(prim, attr)
        value = attr.Get()
        if isinstance(value, str):
            self.check(prim, name, value)
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            self.check(prim, name, value)
        elif hasattr(value, "__len__") and not isinstance(value, str) and len(value) in (2, 3):
            self.check(prim, name, tuple(value))
        return value

    # --------------------------------------------------------------- scenery
    def world_matrix(self, prim) -> np.ndarray:
        """(4, 4) local-to-world in canonical units (row vectors), finite and within the scene's extent."""
        m = np.array(self.xcache.GetLocalToWorldTransform(prim), dtype=np.float64) @ self.frame.to_canonical
        if not np.isfinite(m).all():
            from pxr import Usd

            from .events import _bad_op

            self.fail("not a finite value", prim, _bad_op(prim, Usd.TimeCode.Default()))
        self.check_extent(prim, _translate_op(prim), m[3, :3])
        return m

    def position_heading(self, prim):
        """Canonical translation and yaw of a prim whose transform is authored."""
        from pxr import UsdGeom

        xf = UsdGeom.Xformable(prim)
        if not xf or not xf.GetOrderedXformOps():
            return None, None
        m = self.world_matrix(prim)
        return tuple(m[3, :3]), math.atan2(m[0, 1], m[0, 0])


def _translate_op(prim) -> str:
    """The attribute to name for where a prim is: its first translate op, else its op order."""
    from pxr import UsdGeom

    xf = UsdGeom.Xformable(prim)
    ops = [op.GetName() for op in (xf.GetOrderedXformOps() if xf else []) if "translate" in op.GetName()]
    return ops[0] if ops else "xformOpOrder"


def usdcrowd_data(stage) -> dict:
    """The ``usdcrowd`` dictionary of a stage's root layer customLayerData ({} when absent)."""
    layer = stage.GetRootLayer()
    data = (layer.customLayerData or {}).get("usdcrowd", {})
    if not isinstance(data, dict):
        raise ScenarioError(f"must be a dictionary (seed, palette...), got {type(data).__name__} {data!r:.40}",
                            file=layer.identifier, attribute="customLayerData:usdcrowd")
    return data


def checked_seed(seed, file: str | None = None, attribute: str = "--seed") -> int:
    """``seed`` if it is an integer from 0 to :data:`MAX_SEED` (what numpy's generators take)."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed <= MAX_SEED:
        raise ScenarioError(f"a seed is an integer from 0 to {MAX_SEED:,}, got {seed!r:.40}", file=file,
                            attribute=attribute)
    return int(seed)


def stored_seed(stage) -> int | None:
    """The seed a stage records in its root layer's customLayerData, if any."""
    data = usdcrowd_data(stage)
    if "seed" not in data:
        return None
    return checked_seed(data["seed"], stage.GetRootLayer().identifier, "customLayerData:usdcrowd:seed")


def stored_palette(stage) -> str:
    """The palette (``character.appearance.PALETTES``) a stage asks for in customLayerData, else "everyday"."""
    from ..character.appearance import PALETTES

    name = usdcrowd_data(stage).get("palette", "everyday")
    if not isinstance(name, str) or name not in PALETTES:
        raise ScenarioError(f"unknown palette {name!r} (palettes: {', '.join(PALETTES)})",
                            file=stage.GetRootLayer().identifier, attribute="customLayerData:usdcrowd:palette")
    return name


def load_scenario(path: str | os.PathLike, seed: int | None = None, stage=None,
                  limits: Limits = DEFAULT_LIMITS) -> model.Scenario:
    """Read a scenario stage into arrays.

    Parameters
    ----------
    path : path-like
        The scenario (or shot) stage.
    seed : int, optional
        Seed of the run; default: the one recorded in the stage, else 0.
    stage : Usd.Stage, optional
        An already opened stage for ``path``.
    limits : Limits
        Largest agent count, frame count and behavior-map image accepted.

    Raises
    ------
    StageError, ScenarioError
        The first problem, in one line naming file, prim and attribute.
    """
    source = os.fspath(path)
    return _read(_Reader(stage or open_stage(source), source, limits), seed)


def shot_scenario(scene) -> model.Scenario | None:
    """The scenario a shot (a :class:`usdcrowd.scenario.shot_scene.ShotScene`: its stage and path) refers to,
    None if it names none."""
    ref = dict(scene.stage.GetRootLayer().customLayerData.get("usdcrowd", {})).get("scenario")
    if not ref:
        return None
    return load_scenario(os.path.join(os.path.dirname(os.path.abspath(scene.path)), ref))


def scenario_errors(path: str | os.PathLike, stage=None, limits: Limits = DEFAULT_LIMITS) -> list[UsdcrowdError]:
    """Every problem :func:`load_scenario` would raise the first of (the first of each prim), in stage order."""
    source = os.fspath(path)
    r = _Reader(stage or open_stage(source), source, limits, problems=[])
    with r.checking():
        _read(r, None)
    out, seen = [], set()
    for exc in r.problems:
        key = exc.prim or (exc.attribute, exc.message)
        if key not in seen:
            seen.add(key)
            out.append(exc)
    return out


def _read(r: _Reader, seed: int | None) -> model.Scenario | None:
    """The scenario (None when problems were collected instead of raised)."""
    stage, source = r.stage, r.source
    time, seed = _read_time_and_seed(r, seed)
    groups, agents, waypoints, layers, points, scenery = _traverse(r, time)
    if not groups and not agents:
        raise ScenarioError("no CrowdGroup and no agent: nothing to simulate", file=source)

    table, group_table = _resolve(r, seed, groups, agents)
    if any(w is not None for w in waypoints):
        for gi, g in enumerate(groups):          # subgroups follow their parent's waypoints
            if waypoints[gi] is None and g.parent >= 0 and "goal" not in g.authored:
                waypoints[gi] = waypoints[g.parent]
        group_table.waypoints = waypoints
    obstacles, ground, overhead = _obstacles(r, scenery)
    fields = r.each(layers, lambda p: _behavior_field(r, p))
    interest = _interest(r, points)
    cameras = events = None
    with r.checking():
        events = read_events(stage, {p: i for i, p in enumerate(table.path)}, time, agent_ids=table.agent_id)
        events = model.EventTable([e for e in events if e.authored])
    with r.checking():
        cameras = read_camera_agents(stage)
    if r.problems:
        return None
    bounds = _bounds(ground, obstacles, table, interest, fields)
    return model.Scenario(source, time, int(seed), group_table, table, fields, interest, obstacles, bounds,
                          cameras=cameras, events=events, overhead=overhead)


def _read_time_and_seed(r: _Reader, seed: int | None):
    """The stage's units into ``r.frame``, its time range (checked against the limits) and the run's seed."""
    stage, source, limits = r.stage, r.source, r.limits
    with r.checking():
        r.frame = stage_frame(stage)
    time = DEFAULT_TIME
    with r.checking():
        time = time_range(stage)
        if time.n_frames > limits.max_frames:
            raise ScenarioError(f"{time.n_frames:,} frames: more than the {limits.max_frames:,} accepted "
                                f"(raise it with --max-frames)", file=source, attribute="endTimeCode")
    run_seed = 0
    with r.checking():
        run_seed = (stored_seed(stage) or 0) if seed is None else checked_seed(seed)
    return time, run_seed


def _traverse(r: _Reader, time: model.TimeRange):
    """Groups and agents read, and behavior layers, interest points and scenery prims found, in stage order.

    Returns ``(groups, agents, waypoints, layers, points, scenery)``; ``waypoints`` holds, per group, the
    ``(times, points)`` of a time-sampled goal, or None.
    """
    from pxr import Usd

    source = r.source
    groups: list[GroupSpec] = []
    group_row: dict[str, int] = {}
    agents: list[AgentSpec] = []
    layers, points, scenery = [], [], []
    waypoints: list = []

    # Instance proxies too: scenery from DCC tools is often instanced.
    it = iter(Usd.PrimRange(r.stage.GetPseudoRoot(), Usd.TraverseInstanceProxies()))
    for prim in it:
        if not prim.IsActive():
            it.PruneChildren()
            continue
        if prim.GetPath().pathElementCount > MAX_PRIM_DEPTH:
            shown = str(prim.GetPath())
            raise ScenarioError(f"prims nested more than {MAX_PRIM_DEPTH} deep ({shown[:60]}...): flatten the "
                                "hierarchy", file=source)
        tname = prim.GetTypeName()
        if tname == schema.GROUP:
            # Known (as an empty group) even when its values cannot be read, so its agents still find it.
            group_row[str(prim.GetPath())] = len(groups)
            groups.append(GroupSpec(str(prim.GetPath()), _nearest_group(prim, group_row)))
            waypoints.append(None)
            with r.checking():
                _read_group(r, prim, groups, waypoints, time.start)
        elif schema.is_agent(prim):
            it.PruneChildren()        # an agent's skeleton and body are not scenery
            if prim.IsInstanceProxy():
                with r.checking():
                    raise _instanced_agent(prim)
                continue
            with r.checking():
                group = _agent_group(r, prim, group_row)
                agents.append(AgentSpec(str(prim.GetPath()), group))     # until its values are read
                agents[-1] = _agent_spec(r, prim, group)
        elif tname == schema.BEHAVIOR_LAYER:
            layers.append(prim)
        elif tname == schema.INTEREST_POINT:
            points.append(prim)
        elif tname == "Camera" or prim.IsA(_lux_base()):
            continue
        elif _is_gprim(prim):
            scenery.append(prim)
    return groups, agents, waypoints, layers, points, scenery


def _instanced_agent(prim) -> StageError:
    """An agent inside an instanceable prim: USD instances are read-only, so its animation could not be written."""
    instance = prim.GetParent()
    while instance and not instance.IsInstance():
        instance = instance.GetParent()
    return StageError(f"is inside the instanceable prim {instance.GetPath()}: an instance's prims cannot be "
                      "animated; set instanceable = false on it", file=prim.GetStage().GetRootLayer().identifier,
                      prim=str(prim.GetPath()))


def _read_group(r: _Reader, prim, groups: list[GroupSpec], waypoints: list, start: float) -> None:
    """A group's clone counts, authored values and goal waypoints, into its (last) row."""
    g = groups[-1]
    clones = int(r.get(prim, "clones"))
    subclones = int(r.get(prim, "subclones"))
    total_clones = sum(h.clones for h in groups) + clones
    if total_clones > r.limits.max_agents:        # before anything is allocated for them
        r.fail(f"{total_clones:,} clones: more than the {r.limits.max_agents:,} agents accepted "
               f"(raise it with --max-agents)", prim, "crowd:clones")
    authored = r.authored(prim, INHERITED)
    schedule = r.goal_waypoints(prim, start)
    if schedule is not None:
        authored["goal"] = schedule[2]
    g.authored, g.clones, g.subclones = authored, clones, subclones
    waypoints[-1] = schedule[:2] if schedule is not None else None


def clone_path(group_path: str, k: int) -> str:
    """Prim path of a group's k-th clone."""
    return f"{group_path}/clone_{k:04d}"


def _lux_base():
    from pxr import UsdLux

    return UsdLux.BoundableLightBase


def _is_gprim(prim) -> bool:
    from pxr import UsdGeom

    return prim.IsA(UsdGeom.Gprim) and UsdGeom.Imageable(prim).ComputePurpose() != UsdGeom.Tokens.guide


def _nearest_group(prim, group_row) -> int:
    p = prim.GetParent()
    while p and not p.IsPseudoRoot():
        row = group_row.get(str(p.GetPath()))
        if row is not None:
            return row
        p = p.GetParent()
    return -1


def _agent_group(r: _Reader, prim, group_row) -> int:
    """The row of an agent's group: its crowd:group target, else its nearest enclosing group."""
    rel = prim.GetRelationship("crowd:group")
    targets = rel.GetTargets() if rel else []
    if targets:
        g = group_row.get(str(targets[0]))
        if g is None:
            tgt = r.stage.GetPrimAtPath(targets[0])
            if not tgt or tgt.GetTypeName() != schema.GROUP:
                r.fail(f"target {targets[0]} is not a CrowdGroup", prim, "crowd:group")
            g = group_row.get(str(targets[0]))
            if g is None:
                r.fail(f"target {targets[0]} must come before the agent in the stage", prim, "crowd:group")
    else:
        g = _nearest_group(prim, group_row)
        if g < 0:
            r.fail("agent is in no CrowdGroup: put it under one or author crowd:group", prim, "crowd:group")
    return g


def _agent_spec(r: _Reader, prim, g: int) -> AgentSpec:
    path = str(prim.GetPath())
    names = [n for n in INHERITED if n not in ("visitProfile", "visitBudget", "speedRange", "heightRange",
                                               "spawnCenter", "spawnRadius", "goal")]
    authored = r.authored(prim, names + ["speed", "height", "startPosition"])
    leader_rel = prim.GetRelationship("crowd:leader")
    leader_targets = leader_rel.GetTargets() if leader_rel else []
    pos, heading = r.position_heading(prim)
    return AgentSpec(path, g, authored, int(r.get(prim, "agentId")), str(r.get(prim, "role")),
                     str(leader_targets[0]) if leader_targets else None, pos, heading)


def _resolve(r: _Reader, seed, groups, agents):
    """The agent and group tables: every group's members (authored and cloned) resolved, ids and leaders set."""
    values = inherited_values(groups)
    rows, cat = _group_members(r, seed, groups, agents, values)
    path_row = {a.path: i for i, a in enumerate(rows)}
    ids = _track_ids(r, rows, groups, path_row)
    role, group, g_leader, leader = _leaders(r, rows, groups, path_row)

    table = model.AgentTable(
        path=[a.path for a in rows], agent_id=ids.astype(np.int32), group=group, leader=leader, role=role,
        **{k: cat.get(k, np.zeros(0)) for k in (
            "character_type", "personality", "behavior", "condition", "fear_response", "visit_profile",
            "speed", "height", "max_slope", "map_influence", "color", "start", "start_heading")},
        trades=cat.get("trades", np.zeros(0, bool)), palette=cat.get("palette"))
    goals = np.array([values[i].get("goal", (np.nan,) * 3) for i in range(len(groups))], dtype=np.float64).reshape(-1, 3)
    budgets = np.array([values[i].get("visitBudget", 300.0) for i in range(len(groups))], dtype=np.float64)
    group_table = model.GroupTable([g.path for g in groups], np.array([g.parent for g in groups], dtype=np.int32),
                                   goals, budgets, g_leader)
    return table, group_table


def _group_members(r: _Reader, seed, groups, agents, values):
    """Agent rows group by group (authored agents, then clones not on the stage) and their columns."""
    palette = "everyday"
    with r.checking():
        palette = stored_palette(r.stage)
    by_group: dict[int, list[AgentSpec]] = {i: [] for i in range(len(groups))}
    for a in agents:
        by_group[a.group].append(a)
    rows: list[AgentSpec] = []
    cols: dict[str, list[np.ndarray]] = {}
    for gi, g in enumerate(groups):
        # A shot stage already holds the clones a run made: they are read as
        # authored agents, not made again; one its user deactivated is gone, not made again either.
        have = {a.path for a in by_group[gi]}
        clones = [AgentSpec(p, gi) for p in (clone_path(g.path, k) for k in range(g.clones))
                  if p not in have and not r.stage.GetPrimAtPath(p)]
        members = by_group[gi] + clones
        has_subgroups = any(h.parent == gi for h in groups)
        if not members and not has_subgroups:
            with r.checking():
                r.fail("empty group: no agents, no subgroups and crowd:clones = 0", r.stage.GetPrimAtPath(g.path),
                       "crowd:clones")
        if not members:
            continue
        with r.checking():
            # Authored starts are checked where they are read; what is left is the disc clones spawn in.
            centre = np.asarray(values[gi].get("spawnCenter", FALLBACKS["spawnCenter"]), dtype=np.float64)
            radius = float(values[gi].get("spawnRadius", FALLBACKS["spawnRadius"]))
            r.check_extent(r.stage.GetPrimAtPath(g.path), "crowd:spawnRadius",
                           [centre[:2] - radius, centre[:2] + radius], "the spawn disc")
        for k, arr in resolve_group_members(seed, g, values[gi], members, palette).items():
            cols.setdefault(k, []).append(arr)
        rows.extend(members)
    return rows, {k: np.concatenate(v) for k, v in cols.items()}


def _track_ids(r: _Reader, rows: list[AgentSpec], groups, path_row: dict[str, int]) -> np.ndarray:
    """(n,) int64 track ids: authored ones kept (unique, >= 1), the rest numbered after them."""
    ids = np.array([a.agent_id for a in rows], dtype=np.int64)
    authored_ids = ids[ids != -1]
    with r.checking():
        if np.any(authored_ids < 1):
            bad = rows[int(np.flatnonzero((ids != -1) & (ids < 1))[0])]
            r.fail(f"agent ids must be >= 1, got {ids[path_row[bad.path]]}", r.stage.GetPrimAtPath(bad.path),
                   "crowd:agentId")
    uniq, counts = np.unique(authored_ids, return_counts=True)
    with r.checking():
        if np.any(counts > 1):
            dup = int(uniq[counts > 1][0])
            bad = rows[int(np.flatnonzero(ids == dup)[1])]
            r.fail(f"agent id {dup} is used twice", r.stage.GetPrimAtPath(bad.path), "crowd:agentId")
    free = ids == -1
    ids[free] = (authored_ids.max() if authored_ids.size else 0) + 1 + np.arange(int(free.sum()))
    if ids.size and ids.max() > MAX_AGENT_ID:
        # Named where the numbering starts: the largest authored id, else (none authored) the first group.
        top = rows[int(np.argmax(np.where(free, -1, ids)))]
        prim = r.stage.GetPrimAtPath(top.path)
        with r.checking():
            r.fail(f"the {int(free.sum()):,} agents numbered after {int(ids[~free].max(initial=0)):,} (clones "
                   f"included) would reach {int(ids.max()):,}, past the largest agent id {MAX_AGENT_ID:,}",
                   prim or r.stage.GetPrimAtPath(groups[top.group].path), "crowd:agentId" if prim else "crowd:clones")
        ids[free] = 0           # (only collecting problems from here on)
    return ids


def _leaders(r: _Reader, rows: list[AgentSpec], groups, path_row: dict[str, int]):
    """Roles, groups, each group's leader row and each agent's leader row (-1: none), leader cycles refused."""
    n = len(rows)
    role = np.array([model.ROLES.index(a.role) for a in rows], dtype=np.int8)
    group = np.array([a.group for a in rows], dtype=np.int32)
    g_leader = np.full(len(groups), -1, dtype=np.int32)
    for i in np.flatnonzero(role != model.ROLES.index("member"))[::-1]:
        g_leader[group[i]] = i
    leader = np.full(n, -1, dtype=np.int32)
    for i, a in enumerate(rows):
        if a.leader_path is not None:
            with r.checking():
                if a.leader_path not in path_row:
                    r.fail(f"target {a.leader_path} is not a CrowdAgentAPI agent", r.stage.GetPrimAtPath(a.path),
                           "crowd:leader")
                leader[i] = path_row[a.leader_path]
        elif g_leader[a.group] != i:
            leader[i] = g_leader[a.group]
    with r.checking():
        _check_leader_cycles(r, rows, leader)
    return role, group, g_leader, leader


def _check_leader_cycles(r: _Reader, rows: list[AgentSpec], leader: np.ndarray) -> None:
    """Leaders must lead somewhere: no agent follows itself, and no leaders follow each other in a circle."""
    state = np.zeros(len(leader), dtype=np.int8)        # 0 not seen, 1 on the chain being followed, 2 done
    for first in range(len(leader)):
        chain, i = [], first
        while i >= 0 and state[i] == 0:
            state[i] = 1
            chain.append(i)
            i = int(leader[i])
        if i >= 0 and state[i] == 1:
            circle = chain[chain.index(i):]
            # A circle needs an authored crowd:leader (a group's leader follows no one unless told to).
            who = next(j for j in circle if rows[j].leader_path is not None)
            prim = r.stage.GetPrimAtPath(rows[who].path)
            if len(circle) == 1:
                r.fail("the agent follows itself", prim, "crowd:leader")
            k = circle.index(who)
            names = [rows[j].path for j in circle[k:] + circle[:k + 1]]
            r.fail(f"leaders follow each other in a circle ({' -> '.join(names)}): one of them must lead",
                   prim, "crowd:leader")
        state[chain] = 2


def _scenery_role(prim) -> str:
    """crowd:scenery of the nearest prim (itself or an ancestor) with CrowdSceneryAPI, else "auto"."""
    p = prim
    while p and not p.IsPseudoRoot():
        if p.HasAPI(schema.SCENERY_API):
            return str(p.GetAttribute("crowd:scenery").Get())
        p = p.GetParent()
    return "auto"


def _obstacles(r: _Reader, prims):
    """Footprints of the scenery that blocks walking, flat scenery (ground), raised scenery (overhead).

    A footprint is the convex hull of the prim's tessellated vertices seen
    from above (a round fountain stays round); what a prim is follows its
    CrowdSceneryAPI role, or the height rule when it has none.
    """
    from scipy.spatial import ConvexHull

    from ..core.geometry import mesh_of

    paths, polys, heights, ground = [], [], [], []
    raised = ([], [], [], [])               # paths, footprints, tops, undersides

    def read(prim):
        role = _scenery_role(prim)
        if role == "ignore":
            return
        mesh = mesh_of(prim)
        if mesh is None or len(mesh.vertices) == 0:
            return
        m = r.world_matrix(prim)
        pts = mesh.vertices.astype(np.float64) @ m[:3, :3] + m[3, :3]
        r.check_extent(prim, _size_attribute(prim), pts, "the geometry")
        bottom, top = pts[:, 2].min(), pts[:, 2].max()
        if role == "ground" or (role == "auto" and top - bottom < OBSTACLE_MIN_HEIGHT):
            ground.append(pts[:, :2])
            return
        xy = pts[:, :2]
        try:
            poly = xy[ConvexHull(xy).vertices]
        except Exception:      # degenerate footprint (a vertical plane): keep its segment
            poly = xy[[np.argmin(xy[:, 0]), np.argmax(xy[:, 0])]]
        if role == "auto" and bottom > OBSTACLE_MAX_BOTTOM:
            # People walk under it; cameras above it cannot see them through it.
            for out, value in zip(raised, (str(prim.GetPath()), np.ascontiguousarray(poly), top, bottom)):
                out.append(value)
            return
        paths.append(str(prim.GetPath()))
        polys.append(np.ascontiguousarray(poly))
        heights.append(top)

    r.each(prims, read)
    overhead = model.Obstacles(raised[0], raised[1], np.array(raised[2], dtype=np.float64),
                               np.array(raised[3], dtype=np.float64))
    return _canonical_obstacles(paths, polys, heights), ground, overhead


# Footprint coordinates are compared at this many decimals (metres): a micrometre, far below
# anything the simulation resolves, far above the float noise of composing the same transform twice.
_ORDER_DECIMALS = 6


def _canonical_obstacles(paths: list[str], polys: list[np.ndarray], heights: list[float]) -> model.Obstacles:
    """Obstacles in an order of their geometry alone, not of the prims that hold them.

    The simulation depends on the order (where footprints overlap, the later one owns the
    overlap in the walk grid, and agents there are pushed out of that one): the same town
    exported with its prims in another order or under other names must give the same crowd.
    Each footprint starts at its lowest (x, then y) vertex, and the footprints are sorted by
    their coordinates, then by height.

    Parameters
    ----------
    paths : list of str
        Prim path of each obstacle.
    polys : list of (k, 2) float64
        Footprints, in the order the prims were found.
    heights : list of float
        Top of each obstacle, metres.

    Returns
    -------
    Obstacles
    """
    polys = [_from_lowest_vertex(p) for p in polys]

    def key(i: int):
        return tuple(np.round(polys[i], _ORDER_DECIMALS).ravel()), round(float(heights[i]), _ORDER_DECIMALS)

    order = sorted(range(len(polys)), key=key)
    return model.Obstacles([paths[i] for i in order], [polys[i] for i in order],
                           np.array([heights[i] for i in order], dtype=np.float64))


def _from_lowest_vertex(poly: np.ndarray) -> np.ndarray:
    """(k, 2) ``poly`` rolled to start at its lowest vertex by (x, then y), winding kept.

    Qhull's first hull vertex follows the order of the points it is given.
    """
    rounded = np.round(poly, _ORDER_DECIMALS)
    first = int(np.lexsort((rounded[:, 1], rounded[:, 0]))[0])
    return np.ascontiguousarray(np.roll(poly, -first, axis=0))


def _size_attribute(prim) -> str:
    """The attribute that sizes a gprim (its points, size, radius...; its scale when it has one)."""
    from pxr import UsdGeom

    xf = UsdGeom.Xformable(prim)
    scales = [op.GetName() for op in (xf.GetOrderedXformOps() if xf else []) if "scale" in op.GetName()]
    own = [n for n in ("points", "size", "radius", "height", "width", "length") if prim.HasAttribute(n)]
    return scales[0] if scales else own[0] if own else "extent"


def _behavior_field(r: _Reader, prim) -> model.BehaviorField:
    meaning = str(r.get(prim, "meaning"))
    generator = str(r.get(prim, "generator"))
    lo = np.array(r.get(prim, "extentMin"), dtype=np.float64) * r.frame.meters_per_unit
    hi = np.array(r.get(prim, "extentMax"), dtype=np.float64) * r.frame.meters_per_unit
    r.check_extent(prim, "crowd:extentMin", lo)
    r.check_extent(prim, "crowd:extentMax", hi)
    if np.any(hi <= lo):
        r.fail(f"extent max {tuple(hi)} must exceed extent min {tuple(lo)}", prim, "crowd:extentMax")
    vrange = np.array(r.get(prim, "valueRange"), dtype=np.float64)
    influence = float(r.get(prim, "influence"))
    values = None
    if generator == "painted":
        values = _read_image(r, prim, vrange, hi - lo)
    origin = r.frame.points_to_canonical(np.array(r.get(prim, "origin"), dtype=np.float64))
    radius = float(r.frame.length_to_canonical(r.get(prim, "radius")))
    r.check_extent(prim, "crowd:origin", origin)
    r.check_extent(prim, "crowd:radius", radius, "length")
    if meaning == "height" and values is not None:
        values = values * r.frame.meters_per_unit
        r.check_extent(prim, "crowd:valueRange", values, "terrain height")
    return model.BehaviorField(str(prim.GetPath()), model.LAYER_MEANINGS.index(meaning),
                               model.LAYER_GENERATORS.index(generator), values, lo, hi, influence,
                               origin, radius, float(r.get(prim, "startTime")))


# The finest behavior-map detail the simulation can use (its grids are coarser):
# larger images are read down to this many metres per pixel.
MAP_RESOLUTION = 0.05


def _read_image(r: _Reader, prim, vrange, extent: np.ndarray) -> np.ndarray:
    """(h, w) float32 values of a painted layer, at most one pixel per MAP_RESOLUTION metres.

    Finer images are resampled to that by nearest pixel (values stay the
    painted ones: a forbidden mask stays 0 and 1) before they become floats,
    so a huge image costs its decoding, not four bytes a pixel.
    """
    from PIL import Image

    attr = prim.GetAttribute("crowd:image")
    asset = attr.Get() if attr.HasAuthoredValue() else None
    if asset is None or not asset.path:
        r.fail("a painted behavior layer needs an image", prim, "crowd:image")
    from .stageio import unpacked

    resolved = unpacked(asset.resolvedPath)         # an image inside a usdz: a copy on disk
    if not resolved or not os.path.isfile(resolved):
        r.fail(f"image @{asset.path}@ not found", prim, "crowd:image")
    try:
        with Image.open(resolved) as im:      # lazy: the size is known before any pixel is decoded
            w, h = im.size
            if w * h > r.limits.max_image_pixels:
                r.fail(f"image @{asset.path}@ is {w} x {h}: more than the {r.limits.max_image_pixels:,} pixels "
                       f"accepted (raise it with --max-image-pixels)", prim, "crowd:image")
            mode = im.mode
            need = (max(1, int(np.ceil(extent[0] / MAP_RESOLUTION))), max(1, int(np.ceil(extent[1] / MAP_RESOLUTION))))
            if w > need[0] or h > need[1]:
                im = im.resize((min(w, need[0]), min(h, need[1])), Image.NEAREST)
            arr = np.asarray(im)
    except ScenarioError:
        raise
    except Exception as exc:
        r.fail(f"image @{asset.path}@ cannot be read ({exc.__class__.__name__})", prim, "crowd:image")
    if arr.ndim == 3:
        arr = arr[..., 0]
    bad = ~np.isfinite(arr) if arr.dtype.kind == "f" else None
    if bad is not None and bad.any():
        y, x = np.argwhere(bad)[0]
        r.fail(f"image @{asset.path}@ has a texel that is not a finite number: {arr[y, x]} at x {x}, y {y} "
               f"(of {arr.shape[1]} x {arr.shape[0]} read)", prim, "crowd:image")
    # Normalise by what the file stores, not by numpy's dtype: Pillow opens
    # 16-bit PNGs as "I;16" or, in some versions, as 32-bit "I".
    full = 65535.0 if mode.startswith("I") else 1.0 if mode == "F" else 255.0
    arr = arr.astype(np.float32) / full
    with np.errstate(over="ignore", invalid="ignore"):
        values = (vrange[0] + (vrange[1] - vrange[0]) * arr).astype(np.float32)
    if not np.isfinite(values).all():
        r.fail(f"the values of image @{asset.path}@ times this range are not finite numbers (texels up to "
               f"{float(np.abs(arr).max()):g})", prim, "crowd:valueRange")
    return values


_INTEREST_VALUES = ("interest", "radius", "visibility", "priorKnowledge", "decayRate", "viewDuration")


def _interest_point(r: _Reader, prim) -> tuple:
    """(path, position, values of _INTEREST_VALUES) of an interest point, canonical metres."""
    values = [float(r.get(prim, n)) for n in _INTEREST_VALUES]
    m = r.world_matrix(prim)
    # In the point's own space, as its position: a shot placed under a set's unit conversion keeps its size.
    values[1] *= float(np.linalg.norm(m[0, :3]))
    r.check_extent(prim, "crowd:radius", values[1], "length")
    return str(prim.GetPath()), m[3, :3], values


def _interest(r: _Reader, prims) -> model.InterestTable:
    read = r.each(prims, lambda p: _interest_point(r, p))
    if not read:
        return model.InterestTable.empty()
    vals = np.array([v for _, _, v in read], dtype=np.float64).T
    return model.InterestTable([p for p, _, _ in read], np.array([x for _, x, _ in read]), *vals)


def _bounds(ground, obstacles: model.Obstacles, agents: model.AgentTable, interest, fields) -> np.ndarray:
    """Walkable bounds: the ground's extent if there is ground, else everything padded."""
    if ground:
        pts = np.concatenate(ground)
        return np.array([pts.min(0), pts.max(0)])
    pts = [agents.start[:, :2], interest.position[:, :2]] + list(obstacles.polygons)
    pts += [np.array([f.extent_min, f.extent_max]) for f in fields]
    allp = np.concatenate([p for p in pts if len(p)])
    return np.array([allp.min(0) - BOUNDS_MARGIN, allp.max(0) + BOUNDS_MARGIN])
