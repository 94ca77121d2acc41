"""The shot stage: a root layer that sublayers what was generated over what was authored.

::

    shot.usda       the user's layer (strongest): edits go here; usdcrowd adds
                    the frames, units and lights when the scenario has none
      cameras.usda  camera trajectories (generated)
      crowd.usdc    agents' skeletons, animation, state (generated)
      scenario      the user's stage, referred to in place, never rewritten

Re-running the cameras rewrites only cameras.usda; re-running the simulation
rewrites the generated layers and updates shot.usda without losing an
opinion in it (see :func:`write_shot`).
"""

from __future__ import annotations

import os

from .. import __version__, schema
from ..core import model
from ..atomic import export_layer
from ..scenario.stageio import StageFrame
from .cameras import CAMERAS

SHOT = "shot.usda"
CROWD = "crowd.usdc"


def _relative(target: str, start_dir: str) -> str:
    rel = os.path.relpath(os.path.abspath(target), os.path.abspath(start_dir))
    return rel if rel.startswith(".") else f"./{rel}"


def scenario_files(scenario_path: str | os.PathLike, known: dict | None = None) -> dict[str, str]:
    """What a shot was simulated from: ``{path relative to the scenario: "size:mtime_ns:sha256"}`` for the
    scenario and every file it uses (sublayers, references, scenery, images).

    A file whose size and mtime match its entry in ``known`` is not read again (scenery can be large).
    """
    from ..atomic import file_sha256
    from ..guard import files_used

    scenario_path = os.path.abspath(scenario_path)
    folder = os.path.dirname(scenario_path)
    known = known or {}
    files = {}
    for path in [scenario_path, *files_used(scenario_path)]:
        st = os.stat(path)
        rel = os.path.relpath(path, folder)
        before = str(known.get(rel, "")).split(":")
        if len(before) == 3 and before[:2] == [str(st.st_size), str(st.st_mtime_ns)]:
            files[rel] = known[rel]
        else:
            files[rel] = f"{st.st_size}:{st.st_mtime_ns}:{file_sha256(path)}"
    return files


def stale_scenario(shot_path: str | os.PathLike) -> str | None:
    """Why ``shot_path``'s scenario no longer is what the shot was simulated from, or None (also for
    stages that are not shots, or shots written before the files were recorded)."""
    from pxr import Sdf

    try:
        layer = Sdf.Layer.FindOrOpen(os.fspath(shot_path))
    except Exception:
        return None
    data = layer.customLayerData.get("usdcrowd") if layer is not None else None
    if not isinstance(data, dict) or not isinstance(data.get("scenarioFiles"), dict):
        return None
    recorded = {str(k): str(v) for k, v in data["scenarioFiles"].items()}
    scenario = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(shot_path)), str(data.get("scenario"))))
    try:
        now = scenario_files(scenario, recorded)
    except OSError:
        return None                         # a missing scenario is the readers' own error
    sha = {k: v.rsplit(":", 1)[-1] for k, v in now.items()}
    if sha == {k: v.rsplit(":", 1)[-1] for k, v in recorded.items()}:
        return None
    changed = sorted(k for k in sha.keys() | recorded.keys() if sha.get(k) != recorded.get(k, "").rsplit(":", 1)[-1])
    return (f"its scenario {data.get('scenario')} changed since the shot was simulated ({', '.join(changed[:3])}): "
            "the shot shows the old one; run simulate again")


def is_shot_layer(layer) -> bool:
    """Whether ``layer`` is a shot's root layer (``usdcrowd simulate`` wrote it: it names its scenario)."""
    data = layer.customLayerData.get("usdcrowd") if layer is not None else None
    # The crowd layer names its scenario too, beside the generator that wrote it.
    return isinstance(data, dict) and bool(data.get("scenario")) and "generator" not in data


def find_shot(path: str | os.PathLike) -> str:
    """The shot a stage is, or the one shot it uses (sublayered under a layer that moves or edits it,
    or referenced into a set): commands that rewrite a shot's generated layers work on it, in its own
    space, and what they write moves with it wherever it is placed.

    Raises
    ------
    StageError
        The stage is not a shot and uses none, or uses several.
    """
    from ..core.errors import StageError
    from ..scenario import open_stage

    path = os.fspath(path)
    if earlier_shot(path) is not None:      # its root layer alone says so: the caller composes the shot once
        return path
    stage = open_stage(path)                # its checks first: a FIFO or a device is refused, not read
    shots = sorted({layer.realPath for layer in stage.GetUsedLayers() if layer.realPath and is_shot_layer(layer)})
    if len(shots) == 1:
        return shots[0]
    raise StageError("not a usdcrowd shot: customLayerData has no usdcrowd.scenario" + (
        f", and it uses {len(shots)} shots ({', '.join(shots[:3])}): name the one to work on" if shots else
        ", and it uses no shot"), file=path)


def earlier_shot(path: str | os.PathLike):
    """The shot layer at ``path`` as an anonymous copy (never the registry's cached one), or None when
    there is none or it is not a shot's."""
    from pxr import Sdf

    path = os.fspath(path)
    if not os.path.isfile(path):
        return None
    try:
        layer = Sdf.Layer.OpenAsAnonymous(path)
    except Exception:                       # unreadable: not ours to merge into (the guard decides)
        return None
    return layer if is_shot_layer(layer) else None


def write_shot(out_dir: str | os.PathLike, scenario_path: str, time: model.TimeRange, frame: StageFrame,
               default_prim: str, seed: int, add_lights: bool) -> str:
    """Write shot.usda in ``out_dir``, sublayering cameras, crowd and scenario.

    An earlier shot's shot.usda is the user's layer: it is updated, not replaced. Only what usdcrowd owns
    changes (the generated sublayers and the scenario among its sublayers, the frames, axes, units,
    fallback types and customLayerData["usdcrowd"]); every prim and opinion in it, the user's own
    sublayers and other metadata stay. When nothing of usdcrowd's changed, the file is not touched.

    Parameters
    ----------
    add_lights : bool
        Add a sun and a sky dome (UsdLux) because the scenario has no light (unless the layer has them).
    """
    from pxr import Sdf

    out_dir = os.fspath(out_dir)
    final = os.path.join(out_dir, SHOT)
    layer = earlier_shot(final)
    before = layer.ExportToString() if layer is not None else None
    if layer is None:
        layer = Sdf.Layer.CreateAnonymous(".usda")
    scenario_ref = _relative(scenario_path, out_dir)
    layer.subLayerPaths = _sublayers(layer, scenario_ref)
    layer.defaultPrim = default_prim
    layer.startTimeCode, layer.endTimeCode = time.start, time.end
    layer.timeCodesPerSecond = layer.framesPerSecond = time.fps
    layer.pseudoRoot.SetInfo("upAxis", frame.up_axis)
    layer.pseudoRoot.SetInfo("metersPerUnit", frame.meters_per_unit)
    schema.author_fallbacks(layer)          # readable without our schemas (Blender, plain usd-core)
    layer.customLayerData = {**dict(layer.customLayerData),
                             "usdcrowd": {"version": __version__, "seed": int(seed), "scenario": scenario_ref,
                                          "scenarioFiles": scenario_files(scenario_path)}}
    root = f"/{default_prim}" if default_prim else ""
    if add_lights and not layer.GetPrimAtPath(f"{root}/Lights"):
        _add_lights(layer, root, frame)
    if before is not None and layer.ExportToString() == before:
        return final
    if before is not None:
        _keep_previous_text(final)
    return export_layer(layer, final)


def _keep_previous_text(final: str) -> None:
    """USD writes a layer's opinions, not its comments or hand formatting: the text as it was is kept
    beside the shot's record before it is updated (the latest one: never an older edit)."""
    from ..guard import STATE_DIR

    with open(final, encoding="utf-8", errors="replace") as f:
        text = f.read()
    # In the folder's own state directory (not an output the guard records), replaced atomically.
    folder = os.path.join(os.path.dirname(final), STATE_DIR)
    os.makedirs(folder, exist_ok=True)
    keep = os.path.join(folder, f"{SHOT}.previous")
    with open(keep + ".partial", "w", encoding="utf-8") as f:
        f.write(text)
    os.replace(keep + ".partial", keep)


def _sublayers(layer, scenario_ref: str) -> list[str]:
    """The generated layers and the scenario (replacing the one an earlier run named), and the user's own
    sublayers where they put them."""
    old = layer.customLayerData.get("usdcrowd", {}).get("scenario") if layer.subLayerPaths else None
    paths = [scenario_ref if p == old else p for p in layer.subLayerPaths]
    for p in (f"./{CAMERAS}", f"./{CROWD}", scenario_ref):
        if p not in paths:
            paths.append(p)
    return paths


def _add_lights(layer, root: str, frame: StageFrame) -> None:
    """A sun and a sky dome under ``root``/Lights."""
    from pxr import Gf, Sdf

    with Sdf.ChangeBlock():
        _define_scope(layer, f"{root}/Lights")
        sun = Sdf.CreatePrimInLayer(layer, f"{root}/Lights/Sun")
        sun.specifier, sun.typeName = Sdf.SpecifierDef, "DistantLight"
        _set(sun, "inputs:intensity", Sdf.ValueTypeNames.Float, 3.0)
        _set(sun, "inputs:angle", Sdf.ValueTypeNames.Float, 0.53)
        # UsdLux: normalised, the intensity is the illuminance, not the 0.53-degree disc's luminance
        _set(sun, "inputs:normalize", Sdf.ValueTypeNames.Bool, True)
        _set(sun, "inputs:color", Sdf.ValueTypeNames.Color3f, Gf.Vec3f(1.0, 0.96, 0.9))
        rot = (40.0, 0.0, 30.0) if frame.up_axis == "Z" else (-50.0, 30.0, 0.0)
        _set(sun, "xformOp:rotateXYZ", Sdf.ValueTypeNames.Float3, Gf.Vec3f(*rot))
        _set(sun, "xformOpOrder", Sdf.ValueTypeNames.TokenArray, ["xformOp:rotateXYZ"], uniform=True)
        sky = Sdf.CreatePrimInLayer(layer, f"{root}/Lights/Sky")
        sky.specifier, sky.typeName = Sdf.SpecifierDef, "DomeLight"
        _set(sky, "inputs:intensity", Sdf.ValueTypeNames.Float, 0.6)
        _set(sky, "inputs:color", Sdf.ValueTypeNames.Color3f, Gf.Vec3f(0.75, 0.85, 1.0))


def _define_scope(layer, path: str) -> None:
    """A typeless ``def`` at ``path``: defined (so its children are traversed)
    without overriding the type the scenario may give it."""
    from pxr import Sdf

    Sdf.CreatePrimInLayer(layer, path).specifier = Sdf.SpecifierDef


def _set(spec, name, type_name, value, uniform=False):
    from pxr import Sdf

    attr = Sdf.AttributeSpec(spec, name, type_name, Sdf.VariabilityUniform if uniform else Sdf.VariabilityVarying)
    attr.default = value
    return attr
