"""The shot stage: a root layer that sublayers what was generated over what was authored.

::

    shot.usda       lights and settings added by usdcrowd (strongest)
      cameras.usda  camera trajectories (generated)
      crowd.usdc    agents' skeletons, animation, state (generated)
      scenario      the user's stage, referred to in place, never rewritten

Re-running the cameras rewrites only cameras.usda; a DCC tool's edits go in
shot.usda or a stronger layer of its own.
"""

from __future__ import annotations

import os

from .. import __version__, model, schema
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


def write_shot(out_dir: str | os.PathLike, scenario_path: str, time: model.TimeRange, frame: StageFrame,
               default_prim: str, seed: int, add_lights: bool) -> str:
    """Write shot.usda in ``out_dir``, sublayering cameras, crowd and scenario.

    Parameters
    ----------
    add_lights : bool
        Add a sun and a sky dome (UsdLux) because the scenario has no light.
    """
    from pxr import Gf, Sdf

    out_dir = os.fspath(out_dir)
    final = os.path.join(out_dir, SHOT)
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.subLayerPaths = [f"./{CAMERAS}", f"./{CROWD}", _relative(scenario_path, out_dir)]
    layer.defaultPrim = default_prim
    layer.startTimeCode, layer.endTimeCode = time.start, time.end
    layer.timeCodesPerSecond = layer.framesPerSecond = time.fps
    layer.pseudoRoot.SetInfo("upAxis", frame.up_axis)
    layer.pseudoRoot.SetInfo("metersPerUnit", frame.meters_per_unit)
    schema.author_fallbacks(layer)          # readable without our schemas (Blender, plain usd-core)
    layer.customLayerData = {"usdcrowd": {"version": __version__, "seed": int(seed),
                                          "scenario": _relative(scenario_path, out_dir),
                                          "scenarioFiles": scenario_files(scenario_path)}}
    if add_lights:
        root = f"/{default_prim}" if default_prim else ""
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
    return export_layer(layer, final)


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
