"""A readable summary of a stage: what ``usdcrowd inspect`` prints.

Works on scenario and shot stages alike: layers, time range, the group tree
with counts and resolved attributes, agents, behavior layers, interest
points, cameras, lights and events.
"""

from __future__ import annotations

import os
from collections import Counter

import numpy as np

from ..core import model
from .. import schema


def summarize(path: str | os.PathLike, stage=None, limits=None) -> dict:
    """Collect the summary of a stage as plain JSON-able data."""
    from pxr import Usd, UsdGeom, UsdLux

    from ..scenario.stageio import camera_lens

    from ..scenario import load_scenario, open_stage, stage_frame
    from ..scenario.events import read_events
    from ..scenario.read import stored_seed
    from ..scenario.stageio import time_range

    path = os.fspath(path)
    stage = stage or open_stage(path)
    frame = stage_frame(stage)
    out: dict = {
        "stage": path,
        "upAxis": frame.up_axis,
        "metersPerUnit": frame.meters_per_unit,
        "defaultPrim": stage.GetDefaultPrim().GetName() if stage.GetDefaultPrim() else None,
        "time": {"start": stage.GetStartTimeCode(), "end": stage.GetEndTimeCode(),
                 "fps": stage.GetTimeCodesPerSecond(), "authored": stage.HasAuthoredTimeCodeRange()},
        "seed": stored_seed(stage),
        "layers": [_layer_name(layer, path) for layer in stage.GetLayerStack(includeSessionLayers=False)],
    }
    has_crowd = any(p.GetTypeName() == schema.GROUP or schema.is_agent(p) for p in stage.Traverse())
    if has_crowd:
        sc = load_scenario(path, stage=stage, **({'limits': limits} if limits else {}))
        out["groups"] = _groups(stage, sc)
        out["agents"] = _agents(sc)
        out["behaviorLayers"] = [{
            "path": f.path, "meaning": model.LAYER_MEANINGS[f.meaning],
            "generator": model.LAYER_GENERATORS[f.generator],
            "extent": [f.extent_min.tolist(), f.extent_max.tolist()],
            "resolution": list(f.values.shape[::-1]) if f.values is not None else None,
            "influence": f.influence} for f in sc.fields]
        out["interestPoints"] = [{
            "path": p, "position": sc.interest.position[i].round(3).tolist(),
            "interest": float(sc.interest.interest[i]), "radius": float(sc.interest.radius[i]),
            "visibility": float(sc.interest.visibility[i])} for i, p in enumerate(sc.interest.path)]
        out["obstacles"] = len(sc.obstacles)
    else:
        carried = _carried_agents(stage)
        if carried:
            out["agents"] = _carried_summary(carried)
    cams, lights, events = [], [], []
    # Lens attributes are in tenths of the authoring layer's scene unit; reported in millimetres.
    frame = stage_frame(stage)
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.Camera):
            cam = UsdGeom.Camera(prim)
            xf = UsdGeom.Xformable(prim)
            focal, h_ap, v_ap, near, far = camera_lens(cam, Usd.TimeCode.Default(), frame)
            cams.append({
                "path": str(prim.GetPath()), "focalLengthMm": focal, "apertureMm": [h_ap, v_ap],
                "clipping": [near, far],
                "animated": bool(xf.TransformMightBeTimeVarying()),
                "cameraAgent": prim.HasAPI(schema.CAMERA_AGENT_API),
                "toric": ({"behavior": str(prim.GetAttribute("crowd:toric:behavior").Get()),
                           "shotSize": str(prim.GetAttribute("crowd:toric:shotSize").Get())}
                          if prim.HasAPI(schema.TORIC_CAMERA_API) else None)})
        elif prim.HasAPI(UsdLux.LightAPI):
            light = UsdLux.LightAPI(prim)
            lights.append({"path": str(prim.GetPath()), "type": str(prim.GetTypeName()),
                           "intensity": light.GetIntensityAttr().Get(),
                           "exposure": light.GetExposureAttr().Get(),
                           "color": list(light.GetColorAttr().Get())})
    rows = {p: i for i, p in enumerate(sc.agents.path)} if has_crowd else {}
    ids = sc.agents.agent_id if has_crowd else None
    for e in read_events(stage, rows, time_range(stage), agent_ids=ids):
        events.append({"path": e.path, "kind": model.EVENT_KINDS[e.kind], "members": len(e.members),
                       "start": e.start, "end": e.end, "authored": e.authored})
    out["cameras"], out["lights"], out["events"] = cams, lights, events
    return out


def _layer_name(layer, stage_path: str) -> str:
    real = layer.realPath
    if not real:
        return layer.identifier
    return os.path.relpath(real, os.path.dirname(os.path.abspath(stage_path)))


def _groups(stage, sc: model.Scenario) -> list[dict]:
    a = sc.agents
    per_group = np.bincount(a.group, minlength=len(sc.groups))
    total = per_group.astype(np.int64).copy()
    for gi in range(len(sc.groups) - 1, -1, -1):       # parents come first: sum bottom-up
        if sc.groups.parent[gi] >= 0:
            total[sc.groups.parent[gi]] += total[gi]
    rows = []
    for gi, path in enumerate(sc.groups.path):
        prim = stage.GetPrimAtPath(path)
        members = np.flatnonzero(a.group == gi)
        authored = {p.GetName().split(":", 1)[1]: _plain(p.Get()) for p in prim.GetAttributes()
                    if p.GetName().startswith("crowd:") and p.HasAuthoredValue()}
        resolved = {}
        if members.size:
            for key, vocab in (("characterType", model.CHARACTER_TYPES), ("personality", model.PERSONALITIES),
                               ("behavior", model.BEHAVIORS), ("condition", model.CONDITIONS),
                               ("visitProfile", model.VISIT_PROFILES)):
                col = getattr(a, _snake(key))[members]
                resolved[key] = dict(Counter(vocab[c] for c in col))
            resolved["speed"] = [round(float(a.speed[members].min()), 3), round(float(a.speed[members].max()), 3)]
            resolved["height"] = [round(float(a.height[members].min()), 3), round(float(a.height[members].max()), 3)]
        depth, p = 0, sc.groups.parent[gi]
        while p >= 0:
            depth, p = depth + 1, sc.groups.parent[p]
        rows.append({"path": path, "depth": depth, "agents": int(per_group[gi]), "agentsInTree": int(total[gi]),
                     "authored": authored, "resolved": resolved})
    return rows


def _agents(sc: model.Scenario) -> dict:
    a = sc.agents
    return {
        "count": len(a),
        "visible": int(a.visible.sum()),
        "roles": dict(Counter(model.ROLES[c] for c in a.role)),
        "personality": dict(Counter(model.PERSONALITIES[c] for c in a.personality)),
        "ids": [int(a.agent_id.min()), int(a.agent_id.max())] if len(a) else [],
        "withLeader": int((a.leader >= 0).sum()),
    }


def agent_list(path: str | os.PathLike, limits=None) -> list[dict]:
    """Every agent of a stage (scenario or shot): name, prim path, id, group, visible and role, in the
    scenario's order (what ``inspect --agents`` lists); for a shot back from a DCC tool, its agents known by
    their custom properties, in stage order; empty for a stage without a crowd."""
    from ..scenario import load_scenario, open_stage

    path = os.fspath(path)
    stage = open_stage(path)
    if not any(p.GetTypeName() == schema.GROUP or schema.is_agent(p) for p in stage.Traverse()):
        return _carried_agents(stage)
    sc = load_scenario(path, stage=stage, **({"limits": limits} if limits else {}))
    a = sc.agents
    return [{"name": path.rsplit("/", 1)[-1], "path": path, "id": int(a.agent_id[i]),
             "group": sc.groups.path[a.group[i]], "visible": bool(a.visible[i]), "role": model.ROLES[a.role[i]]}
            for i, path in enumerate(a.path)]


def _carried_agents(stage) -> list[dict]:
    """The rows of :func:`agent_list` for agents without our schemas, known by the crowd custom properties
    they carry (:func:`usdcrowd.schema.agent_id`): a shot exported back out of a DCC tool."""
    from pxr import Usd, UsdGeom

    time = Usd.TimeCode(stage.GetStartTimeCode())
    rows = []
    for prim, aid in schema.agent_prims(stage):
        if schema.is_agent(prim):
            continue
        path = str(prim.GetPath())
        rows.append({"name": path.rsplit("/", 1)[-1], "path": path, "id": aid, "group": schema.agent_group(prim),
                     "visible": UsdGeom.Imageable(prim).ComputeVisibility(time) != UsdGeom.Tokens.invisible,
                     "role": str(schema.crowd_value(prim, "role") or "member")})
    return rows


def _carried_summary(agents: list[dict]) -> dict:
    """:func:`_agents`'s summary of agents known only by their custom properties (who leads whom is lost)."""
    ids = [a["id"] for a in agents]
    return {"count": len(agents), "visible": sum(a["visible"] for a in agents),
            "roles": dict(Counter(a["role"] for a in agents)), "personality": {}, "ids": [min(ids), max(ids)],
            "withLeader": 0, "customProperties": True}


def format_agents(agents: list[dict]) -> str:
    """One line per agent (after a header): what ``inspect --agents`` prints."""
    if not agents:
        return "no agents"
    rows = [("name", "path", "id", "group", "visible", "role")] + [
        (a["name"], a["path"], str(a["id"]), a["group"], "yes" if a["visible"] else "no", a["role"]) for a in agents]
    widths = [max(len(r[k]) for r in rows) for k in range(5)]
    return "\n".join("  ".join(v.ljust(w) for v, w in zip(r, widths)) + "  " + r[5] for r in rows)


def _snake(name: str) -> str:
    return "".join("_" + c.lower() if c.isupper() else c for c in name)


def _plain(v):
    if hasattr(v, "path"):          # Sdf.AssetPath
        return v.path
    if hasattr(v, "__len__") and not isinstance(v, str):
        return [round(float(x), 4) for x in v]
    if isinstance(v, float):
        return round(v, 4)
    return v if isinstance(v, (int, bool)) else str(v)


def _agents_line(a: dict) -> str:
    """The ``agents`` line of :func:`format_summary`."""
    if not a["count"]:
        return "agents  0"
    if a.get("customProperties"):
        return (f"agents  {a['count']} ({a['visible']} visible), ids {a['ids'][0]}-{a['ids'][1]}, roles {a['roles']}, "
                f"known by their custom properties (names: inspect --agents; what was lost: validate)")
    return (f"agents  {a['count']} ({a['visible']} visible), ids {a['ids'][0]}-{a['ids'][1]}, "
            f"roles {a['roles']}, {a['withLeader']} follow a leader (names: inspect --agents)")


def format_summary(s: dict) -> str:
    """Render :func:`summarize`'s data as the text ``inspect`` prints."""
    t = s["time"]
    lines = [f"stage   {s['stage']}",
             f"        {s['upAxis']} up, {s['metersPerUnit']:g} m/unit, frames {t['start']:g}-{t['end']:g} "
             f"at {t['fps']:g} fps{'' if t['authored'] else ' (not authored)'}, "
             f"seed {s['seed'] if s['seed'] is not None else 'unset'}",
             "layers  " + "  >  ".join(s["layers"])]
    if "groups" in s:
        lines.append(f"groups  {len(s['groups'])}")
        for g in s["groups"]:
            name = g["path"] if g["depth"] == 0 else "  " * g["depth"] + g["path"].rsplit("/", 1)[-1]
            res = g["resolved"]
            bits = [f"{k}={'/'.join(f'{v}:{c}' if len(res[k]) > 1 else v for v, c in res[k].items())}"
                    for k in ("characterType", "personality", "behavior", "condition", "visitProfile") if k in res]
            if "speed" in res:
                bits.append(f"speed={res['speed'][0]:g}-{res['speed'][1]:g} m/s")
            lines.append(f"  {name:<34} {g['agents']:>6} agents ({g['agentsInTree']} in tree)  " + " ".join(bits))
        lines.append(_agents_line(s["agents"]))
        lines.append(f"layers  {len(s['behaviorLayers'])} behavior layer(s)")
        for f in s["behaviorLayers"]:
            lines.append(f"  {f['path']}  {f['meaning']} ({f['generator']}), extent {f['extent']}, influence {f['influence']:g}")
        lines.append(f"interest {len(s['interestPoints'])} point(s)")
        for p in s["interestPoints"]:
            lines.append(f"  {p['path']}  at {p['position']}, interest {p['interest']:g}, radius {p['radius']:g} m, "
                         f"visibility {p['visibility']:g}")
        lines.append(f"scenery {s['obstacles']} obstacle(s)")
    elif "agents" in s:
        lines.append(_agents_line(s["agents"]))
    lines.append(f"cameras {len(s['cameras'])}")
    for c in s["cameras"]:
        lines.append(f"  {c['path']}  {c['focalLengthMm']:.4g} mm, aperture {c['apertureMm'][0]:.4g}x"
                     f"{c['apertureMm'][1]:.4g} mm, "
                     f"clip {c['clipping'][0]:.4g}-{c['clipping'][1]:.6g} m{', animated' if c['animated'] else ''}"
                     f"{', camera agent' if c['cameraAgent'] else ''}"
                     + (f", toric camera ({c['toric']['behavior']}, {c['toric']['shotSize']})" if c.get("toric") else ""))
    lines.append(f"lights  {len(s['lights'])}")
    for li in s["lights"]:
        lines.append(f"  {li['path']}  {li['type']}, intensity {li['intensity']:g}, exposure {li['exposure']:g}")
    lines.append(f"events  {len(s['events'])}")
    for e in s["events"]:
        when = f"frames {e['start']:g}-{e['end']:g}" if e["start"] <= e["end"] else "not within the stage's frames"
        lines.append(f"  {e['path']}  {e['kind']}, {e['members']} members, {when}")
    return "\n".join(lines)
