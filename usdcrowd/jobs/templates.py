"""``usdcrowd new``: a scenario stage from one of the examples in stages/."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np

from .. import schema
from .. import guard
from ..atomic import atomic_path
from ..core.errors import UsdcrowdError
from ..core.resources import data_dir


def list_templates() -> list[str]:
    """Names of the example scenarios shipped in stages/."""
    return sorted(p.stem for p in data_dir("stages").glob("*.usda"))


def _split(total: int, weights: np.ndarray) -> np.ndarray:
    """Split ``total`` in proportion to ``weights`` (largest remainder), each >= 0."""
    if weights.sum() <= 0:
        weights = np.ones_like(weights, dtype=np.float64)
    exact = total * weights / weights.sum()
    out = np.floor(exact).astype(int)
    out[np.argsort(-(exact - out))[: total - out.sum()]] += 1
    return out


def _cast(stage):
    """A template stage's cast: its groups, authored agent count, clones per group ((g,) float64) and
    the groups ((g,) bool) that clone and have no agent of their own, so must keep at least one clone."""
    groups = [p for p in stage.Traverse() if p.GetTypeName() == schema.GROUP]
    n_authored = sum(1 for p in stage.Traverse() if schema.is_agent(p))
    clones = np.array([p.GetAttribute("crowd:clones").Get() or 0 for p in groups], dtype=np.float64)
    own = np.array([any(schema.is_agent(c) for c in p.GetChildren()) for p in groups], dtype=bool)
    return groups, n_authored, clones, (clones > 0) & ~own


def agent_range(template: str) -> tuple[int, int | None]:
    """(fewest, most) agents ``new_scenario`` can give a template (most None: no limit).

    A template whose groups clone nobody has a fixed cast: both are its size.
    """
    from pxr import Usd

    _, n_authored, clones, needs_one = _cast(Usd.Stage.Open(str(data_dir("stages") / f"{template}.usda")))
    if clones.sum() == 0:
        return n_authored, n_authored
    return n_authored + int(needs_one.sum()), None


def _resize(stage, agents: int, template: str) -> None:
    """Rescale the groups' clones so the scenario has ``agents`` agents in all.

    Groups keep their proportions; a group that had clones and no authored
    agent of its own keeps at least one, so no group is left empty.
    """
    groups, n_authored, clones, needs_one = _cast(stage)
    if clones.sum() == 0:
        if agents != n_authored:
            raise UsdcrowdError(f"template {template!r} has a fixed cast of {n_authored} agents; "
                                f"--agents cannot change it")
        return
    minimum = n_authored + int(needs_one.sum())
    if agents < minimum:
        raise UsdcrowdError(f"template {template!r} needs at least {minimum} agents "
                            f"(one per cloned group plus {n_authored} authored), got --agents {agents}")
    target = needs_one.astype(int) + _split(agents - minimum, clones)
    for prim, k in zip(groups, target):
        if k or prim.GetAttribute("crowd:clones").HasAuthoredValue():
            prim.GetAttribute("crowd:clones").Set(int(k))


def new_scenario(template: str, out: str | os.PathLike, agents: int | None = None, seed: int | None = None,
                 scenery: str | os.PathLike | None = None) -> dict:
    """Write a copy of a template, optionally resized to ``agents`` agents and reseeded.

    Image assets the template refers to (behavior maps) are copied next to
    the new stage so its relative asset paths keep working. With ``scenery``
    (a USD file from a DCC tool, any up axis and units) the template's own
    scenery is replaced by a reference to it at ``/World/Scenery``, with the
    transform its axes and units need (:func:`usdcrowd.scenario.scenery.place_scenery`),
    one child per root prim of the file; when it brings lights, the template's
    are dropped.

    Returns
    -------
    dict
        ``{"path", "agents", "seed", "assets", "scenery_roots"}`` (``scenery_roots``: names of the
        scenery's root prims referenced under ``/World/Scenery``, empty without ``scenery``).
    """
    from pxr import Sdf, Usd

    names = list_templates()
    if template not in names:
        raise UsdcrowdError(f"unknown template {template!r}; choose one of: {', '.join(names)}")
    if agents is not None and agents < 1:
        raise UsdcrowdError(f"--agents must be >= 1, got {agents}")
    src = data_dir("stages") / f"{template}.usda"
    out = Path(out)
    if out.suffix not in (".usda", ".usdc", ".usd"):
        raise UsdcrowdError("the output must end in .usda, .usdc or .usd", file=str(out))

    layer = Sdf.Layer.CreateAnonymous(out.suffix)
    layer.TransferContent(Sdf.Layer.FindOrOpen(str(src)))
    stage = Usd.Stage.Open(layer)
    if agents is not None:
        _resize(stage, agents, template)
    data = dict(layer.customLayerData)
    crowd = dict(data.get("usdcrowd", {}))
    if seed is not None:
        crowd["seed"] = int(seed)
    crowd["template"] = template
    data["usdcrowd"] = crowd
    layer.customLayerData = data
    schema.author_fallbacks(layer)          # readable without our schemas (Blender, plain usd-core)

    # Copy the image assets the template points at, keeping relative paths.
    assets = []
    for prim in stage.Traverse():
        for attr in prim.GetAttributes():
            if attr.GetTypeName() == Sdf.ValueTypeNames.Asset and attr.HasAuthoredValue():
                rel = attr.Get().path
                if rel and not os.path.isabs(rel):
                    source_file = src.parent / rel
                    if source_file.is_file():
                        assets.append((source_file, out.parent / rel))
    _, n_authored, clones, _ = _cast(stage)
    total = n_authored + int(clones.sum())
    roots = []
    if scenery is not None:
        del stage           # an open stage would try to compose the reference from an anonymous layer
        roots = replace_scenery(layer, scenery, out)
    with atomic_path(out) as tmp:
        if not layer.Export(str(tmp)):
            raise UsdcrowdError("could not be written", file=str(out))
        for source_file, dest in assets:
            if source_file.resolve() != dest.resolve():
                guard.check_write(dest)
                guard.make_dir(dest.parent)
                shutil.copyfile(source_file, dest)
                guard.wrote(dest)
    return {"path": str(out), "agents": total, "seed": crowd.get("seed"), "assets": [str(d) for _, d in assets],
            "scenery_roots": roots}


def replace_scenery(layer, scenery, out: Path) -> list[str]:
    """The DCC scenery in place of the template's (and its lights in place of the template's, if any).

    Returns the names of the scenery's root prims, each referenced under the template's Scenery.
    """
    from ..scenario.scenery import place_scenery

    root = f"/{layer.defaultPrim}" if layer.defaultPrim else "/World"
    parent = layer.GetPrimAtPath(root)
    if parent and "Scenery" in parent.nameChildren:
        del parent.nameChildren["Scenery"]
    placed = place_scenery(layer, scenery, f"{root}/Scenery", out.parent)
    if placed["lights"] and parent and "Lights" in parent.nameChildren:
        del parent.nameChildren["Lights"]
    return placed["roots"]
