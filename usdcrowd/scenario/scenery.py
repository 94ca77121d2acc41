"""A DCC tool's scenery under a template crowd: referenced, with the transform its units and axes need.

A layer written in other units or another up axis than the stage that
references it is composed as it is: a Y-up centimetre town referenced into a
Z-up metre scenario comes in a hundred times too big and on its side. USD
leaves the correction to the referencing prim, so :func:`place_scenery`
authors it there (a rotation about X between Y-up and Z-up, then a uniform
scale), and :func:`frame_problems` reports a reference without it, or a
sublayer, which cannot be corrected at all. Every root prim of the scenery is
referenced (:func:`scenery_roots`); :func:`dropped_root_problems` reports a
reference that leaves some out of a file with no defaultPrim.
"""

from __future__ import annotations

import os

import numpy as np

from ..core.errors import StageError
from .stageio import StageFrame, correction, layer_frame


def scenery_roots(stage) -> list:
    """The root prims a scenery file shows (defined, active, not abstract), its default prim first.

    Parameters
    ----------
    stage : Usd.Stage
        The scenery file, opened.

    Returns
    -------
    list of Usd.Prim
    """
    roots = list(stage.GetPseudoRoot().GetChildren())     # the default predicate: what usdview shows
    default = stage.GetDefaultPrim()
    return sorted(roots, key=lambda prim: prim != default)     # stable: the others keep the file's order


def place_scenery(layer, scenery: str | os.PathLike, at: str, relative_to: str | os.PathLike) -> dict:
    """Reference every root prim of ``scenery`` under ``at`` in ``layer``, corrected to its frame.

    Parameters
    ----------
    layer : Sdf.Layer
        The scenario being written (its upAxis and metersPerUnit are the target).
    scenery : path-like
        A USD file from a DCC tool.
    at : str
        Prim path that will hold the scenery (defined here as an Xform).
    relative_to : path-like
        Folder of the file ``layer`` will be saved as (the reference is relative to it).

    Returns
    -------
    dict
        ``{"source": StageFrame, "scale": float, "rotate_x": float, "lights": bool, "roots": list of str}``
        (``roots``: the names of the referenced root prims, the default prim first).
    """
    from pxr import Gf, Sdf, Usd, UsdLux, Vt

    from .stageio import open_stage

    scenery = os.fspath(scenery)
    stage = open_stage(scenery)             # every layer it needs exists and is readable
    root_layer = stage.GetRootLayer()
    source = layer_frame(root_layer)
    target = layer_frame(layer)
    roots = scenery_roots(stage)
    if not roots:
        raise StageError("has no root prim to reference as scenery", file=scenery)
    m = correction(source, target)
    scale = float(np.cbrt(abs(np.linalg.det(m[:3, :3]))))
    rotate_x = 0.0 if source.up_axis == target.up_axis else (90.0 if source.up_axis == "Y" else -90.0)
    # The correction sits on a parent of the referencing prim: on the same prim its
    # xformOpOrder would replace the referenced root's own transform ops.
    spec = Sdf.CreatePrimInLayer(layer, at)
    spec.specifier, spec.typeName = Sdf.SpecifierDef, "Xform"
    _reference_roots(layer, at, os.path.relpath(os.path.abspath(scenery), os.path.abspath(relative_to)), roots,
                     stage.GetDefaultPrim())
    ops = []
    if rotate_x:
        a = Sdf.AttributeSpec(spec, "xformOp:rotateX", Sdf.ValueTypeNames.Float)
        a.default = rotate_x
        ops.append("xformOp:rotateX")
    if abs(scale - 1.0) > 1e-12:
        a = Sdf.AttributeSpec(spec, "xformOp:scale", Sdf.ValueTypeNames.Float3)
        a.default = Gf.Vec3f(scale, scale, scale)
        ops.append("xformOp:scale")
    if ops:
        a = Sdf.AttributeSpec(spec, "xformOpOrder", Sdf.ValueTypeNames.TokenArray, Sdf.VariabilityUniform)
        a.default = Vt.TokenArray(ops)
    lights = any(p.HasAPI(UsdLux.LightAPI) for root in roots for p in Usd.PrimRange(root))
    return {"source": source, "scale": scale, "rotate_x": rotate_x, "lights": lights,
            "roots": [root.GetName() for root in roots]}


def _reference_roots(layer, at: str, asset: str, roots: list, default) -> None:
    """One child of ``at`` per root prim of the scenery, each referencing it.

    References, not a sublayer: a sublayer's opinions apply as they are, so no transform can
    convert its units or axes (:func:`frame_problems`), and its roots would land at the
    scenario's root, merged with its own /World. Referenced under ``at``, every root gets the
    correction, and the scenario reader (obstacles) and the renderers find all of its meshes
    there. A layer without a defaultPrim offers no single prim to reference: each root is
    named by its path, or all but the first (say a kiosk beside the town) would vanish.
    Relationships from one root into another (a material binding to a /Looks root) are not
    mapped by references: such a file keeps geometry and obstacles, not those bindings.
    """
    from pxr import Sdf

    for root in roots:
        ref = Sdf.CreatePrimInLayer(layer, f"{at}/{root.GetName()}")
        ref.specifier = Sdf.SpecifierDef
        # The default prim as the layer declares it (a reference without a path follows it).
        path = Sdf.Path() if root == default else root.GetPath()
        ref.referenceList.prependedItems = [Sdf.Reference(asset, path)]


def frame_problems(stage) -> list[tuple[str, str, str]]:
    """(file, prim, message) for layers composed in other units or axes than the stage, uncorrected.

    A sublayer cannot be corrected (its opinions apply as they are); a
    reference can, by the referencing prim's transform, which must then be
    :func:`correction` (rotation and scale) of the two frames.
    """
    from pxr import UsdGeom

    target = layer_frame(stage.GetRootLayer())
    cache = UsdGeom.XformCache()
    out = []
    for layer in stage.GetLayerStack(includeSessionLayers=False)[1:]:
        f = layer_frame(layer)
        if _differs(f, target) and (layer.pseudoRoot.HasInfo("upAxis") or layer.pseudoRoot.HasInfo("metersPerUnit")):
            out.append((layer.identifier, "", f"sublayer in {_describe(f)} under a {_describe(target)} stage: "
                                              f"sublayers cannot be corrected; reference it from a prim instead"))
    for prim, spec, ref, ref_layer in _file_references(stage):
        f = layer_frame(ref_layer)
        if not _differs(f, target):
            continue
        # The correction sits above the referencing prim (on it, it would replace the referenced
        # root's own ops): its parent's world transform must hold it.
        parent = prim.GetParent()
        above = np.array(cache.GetLocalToWorldTransform(parent), dtype=np.float64)[:3, :3] \
            if parent and not parent.IsPseudoRoot() else np.eye(3)
        if not _converts(above, correction(f, target)[:3, :3], target):
            out.append((spec.layer.identifier, str(prim.GetPath()),
                        f"references {ref.assetPath} ({_describe(f)}) into a {_describe(target)} stage "
                        f"without the transform that converts it (usdcrowd new --scenery authors it)"))
    return out


def dropped_root_problems(stage) -> list[tuple[str, str, str]]:
    """(file, prim, message) for files without a defaultPrim of which the stage references only some roots.

    Such a file offers no single prim to reference: a scenery referenced by one
    root's path (a town) loses the others (a kiosk beside it), which then
    neither block walking nor are drawn. A file with a defaultPrim declares
    what it offers, so its other roots are not reported. One finding per file,
    at the first prim that references it.
    """
    found = {}      # layer identifier -> (layer, (file, prim, asset) of its first reference, root names brought)
    for prim, spec, ref, ref_layer in _file_references(stage):
        if ref_layer.defaultPrim:
            continue
        _, _, brought = found.setdefault(ref_layer.identifier, (
            ref_layer, (spec.layer.identifier, str(prim.GetPath()), ref.assetPath), set()))
        if not ref.primPath.isEmpty:
            brought.add(ref.primPath.GetPrefixes()[0].name)     # a part of a root (</Town/Hall>) counts as chosen
    out = []
    for ref_layer, (file, prim, asset), brought in found.values():
        dropped = [name for name in _root_names(ref_layer) if name not in brought]
        if dropped and brought:         # none brought: USD itself refuses the reference (no defaultPrim)
            out.append((file, prim, f"references {asset}, which has no defaultPrim, but not its root prim(s) "
                                    f"{', '.join('/' + name for name in dropped)}: they are not on this stage "
                                    f"(nothing blocks walking there, nothing is drawn); reference each root prim, "
                                    f"as usdcrowd new --scenery does"))
    return out


def _file_references(stage):
    """(prim, spec, reference, referenced layer) of every reference to another file on the stage's prims.

    References whose file cannot be opened are left out (composition reports them).
    """
    from pxr import Sdf

    for prim in stage.Traverse():
        if not prim.HasAuthoredReferences():
            continue
        for spec in prim.GetPrimStack():
            for ref in spec.referenceList.GetAddedOrExplicitItems():
                if not ref.assetPath:
                    continue
                ref_layer = Sdf.Layer.FindOrOpen(spec.layer.ComputeAbsolutePath(ref.assetPath))
                if ref_layer is not None:
                    yield prim, spec, ref, ref_layer


def _root_names(layer) -> list[str]:
    """Names of the root prims a file shows (:func:`scenery_roots`), its payloads left unloaded."""
    from pxr import Usd

    stage = Usd.Stage.Open(layer, Usd.Stage.LoadNone)       # held: its prims expire with it
    return [prim.GetName() for prim in scenery_roots(stage)]


def _converts(above: np.ndarray, conversion: np.ndarray, target: StageFrame) -> bool:
    """Whether ``above`` ((3, 3), row vectors) is ``conversion`` followed by a turn about the target's up axis
    (a shot placed and turned in a set, as ``usdcrowd place`` writes it)."""
    turn = np.linalg.solve(conversion, above)
    up = 2 if target.up_axis == "Z" else 1
    return (np.allclose(turn @ turn.T, np.eye(3), atol=1e-6)
            and np.allclose(turn[up], np.eye(3)[up], atol=1e-6))


def _differs(a: StageFrame, b: StageFrame) -> bool:
    return a.up_axis != b.up_axis or abs(a.meters_per_unit / b.meters_per_unit - 1.0) > 1e-6


def _describe(f: StageFrame) -> str:
    units = {1.0: "metres", 0.01: "centimetres", 0.001: "millimetres"}.get(round(f.meters_per_unit, 6),
                                                                         f"{f.meters_per_unit:g} m per unit")
    return f"{f.up_axis}-up {units}"
