"""Read a scenario stage once into a :class:`usdcrowd.model.Scenario`.

Groups, agents (authored and cloned), behavior layers (images sampled),
interest points and scenery obstacles are read, checked and converted into
canonical units (Z up, metres). Every problem is a one-line
:class:`~usdcrowd.errors.ScenarioError` naming the file, prim and attribute.
"""

from __future__ import annotations

import math
import os

import numpy as np

from .. import model, schema
from ..errors import ScenarioError
from ..limits import DEFAULT as DEFAULT_LIMITS
from ..limits import Limits
from .attributes import INHERITED, AgentSpec, GroupSpec, inherited_values, resolve_group_members
from .events import read_camera_agents, read_events
from .ranges import range_problem
from .stageio import StageFrame, open_stage, stage_frame, time_range

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
    def __init__(self, stage, source: str):
        self.stage = stage
        self.source = source
        self.frame: StageFrame = stage_frame(stage)
        from pxr import Usd, UsdGeom

        self.xcache = UsdGeom.XformCache(Usd.TimeCode.Default())
        self.limits = DEFAULT_LIMITS

    def fail(self, msg, prim=None, attr=None):
        raise ScenarioError(msg, file=self.source, prim=str(prim.GetPath()) if prim else None, attribute=attr)

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
            if name in _POINTS:
                value = tuple(self.frame.points_to_canonical(np.array(value)))
            elif name in _LENGTHS:
                value = float(self.frame.length_to_canonical(value))
            self.check(prim, name, value)
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
        """(4, 4) local-to-world in canonical units (row vectors)."""
        m = np.array(self.xcache.GetLocalToWorldTransform(prim), dtype=np.float64)
        return m @ self.frame.to_canonical

    def position_heading(self, prim):
        """Canonical translation and yaw of a prim whose transform is authored."""
        from pxr import UsdGeom

        xf = UsdGeom.Xformable(prim)
        if not xf or not xf.GetOrderedXformOps():
            return None, None
        m = self.world_matrix(prim)
        return tuple(m[3, :3]), math.atan2(m[0, 1], m[0, 0])


def stored_seed(stage) -> int | None:
    """The seed a stage records in its root layer's customLayerData, if any."""
    data = stage.GetRootLayer().customLayerData.get("usdcrowd", {})
    return int(data["seed"]) if "seed" in data else None


def stored_palette(stage) -> str:
    """The palette (``character.appearance.PALETTES``) a stage asks for in customLayerData, else "everyday"."""
    from ..character.appearance import PALETTES

    name = stage.GetRootLayer().customLayerData.get("usdcrowd", {}).get("palette", "everyday")
    if name not in PALETTES:
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
        With one-line messages naming file, prim and attribute.
    """
    from pxr import Usd

    source = os.fspath(path)
    stage = stage or open_stage(source)
    r = _Reader(stage, source)
    r.limits = limits
    time = time_range(stage)
    n_frames = time.n_frames
    if n_frames > limits.max_frames:
        raise ScenarioError(f"{n_frames:,} frames: more than the {limits.max_frames:,} accepted "
                            f"(raise it with --max-frames)", file=source, attribute="endTimeCode")
    if seed is None:
        seed = stored_seed(stage) or 0

    groups: list[GroupSpec] = []
    group_row: dict[str, int] = {}
    agents: list[AgentSpec] = []
    layers, points, scenery = [], [], []
    waypoints: list = []            # per group: (times, points) of a time-sampled goal, or None

    # Instance proxies too: scenery from DCC tools is often instanced.
    it = iter(Usd.PrimRange(stage.GetPseudoRoot(), Usd.TraverseInstanceProxies()))
    for prim in it:
        if not prim.IsActive():
            it.PruneChildren()
            continue
        tname = prim.GetTypeName()
        path = str(prim.GetPath())
        if tname == schema.GROUP:
            parent = _nearest_group(prim, group_row)
            clones = int(r.get(prim, "clones"))
            subclones = int(r.get(prim, "subclones"))
            total_clones = sum(g.clones for g in groups) + clones
            if total_clones > limits.max_agents:        # before anything is allocated for them
                r.fail(f"{total_clones:,} clones: more than the {limits.max_agents:,} agents accepted "
                       f"(raise it with --max-agents)", prim, "crowd:clones")
            group_row[path] = len(groups)
            authored = r.authored(prim, INHERITED)
            schedule = r.goal_waypoints(prim, time.start)
            if schedule is not None:
                authored["goal"] = schedule[2]
            groups.append(GroupSpec(path, parent, authored, clones, subclones))
            waypoints.append(schedule[:2] if schedule is not None else None)
        elif schema.is_agent(prim):
            agents.append(_agent_spec(r, prim, group_row))
            it.PruneChildren()        # an agent's skeleton and body are not scenery
        elif tname == schema.BEHAVIOR_LAYER:
            layers.append(prim)
        elif tname == schema.INTEREST_POINT:
            points.append(prim)
        elif tname == "Camera" or prim.IsA(_lux_base()):
            continue
        elif _is_gprim(prim):
            scenery.append(prim)

    if not groups and not agents:
        raise ScenarioError("no CrowdGroup and no agent: nothing to simulate", file=source)

    table, group_table = _resolve(r, seed, groups, agents)
    if any(w is not None for w in waypoints):
        for gi, g in enumerate(groups):          # subgroups follow their parent's waypoints
            if waypoints[gi] is None and g.parent >= 0 and "goal" not in g.authored:
                waypoints[gi] = waypoints[g.parent]
        group_table.waypoints = waypoints
    obstacles, ground = _obstacles(r, scenery)
    fields = [_behavior_field(r, p) for p in layers]
    interest = _interest(r, points)
    bounds = _bounds(ground, obstacles, table, interest, fields)
    events = read_events(stage, {p: i for i, p in enumerate(table.path)}, time, agent_ids=table.agent_id)
    events = model.EventTable([e for e in events if e.authored])
    return model.Scenario(source, time, int(seed), group_table, table, fields, interest, obstacles, bounds,
                          cameras=read_camera_agents(stage), events=events)


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


def _agent_spec(r: _Reader, prim, group_row) -> AgentSpec:
    path = str(prim.GetPath())
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
    names = [n for n in INHERITED if n not in ("visitProfile", "visitBudget", "speedRange", "heightRange",
                                               "spawnCenter", "spawnRadius", "goal")]
    authored = r.authored(prim, names + ["speed", "height", "startPosition"])
    leader_rel = prim.GetRelationship("crowd:leader")
    leader_targets = leader_rel.GetTargets() if leader_rel else []
    pos, heading = r.position_heading(prim)
    return AgentSpec(path, g, authored, int(r.get(prim, "agentId")), str(r.get(prim, "role")),
                     str(leader_targets[0]) if leader_targets else None, pos, heading)


def _resolve(r: _Reader, seed, groups, agents):
    values = inherited_values(groups)
    palette = stored_palette(r.stage)
    by_group: dict[int, list[AgentSpec]] = {i: [] for i in range(len(groups))}
    for a in agents:
        by_group[a.group].append(a)
    rows: list[AgentSpec] = []
    cols: dict[str, list[np.ndarray]] = {}
    for gi, g in enumerate(groups):
        # A shot stage already holds the clones a run made: they are read as
        # authored agents, not made again.
        have = {a.path for a in by_group[gi]}
        clones = [AgentSpec(p, gi) for p in (clone_path(g.path, k) for k in range(g.clones)) if p not in have]
        members = by_group[gi] + clones
        has_subgroups = any(h.parent == gi for h in groups)
        if not members and not has_subgroups:
            prim = r.stage.GetPrimAtPath(g.path)
            r.fail("empty group: no agents, no subgroups and crowd:clones = 0", prim, "crowd:clones")
        if not members:
            continue
        for k, arr in resolve_group_members(seed, g, values[gi], members, palette).items():
            cols.setdefault(k, []).append(arr)
        rows.extend(members)

    n = len(rows)
    path_row = {a.path: i for i, a in enumerate(rows)}
    cat = {k: np.concatenate(v) for k, v in cols.items()}

    # Track ids: authored ones kept (unique, >= 1), the rest numbered after them.
    ids = np.array([a.agent_id for a in rows], dtype=np.int64)
    authored_ids = ids[ids != -1]
    if np.any(authored_ids < 1):
        bad = rows[int(np.flatnonzero((ids != -1) & (ids < 1))[0])]
        r.fail(f"agent ids must be >= 1, got {ids[path_row[bad.path]]}", r.stage.GetPrimAtPath(bad.path), "crowd:agentId")
    uniq, counts = np.unique(authored_ids, return_counts=True)
    if np.any(counts > 1):
        dup = int(uniq[counts > 1][0])
        bad = rows[int(np.flatnonzero(ids == dup)[1])]
        r.fail(f"agent id {dup} is used twice", r.stage.GetPrimAtPath(bad.path), "crowd:agentId")
    free = ids == -1
    ids[free] = (authored_ids.max() if authored_ids.size else 0) + 1 + np.arange(int(free.sum()))

    role = np.array([model.ROLES.index(a.role) for a in rows], dtype=np.int8)
    group = np.array([a.group for a in rows], dtype=np.int32)
    g_leader = np.full(len(groups), -1, dtype=np.int32)
    for i in np.flatnonzero(role != model.ROLES.index("member"))[::-1]:
        g_leader[group[i]] = i
    leader = np.full(n, -1, dtype=np.int32)
    for i, a in enumerate(rows):
        if a.leader_path is not None:
            if a.leader_path not in path_row:
                r.fail(f"target {a.leader_path} is not an agent", r.stage.GetPrimAtPath(a.path), "crowd:leader")
            leader[i] = path_row[a.leader_path]
        elif g_leader[a.group] != i:
            leader[i] = g_leader[a.group]

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


def _scenery_role(prim) -> str:
    """crowd:scenery of the nearest prim (itself or an ancestor) with CrowdSceneryAPI, else "auto"."""
    p = prim
    while p and not p.IsPseudoRoot():
        if p.HasAPI(schema.SCENERY_API):
            return str(p.GetAttribute("crowd:scenery").Get())
        p = p.GetParent()
    return "auto"


def _obstacles(r: _Reader, prims):
    """Footprints of the scenery that blocks walking; flat scenery is ground.

    A footprint is the convex hull of the prim's tessellated vertices seen
    from above (a round fountain stays round); what a prim is follows its
    CrowdSceneryAPI role, or the height rule when it has none.
    """
    from scipy.spatial import ConvexHull

    from ..geometry import mesh_of

    paths, polys, heights, ground = [], [], [], []
    for prim in prims:
        role = _scenery_role(prim)
        if role == "ignore":
            continue
        mesh = mesh_of(prim)
        if mesh is None or len(mesh.vertices) == 0:
            continue
        m = r.world_matrix(prim)
        pts = mesh.vertices.astype(np.float64) @ m[:3, :3] + m[3, :3]
        bottom, top = pts[:, 2].min(), pts[:, 2].max()
        if role == "ground" or (role == "auto" and top - bottom < OBSTACLE_MIN_HEIGHT):
            ground.append(pts[:, :2])
            continue
        if role == "auto" and bottom > OBSTACLE_MAX_BOTTOM:
            continue
        xy = pts[:, :2]
        try:
            poly = xy[ConvexHull(xy).vertices]
        except Exception:      # degenerate footprint (a vertical plane): keep its segment
            poly = xy[[np.argmin(xy[:, 0]), np.argmax(xy[:, 0])]]
        paths.append(str(prim.GetPath()))
        polys.append(np.ascontiguousarray(poly))
        heights.append(top)
    return model.Obstacles(paths, polys, np.array(heights, dtype=np.float64)), ground


def _behavior_field(r: _Reader, prim) -> model.BehaviorField:
    meaning = str(r.get(prim, "meaning"))
    generator = str(r.get(prim, "generator"))
    lo = np.array(r.get(prim, "extentMin"), dtype=np.float64) * r.frame.meters_per_unit
    hi = np.array(r.get(prim, "extentMax"), dtype=np.float64) * r.frame.meters_per_unit
    if np.any(hi <= lo):
        r.fail(f"extent max {tuple(hi)} must exceed extent min {tuple(lo)}", prim, "crowd:extentMax")
    vrange = np.array(r.get(prim, "valueRange"), dtype=np.float64)
    influence = float(r.get(prim, "influence"))
    values = None
    if generator == "painted":
        values = _read_image(r, prim, vrange, hi - lo)
    origin = r.frame.points_to_canonical(np.array(r.get(prim, "origin"), dtype=np.float64))
    radius = float(r.frame.length_to_canonical(r.get(prim, "radius")))
    if meaning == "height" and values is not None:
        values = values * r.frame.meters_per_unit
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
    resolved = asset.resolvedPath
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
    # Normalise by what the file stores, not by numpy's dtype: Pillow opens
    # 16-bit PNGs as "I;16" or, in some versions, as 32-bit "I".
    full = 65535.0 if mode.startswith("I") else 1.0 if mode == "F" else 255.0
    arr = arr.astype(np.float32) / full
    return (vrange[0] + (vrange[1] - vrange[0]) * arr).astype(np.float32)


def _interest(r: _Reader, prims) -> model.InterestTable:
    if not prims:
        return model.InterestTable.empty()
    names = ("interest", "radius", "visibility", "priorKnowledge", "decayRate", "viewDuration")
    vals = {n: np.array([float(r.get(p, n)) for p in prims]) for n in names}
    vals["radius"] = vals["radius"] * r.frame.meters_per_unit
    pos = np.array([r.world_matrix(p)[3, :3] for p in prims])
    return model.InterestTable([str(p.GetPath()) for p in prims], pos, vals["interest"], vals["radius"],
                               vals["visibility"], vals["priorKnowledge"], vals["decayRate"], vals["viewDuration"])


def _bounds(ground, obstacles: model.Obstacles, agents: model.AgentTable, interest, fields) -> np.ndarray:
    """Walkable bounds: the ground's extent if there is ground, else everything padded."""
    if ground:
        pts = np.concatenate(ground)
        return np.array([pts.min(0), pts.max(0)])
    pts = [agents.start[:, :2], interest.position[:, :2]] + list(obstacles.polygons)
    pts += [np.array([f.extent_min, f.extent_max]) for f in fields]
    allp = np.concatenate([p for p in pts if len(p)])
    return np.array([allp.min(0) - BOUNDS_MARGIN, allp.max(0) + BOUNDS_MARGIN])
