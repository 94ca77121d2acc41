"""``usdcrowd validate``: USD's own validators plus the crowd schemas' rules.

USD does not enforce allowedTokens or the documented ranges of our
attributes; these checks do, and collect every problem instead of stopping at
the first.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from . import schema
from .errors import UsdcrowdError
from .scenario.samples import sample_values

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

    from .scenario.stageio import _captured_stderr

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
    from .view import lens_problem

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
    from pxr import UsdGeom

    from .scenario.lights import light_problems
    from .scenario.ranges import range_problem

    out: list[Problem] = []
    ids: dict[int, str] = {}

    def add(prim, attr, msg, severity="error"):
        out.append(Problem(source, str(prim.GetPath()), attr, msg, "usdcrowd", severity))

    from pxr import UsdSkel

    anims = []
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.Camera):
            for attr_name, msg in _lens_problems(prim):
                add(prim, attr_name, msg)
        if prim.IsA(UsdSkel.Animation):
            anims.append(prim)
        for attr_name, msg in _non_finite(prim) + light_problems(prim) + _variant_problems(prim):
            add(prim, attr_name, msg)
        tname = prim.GetTypeName()
        if tname == "DistantLight":
            problem = _dim_sun_problem(prim)
            if problem:
                add(prim, "inputs:normalize", problem, "warning")
        ours = tname in (schema.GROUP, schema.BEHAVIOR_LAYER, schema.INTEREST_POINT, schema.EVENT) \
            or schema.is_agent(prim) or prim.HasAPI(schema.CAMERA_AGENT_API) \
            or prim.HasAPI(schema.SCENERY_API) or prim.HasAPI(schema.TORIC_CAMERA_API)
        if not ours:
            continue
        for attr in prim.GetAttributes():
            name = attr.GetName()
            if not name.startswith("crowd:") or not attr.HasAuthoredValue():
                continue
            value = attr.Get()
            allowed = attr.GetMetadata("allowedTokens")
            if allowed and value is not None and str(value) not in [str(t) for t in allowed]:
                add(prim, name, f"{value!r} is not one of {', '.join(str(t) for t in allowed)}")
                continue
            key = name[len("crowd:"):]
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                problem = range_problem(key, value)
            elif hasattr(value, "__len__") and not isinstance(value, str) and len(value) in (2, 3):
                problem = range_problem(key, tuple(value))
            else:
                problem = None
            if problem:
                add(prim, name, problem)
        if prim.HasAPI(schema.CAMERA_AGENT_API):
            if not prim.IsA(UsdGeom.Camera):
                add(prim, "", "CameraAgentAPI is applied to a prim that is not a Camera")
            rel = prim.GetRelationship("crowd:camera:target")
            for target in (rel.GetTargets() if rel else []):
                t = stage.GetPrimAtPath(target)
                if not (t and (t.GetTypeName() == schema.EVENT or schema.is_agent(t))):
                    add(prim, "crowd:camera:target", f"target {target} is neither a CrowdEvent nor an agent")
        if prim.HasAPI(schema.TORIC_CAMERA_API):
            if not prim.IsA(UsdGeom.Camera):
                add(prim, "", "ToricCameraAPI is applied to a prim that is not a Camera")
            for name in ("crowd:toric:targetA", "crowd:toric:targetB"):
                attr = prim.GetAttribute(name)
                for target in {str(attr.Get(t)) for t in (attr.GetTimeSamples() or [None])} if attr else ():
                    t = stage.GetPrimAtPath(target) if target.startswith("/") else None
                    if target and not (t and schema.is_agent(t)):
                        add(prim, name, f"target {target} is not an agent of this stage")
                        break
        if schema.is_agent(prim):
            body = prim.GetChild("Body")
            problem = _palette_problem(body) if body and body.IsA(UsdGeom.Mesh) else None
            if problem:
                add(body, "primvars:displayColor", problem)
            aid = prim.GetAttribute("crowd:agentId").Get()
            if aid is not None and aid != -1:
                if aid in ids:
                    add(prim, "crowd:agentId", f"agent id {aid} is also used by {ids[aid]}")
                ids[aid] = str(prim.GetPath())
            for rel_name, want in (("crowd:leader", "agent"), ("crowd:group", schema.GROUP)):
                rel = prim.GetRelationship(rel_name)
                for target in (rel.GetTargets() if rel else []):
                    t = stage.GetPrimAtPath(target)
                    ok = t and (schema.is_agent(t) if want == "agent" else t.GetTypeName() == want)
                    if not ok:
                        add(prim, rel_name, f"target {target} is not a {'CrowdAgentAPI agent' if want == 'agent' else want}")
        if tname == schema.EVENT:
            start, end = prim.GetAttribute("crowd:startTime").Get(), prim.GetAttribute("crowd:endTime").Get()
            if end < start:
                add(prim, "crowd:endTime", f"ends ({end}) before it starts ({start})")
            rel = prim.GetRelationship("crowd:members")
            for target in (rel.GetTargets() if rel else []):
                t = stage.GetPrimAtPath(target)
                if not (t and schema.is_agent(t)):
                    add(prim, "crowd:members", f"target {target} is not a CrowdAgentAPI agent")
    for prim, attr_name, msg in _animation_problems(anims):
        add(prim, attr_name, msg)
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

    from .shading import distant_illuminance

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
    from .character.appearance import fit_problem

    values, indices = pv.Get(), pv.GetIndices()
    problem = fit_problem(len(values), (max(indices) + 1) if len(indices) else 1) if values is not None else None
    if problem:
        return problem
    if len(indices) and min(indices) < 0:
        return "primvars:displayColor:indices has a negative index"
    return None


def frame_problems(stage) -> list[Problem]:
    """Sublayers, and references without their correcting transform, in other units or axes than the stage."""
    from .scenery import frame_problems as found

    return [Problem(f, prim, "", message, "usdcrowd") for f, prim, message in found(stage)]


def clip_problems(stage) -> list[Problem]:
    """Value-clip layers that cannot be read (USD opens them only when a value is asked for)."""
    from pxr import Sdf, Tf

    from .scenario.stageio import _captured_stderr, _clip_assets

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
    from .scenario.read import scenario_errors

    if not any(p.GetTypeName() == schema.GROUP or schema.is_agent(p) for p in stage.Traverse()):
        return []
    found = scenario_errors(source, stage=stage, **({"limits": limits} if limits else {}))
    return [Problem(e.file or source, e.prim or "", e.attribute or "", e.message, "usdcrowd") for e in found]


def stage_problems(stage, source: str) -> list[Problem]:
    """What validate finds besides the scenario reader: USD's validators, value clips, units, schema rules."""
    return usd_problems(stage, source) + clip_problems(stage) + frame_problems(stage) + schema_problems(stage, source)


def refuse_errors(stage, source: str) -> None:
    """Raise the first error :func:`stage_problems` finds, so a command (``simulate``) refuses what
    ``validate`` reports as an error; the scenario reader raises its own."""
    from .errors import ScenarioError

    # usdcrowd's own words first: they name the prim and the attribute.
    for p in sorted(stage_problems(stage, source), key=lambda p: (p.source != "usdcrowd", p.prim, p.attribute)):
        if p.severity == "error":
            raise ScenarioError(p.message, file=p.file, prim=p.prim or None, attribute=p.attribute or None)


def validate(path: str | os.PathLike, stage=None, limits=None) -> list[Problem]:
    """Every problem found in a stage; errors first. Empty means valid."""
    from .scenario import open_stage

    source = os.fspath(path)
    stage = stage or open_stage(source)
    found = stage_problems(stage, source)
    seen = {(p.prim, p.attribute, p.message) for p in found}
    found += [p for p in scenario_problems(stage, source, limits) if (p.prim, p.attribute, p.message) not in seen]
    return sorted(found, key=lambda p: (p.severity != "error", p.prim, p.attribute))
