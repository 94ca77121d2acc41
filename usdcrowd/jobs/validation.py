"""``usdcrowd validate``: USD's own validators plus the crowd schemas' rules.

USD does not enforce allowedTokens or the documented ranges of our
attributes; these checks do, and collect every problem instead of stopping at
the first.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from .. import schema
from ..core.errors import UsdcrowdError
from ..scenario.namespace import stage_path
from ..scenario.samples import sample_values

# USD validators that judge packaging for delivery formats, not stages in a
# working folder: a .usdc sublayer is exactly what the design asks for.
_SKIPPED_VALIDATORS = {
    "usdUtilsValidators:UsdzPackageValidator",
    "usdUtilsValidators:RootPackageValidator",
    "usdUtilsValidators:PackageEncapsulationValidator",
    "usdUtilsValidators:FileExtensionValidator",
}


@dataclass(frozen=True)
class Problem:
    """One finding: where, what, and from which check."""

    file: str
    prim: str
    attribute: str
    message: str
    source: str          # the validator's name, or "usdcrowd"
    severity: str = "error"

    def __str__(self) -> str:
        where = self.file + (f":{self.prim}" if self.prim else "") + (f".{self.attribute}" if self.attribute else "")
        return f"{where}: {self.severity}: {' '.join(self.message.split())} [{self.source}]"


def usd_problems(stage, source: str) -> list[Problem]:
    """Findings of pxr.UsdValidation's registered validators."""
    from pxr import UsdValidation

    from ..scenario.stageio import _captured_stderr

    reg = UsdValidation.ValidationRegistry()
    validators = [v for v in reg.GetOrLoadAllValidators() if str(v.GetMetadata().name) not in _SKIPPED_VALIDATORS]
    out = []
    with _captured_stderr():        # the C++ warnings a validator prints as it goes: it reports them itself
        errors = UsdValidation.ValidationContext(validators).Validate(stage)
    for err in errors:
        if err.HasNoError():
            continue
        sev = {UsdValidation.ValidationErrorType.Error: "error",
               UsdValidation.ValidationErrorType.Warn: "warning"}.get(err.GetType(), "info")
        prim = attr = ""
        for site in err.GetSites():
            if site.IsPrim():
                prim = str(site.GetPrim().GetPath())
            elif site.IsProperty():
                prop = site.GetProperty()
                prim, attr = str(prop.GetPrim().GetPath()), prop.GetName()
        validator = err.GetValidator()
        name = str(validator.GetMetadata().name) if validator else str(err.GetName())
        out.append(Problem(source, prim, attr, err.GetMessage(), name, sev))
    return out


def _animation_problems(anims) -> list[tuple[object, str, str]]:
    """(prim, attribute, message) for skeletal animation samples that are NaN or infinite.

    Samples are read from the layers that hold them, value clips included
    (no composition per sample: 2.7 s for 2,000 agents x 240 frames here),
    with a progress bar when there are many.
    """
    from pxr import UsdSkel
    from tqdm import tqdm

    out = []
    for prim in tqdm(anims, desc="validate animation", unit="agent", disable=len(anims) < 500, leave=False):
        anim = UsdSkel.Animation(prim)
        for attr in (anim.GetRotationsAttr(), anim.GetTranslationsAttr(), anim.GetScalesAttr()):
            times = attr.GetTimeSamples()
            for t, v in zip(times, sample_values(attr, times)):
                if v is None:
                    out.append((prim, attr.GetName(), f"no value at time {t:g} (a layer that holds it is "
                                                      f"missing or unreadable)"))
                    break
                if not np.isfinite(np.asarray(v, dtype=np.float64)).all():
                    out.append((prim, attr.GetName(), f"not a finite value at time {t:g}"))
                    break
    return out


def _non_finite(prim) -> list[tuple[str, str]]:
    """Transform ops that are NaN or infinite (default value and authored samples)."""
    from pxr import UsdGeom

    attrs = []
    if prim.IsA(UsdGeom.Xformable):
        attrs += [op.GetAttr() for op in UsdGeom.Xformable(prim).GetOrderedXformOps()]
    out = []
    for attr in attrs:
        if not attr or not attr.HasAuthoredValue():
            continue
        for t in [None] + list(attr.GetTimeSamples()):
            v = attr.Get() if t is None else attr.Get(t)
            try:
                finite = v is None or bool(np.isfinite(np.asarray(v, dtype=np.float64)).all())
            except (TypeError, ValueError):
                finite = True
            if not finite:
                out.append((attr.GetName(), f"not a finite value{'' if t is None else f' at time {t:g}'}"))
                break
    return out


def _lens_problems(prim) -> list[tuple[str, str]]:
    """Lens values no renderer can use, at the default time and every authored sample."""
    from ..core.view import lens_problem

    out = []
    for name in ("focalLength", "horizontalAperture", "verticalAperture", "clippingRange"):
        attr = prim.GetAttribute(name)
        if not attr or not attr.HasAuthoredValue():
            continue
        times = [None] + list(attr.GetTimeSamples())
        for t in times:
            v = attr.Get() if t is None else attr.Get(t)
            if v is None:
                continue
            problem = lens_problem(name, v)
            if problem:
                out.append((name, problem + ("" if t is None else f" at time {t:g}")))
                break
    return out


def schema_problems(stage, source: str) -> list[Problem]:
    """Crowd-schema rules: allowed tokens, documented ranges, relationships, assets, ids."""
    from pxr import UsdGeom, UsdSkel

    from ..scenario.lights import light_problems

    found: list[tuple] = []                 # (prim, attribute, message[, severity])
    ids: dict[int, str] = {}
    anims = []
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.Camera):
            found += [(prim, a, m) for a, m in _lens_problems(prim)]
        if prim.IsA(UsdSkel.Animation):
            anims.append(prim)
        found += [(prim, a, m) for a, m in _non_finite(prim) + light_problems(prim) + _variant_problems(prim)]
        tname = prim.GetTypeName()
        if tname == "DistantLight":
            problem = _dim_sun_problem(prim)
            if problem:
                found.append((prim, "inputs:normalize", problem, "warning"))
        if not _is_ours(prim):
            continue
        found += _value_problems(prim)
        if prim.HasAPI(schema.CAMERA_AGENT_API):
            found += _camera_agent_problems(stage, prim)
        if prim.HasAPI(schema.TORIC_CAMERA_API):
            found += _toric_problems(stage, prim)
        if schema.is_agent(prim):
            found += _agent_problems(stage, prim, ids)
        if tname == schema.EVENT:
            found += _event_problems(stage, prim)
    found += _animation_problems(anims)
    return [Problem(source, str(f[0].GetPath()), f[1], f[2], "usdcrowd", *(f[3:] or ("error",))) for f in found]


def _is_ours(prim) -> bool:
    """Whether a prim is one of the crowd schemas' (typed, or with one of their API schemas)."""
    return prim.GetTypeName() in (schema.GROUP, schema.BEHAVIOR_LAYER, schema.INTEREST_POINT, schema.EVENT) \
        or schema.is_agent(prim) or prim.HasAPI(schema.CAMERA_AGENT_API) \
        or prim.HasAPI(schema.SCENERY_API) or prim.HasAPI(schema.TORIC_CAMERA_API)


def _value_problems(prim) -> list[tuple]:
    """Authored ``crowd:`` values outside their allowed tokens or documented ranges."""
    from ..scenario.ranges import range_problem

    out = []
    for attr in prim.GetAttributes():
        name = attr.GetName()
        if not name.startswith("crowd:") or not attr.HasAuthoredValue():
            continue
        value = attr.Get()
        allowed = attr.GetMetadata("allowedTokens")
        if allowed and value is not None and str(value) not in [str(t) for t in allowed]:
            out.append((prim, name, f"{value!r} is not one of {', '.join(str(t) for t in allowed)}"))
            continue
        key = name[len("crowd:"):]
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            problem = range_problem(key, value)
        elif hasattr(value, "__len__") and not isinstance(value, str) and len(value) in (2, 3):
            problem = range_problem(key, tuple(value))
        else:
            problem = None
        if problem:
            out.append((prim, name, problem))
    return out


def _camera_agent_problems(stage, prim) -> list[tuple]:
    from pxr import UsdGeom

    out = [] if prim.IsA(UsdGeom.Camera) else [(prim, "", "CameraAgentAPI is applied to a prim that is not a Camera")]
    rel = prim.GetRelationship("crowd:camera:target")
    for target in (rel.GetTargets() if rel else []):
        t = stage.GetPrimAtPath(target)
        if not (t and (t.GetTypeName() == schema.EVENT or schema.is_agent(t))):
            out.append((prim, "crowd:camera:target", f"target {target} is neither a CrowdEvent nor an agent"))
    return out


def _toric_problems(stage, prim) -> list[tuple]:
    from pxr import UsdGeom

    out = [] if prim.IsA(UsdGeom.Camera) else [(prim, "", "ToricCameraAPI is applied to a prim that is not a Camera")]
    for name in ("crowd:toric:targetA", "crowd:toric:targetB"):
        attr = prim.GetAttribute(name)
        for target in {stage_path(attr, str(attr.Get(t)), t)
                       for t in (attr.GetTimeSamples() or [None])} if attr else ():
            t = stage.GetPrimAtPath(target) if target.startswith("/") else None
            if target and not (t and schema.is_agent(t)):
                out.append((prim, name, f"target {target} is not an agent of this stage"))
                break
    return out


def _agent_problems(stage, prim, ids: dict[int, str]) -> list[tuple]:
    """An agent's palette, its id (unique: ``ids`` holds those seen), its leader and group."""
    from pxr import UsdGeom

    out = []
    body = prim.GetChild("Body")
    problem = _palette_problem(body) if body and body.IsA(UsdGeom.Mesh) else None
    if problem:
        out.append((body, "primvars:displayColor", problem))
    aid = prim.GetAttribute("crowd:agentId").Get()
    if aid is not None and aid != -1:
        if aid in ids:
            out.append((prim, "crowd:agentId", f"agent id {aid} is also used by {ids[aid]}"))
        ids[aid] = str(prim.GetPath())
    for rel_name, want in (("crowd:leader", "agent"), ("crowd:group", schema.GROUP)):
        rel = prim.GetRelationship(rel_name)
        for target in (rel.GetTargets() if rel else []):
            t = stage.GetPrimAtPath(target)
            ok = t and (schema.is_agent(t) if want == "agent" else t.GetTypeName() == want)
            if not ok:
                out.append((prim, rel_name,
                            f"target {target} is not a {'CrowdAgentAPI agent' if want == 'agent' else want}"))
    return out


def _event_problems(stage, prim) -> list[tuple]:
    out = []
    start, end = prim.GetAttribute("crowd:startTime").Get(), prim.GetAttribute("crowd:endTime").Get()
    if end < start:
        out.append((prim, "crowd:endTime", f"ends ({end}) before it starts ({start})"))
    rel = prim.GetRelationship("crowd:members")
    for target in (rel.GetTargets() if rel else []):
        t = stage.GetPrimAtPath(target)
        if not (t and schema.is_agent(t)):
            out.append((prim, "crowd:members", f"target {target} is not a CrowdAgentAPI agent"))
    return out


def _variant_problems(prim) -> list[tuple[str, str]]:
    """Variant selections that name no variant of their set: USD composes nothing from the set, silently."""
    if not prim.HasVariantSets():
        return []
    sets = prim.GetVariantSets()
    out = []
    for name, selection in sets.GetAllVariantSelections().items():
        variants = sets.GetVariantSet(name).GetVariantNames() if sets.HasVariantSet(name) else []
        if selection and selection not in variants:
            out.append((f"variants:{name}", f"selects {selection!r}, which variant set {name!r} does not have "
                                            f"({', '.join(repr(v) for v in variants) or 'no variants'})"))
    return out


def _dim_sun_problem(prim) -> str | None:
    """An unnormalised DistantLight that gives under 1 % of its intensity as illuminance: an older usdcrowd
    stage, or one meant for a renderer that ignores inputs:normalize (UsdLux: its intensity is the disc's
    luminance)."""
    from pxr import UsdLux

    from ..core.shading import distant_illuminance

    light = UsdLux.DistantLight(prim)
    angle, normalize = light.GetAngleAttr().Get(), light.GetNormalizeAttr().Get()
    factor = distant_illuminance(angle, bool(normalize))
    if factor >= 0.01:
        return None
    return (f"not normalised, so UsdLux reads its intensity as the {angle:g}-degree disc's luminance and the "
            f"sun gives {factor:.2g} of it as illuminance; author inputs:normalize = true to make the intensity "
            f"the illuminance")


def _palette_problem(body) -> str | None:
    """An agent body's colours that its vertices' indices cannot use (character.appearance)."""
    from pxr import UsdGeom

    pv = UsdGeom.PrimvarsAPI(body).GetPrimvar("displayColor")
    if not pv or not pv.IsIndexed() or not pv.HasAuthoredValue():
        return None
    from ..character.appearance import fit_problem

    values, indices = pv.Get(), pv.GetIndices()
    problem = fit_problem(len(values), (max(indices) + 1) if len(indices) else 1) if values is not None else None
    if problem:
        return problem
    if len(indices) and min(indices) < 0:
        return "primvars:displayColor:indices has a negative index"
    return None


def frame_problems(stage) -> list[Problem]:
    """Sublayers, and references without their correcting transform, in other units or axes than the stage."""
    from ..scenario.scenery import frame_problems as found

    return [Problem(f, prim, "", message, "usdcrowd") for f, prim, message in found(stage)]


def clip_problems(stage) -> list[Problem]:
    """Value-clip layers that cannot be read (USD opens them only when a value is asked for)."""
    from pxr import Sdf, Tf

    from ..scenario.stageio import _captured_stderr, _clip_assets

    out = []
    for layer in stage.GetUsedLayers():
        for asset in _clip_assets(layer):
            path = layer.ComputeAbsolutePath(asset)
            if not os.path.isfile(path):
                continue                # USD's own validator reports missing files
            with _captured_stderr():
                try:
                    ok = Sdf.Layer.OpenAsAnonymous(path) is not None
                except Tf.ErrorException:
                    ok = False
            if not ok:
                out.append(Problem(layer.realPath or layer.identifier, "", "",
                                   f"value clip {asset} is not a readable USD file", "usdcrowd"))
    return out


def scenario_problems(stage, source: str, limits=None) -> list[Problem]:
    """The problems the scenario reader finds (empty groups, missing images, bad units...), all of them."""
    from ..scenario.read import scenario_errors

    if not any(p.GetTypeName() == schema.GROUP or schema.is_agent(p) for p in stage.Traverse()):
        return []
    found = scenario_errors(source, stage=stage, **({"limits": limits} if limits else {}))
    return [Problem(e.file or source, e.prim or "", e.attribute or "", e.message, "usdcrowd") for e in found]


def round_trip_problems(stage, source: str) -> list[Problem]:
    """What a shot exported back out of a DCC tool has lost, and what it still lets usdcrowd do.

    Its agents have no CrowdAgentAPI: they are known by the crowd custom
    properties they carry (:func:`usdcrowd.schema.agent_id`). What they lost
    is a warning (inspect, render and the ground truth still work); ids that
    no longer tell agents apart are errors, as for any agent.
    """
    agents = schema.agent_prims(stage)
    carried = [prim for prim, _ in agents if not schema.is_agent(prim)]
    found = _characters_without_ids(stage, agents)
    if carried:
        found += [(carried[0], "crowd:agentId",
                   f"{len(carried)} agent(s) without CrowdAgentAPI, known by the crowd:agentId they carry as a "
                   f"custom property (a shot exported back out of a DCC tool): inspect, render and the ground truth "
                   f"read their ids, groups and roles; simulate, cameras and events need the usdcrowd shot",
                   "warning")]
        found += _lost_by_round_trip(stage, carried) + _carried_id_problems(agents)
    return [Problem(source, str(prim.GetPath()) if prim else "", attr, msg, "usdcrowd", severity)
            for prim, attr, msg, severity in found]


def _characters_without_ids(stage, agents: list) -> list[tuple]:
    """(prim, attribute, message, "warning") for usdcrowd's characters that are no agent: a SkelAnimation of
    our rig's joints outside every agent, as a DCC tool exports them without custom properties (nothing
    says who they are: they get no ground truth)."""
    from pxr import UsdSkel

    from ..character import rig

    inside = tuple(str(prim.GetPath()) + "/" for prim, _ in agents)
    lost = [p for p in stage.Traverse() if p.IsA(UsdSkel.Animation)
            and tuple(UsdSkel.Animation(p).GetJointsAttr().Get() or ()) == rig.JOINTS
            and not str(p.GetPath()).startswith(inside)]
    if not lost:
        return []
    return [(lost[0], "", f"{len(lost)} character(s) animated with usdcrowd's skeleton carry no crowd:agentId, so "
                          f"they are no agents and get no ground truth (exported without custom properties?)",
             "warning")]


def _lost_by_round_trip(stage, carried: list) -> list[tuple]:
    """(prim, attribute, message, "warning") for what agents known by custom properties no longer have:
    their groups, per-frame states, leaders, and (when exported without it) their animation."""
    from ..scenario.shot_scene import skeleton_and_animation

    out = []
    groups = sorted({schema.agent_group(p) for p in carried} - {str(p.GetPath()) for p in stage.Traverse()
                                                                 if schema.is_group(p)})
    if groups:
        out.append((None, "", f"the agents' groups ({', '.join(groups[:3])}{', ...' if len(groups) > 3 else ''}) "
                              f"are no CrowdGroup here: their crowd:* attributes are custom properties that nothing "
                              f"inherits", "warning"))
    held = [p for p in carried if any(a.GetName().startswith("crowd:state:") and not a.GetNumTimeSamples()
                                      for a in p.GetAttributes())]
    if held:
        out.append((held[0], "crowd:state:*", f"{len(held)} agent(s) hold one crowd:state:* value each, no longer "
                                              f"sampled per frame: the ground truth leaves their states out",
                    "warning"))
    leaders = [p for p in carried if str(schema.crowd_value(p, "role")) in ("leader", "invisibleLeader")]
    if leaders and not any(p.GetRelationship("crowd:leader") for p in carried):
        out.append((leaders[0], "crowd:leader", "who follows which leader (crowd:leader) is gone", "warning"))
    still = [p for p in carried if skeleton_and_animation(p)[1] is None]
    if still:
        out.append((still[0], "skel:animationSource", f"{len(still)} agent(s) have no SkelAnimation bound to their "
                                                      f"skeleton, so nothing renders them (export with animation: "
                                                      f"Blender's Animation box)", "warning"))
    return out


def _carried_id_problems(agents: list) -> list[tuple]:
    """(prim, "crowd:agentId", message, "error") for carried ids that are no track id or repeat another agent's
    (Blender's duplicate copies an object's custom properties)."""
    from ..scenario.ranges import range_problem

    out, seen = [], {}
    for prim, aid in agents:
        if not schema.is_agent(prim):            # the schema's own agents are checked by schema_problems
            problem = range_problem("agentId", aid) or ("-1 (numbered automatically) means nothing once the shot "
                                                        "is made: the agent lost its track id" if aid == -1 else None)
            if not problem and aid in seen:
                problem = f"agent id {aid} is also used by {seen[aid]}"
            if problem:
                out.append((prim, "crowd:agentId", problem, "error"))
        seen.setdefault(aid, str(prim.GetPath()))
    return out


def dropped_root_problems(stage) -> list[Problem]:
    """Warnings for a scenery file without a defaultPrim referenced for only some of its root prims (a
    warning: scenarios written before every root was brought in still simulate)."""
    from ..scenario.scenery import dropped_root_problems as found

    return [Problem(f, prim, "", message, "usdcrowd", "warning") for f, prim, message in found(stage)]


def placement_problems(stage, source: str) -> list[Problem]:
    """A warning when a stage ``usdcrowd place`` wrote no longer plays its shot's frames (the shot was
    simulated again over other frames since): USD takes the frames from the root layer only."""
    import os

    from pxr import Sdf

    data = stage.GetRootLayer().customLayerData.get("usdcrowd", {})
    placed = data.get("placed") if isinstance(data, dict) else None
    if not isinstance(placed, dict) or "frames" not in placed:
        return []
    shot = os.path.join(os.path.dirname(stage.GetRootLayer().realPath or source), str(placed.get("shot")))
    try:
        layer = Sdf.Layer.OpenAsAnonymous(shot)
    except Exception:
        return []                           # a missing shot is the stage's own error
    now = (float(layer.startTimeCode), float(layer.endTimeCode))
    was = tuple(float(v) for v in placed["frames"])
    if now == was:
        return []
    return [Problem(source, str(placed.get("prim", "")), "endTimeCode",
                    f"its shot now plays frames {now[0]:g}-{now[1]:g}, placed when it played {was[0]:g}-{was[1]:g}: "
                    f"this stage still plays {stage.GetStartTimeCode():g}-{stage.GetEndTimeCode():g}; place it "
                    f"again", "usdcrowd", "warning")]


def lens_unit_problems(stage, source: str) -> list[Problem]:
    """A warning for a camera whose lens was authored in other units than the stage's: usdcrowd reads it
    in its own layer's units, but USD does not convert values across a reference, so Blender, usdview
    and a flattened copy read it that many times too long or short."""
    from pxr import UsdGeom

    from ..scenario import stage_frame
    from ..scenario.stageio import lens_scale

    try:
        frame = stage_frame(stage)
    except UsdcrowdError:
        return []                           # the stage's own units are wrong: reported on their own
    out = []
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.Camera):
            continue
        attr = UsdGeom.Camera(prim).GetFocalLengthAttr()
        if not attr.HasAuthoredValue():
            continue
        t = (attr.GetTimeSamples() or [stage.GetStartTimeCode()])[0]
        scale = lens_scale(attr, t, frame, frame.meters_per_unit)
        if scale != 1.0:
            out.append(Problem(source, str(prim.GetPath()), "focalLength",
                               f"lens authored in a layer of {scale * frame.meters_per_unit:g} m per unit under a "
                               f"stage of {frame.meters_per_unit:g}: usdcrowd reads it right, but Blender, usdview "
                               f"and a flattened copy read it as {1 / scale:g} times its length; "
                               f"`usdcrowd place` converts the lenses of a shot it places", "usdcrowd", "warning"))
    return out


def fallback_problems(stage, source: str) -> list[Problem]:
    """A warning when the stage uses our typed prims from another layer (it references or sublayers a
    shot or a scenario) and its root layer lacks their ``fallbackPrimTypes``: USD reads them only from
    the root layer, and without them Blender drops the crowd's groups and with them the agents' parent."""
    root = stage.GetRootLayer()
    have = dict(root.pseudoRoot.GetInfo("fallbackPrimTypes")) if root.pseudoRoot.HasInfo("fallbackPrimTypes") else {}
    missing = {}
    for prim in stage.Traverse():
        kind = prim.GetTypeName()
        if kind in schema.FALLBACK_PRIM_TYPES and kind not in have and kind not in missing:
            if prim.GetPrimStack()[-1].layer != root:       # defined elsewhere: the stage brings it in
                missing[kind] = str(prim.GetPath())
    if not missing:
        return []
    return [Problem(source, "", "fallbackPrimTypes",
                    f"uses {', '.join(sorted(missing))} prims (e.g. {next(iter(missing.values()))}) without the "
                    f"fallbackPrimTypes that tell tools without usdcrowd's schemas what they are: Blender drops "
                    f"them and their agents' parent; `usdcrowd place` writes them", "usdcrowd", "warning")]


def stage_problems(stage, source: str) -> list[Problem]:
    """What validate finds besides the scenario reader: USD's validators, value clips, units, schema rules, and what
    a round trip through a DCC tool lost."""
    return (usd_problems(stage, source) + clip_problems(stage) + frame_problems(stage) + schema_problems(stage, source)
            + round_trip_problems(stage, source) + fallback_problems(stage, source) + dropped_root_problems(stage)
            + lens_unit_problems(stage, source) + placement_problems(stage, source))


def refuse_errors(stage, source: str) -> None:
    """Raise the first error :func:`stage_problems` finds, so a command (``simulate``) refuses what
    ``validate`` reports as an error; the scenario reader raises its own."""
    from ..core.errors import ScenarioError

    # usdcrowd's own words first: they name the prim and the attribute.
    for p in sorted(stage_problems(stage, source), key=lambda p: (p.source != "usdcrowd", p.prim, p.attribute)):
        if p.severity == "error":
            raise ScenarioError(p.message, file=p.file, prim=p.prim or None, attribute=p.attribute or None)


def validate(path: str | os.PathLike, stage=None, limits=None) -> list[Problem]:
    """Every problem found in a stage; errors first. Empty means valid."""
    from ..scenario import open_stage

    source = os.fspath(path)
    stage = stage or open_stage(source)
    found = stage_problems(stage, source)
    seen = {(p.prim, p.attribute, p.message) for p in found}
    found += [p for p in scenario_problems(stage, source, limits) if (p.prim, p.attribute, p.message) not in seen]
    return sorted(found, key=lambda p: (p.severity != "error", p.prim, p.attribute))
