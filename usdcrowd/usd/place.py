"""Place a shot in a set: a new root layer over the set that references the shot.

::

    out.usda        the placement (strongest), written here
      SET.usda      sublayered as it is, never rewritten
    /<set's default prim>/<name>    an Xform placing the shot:
        xformOp:translate           --at, in the set's units and axes
        xformOp:rotate<up axis>     --rotate, degrees about the set's up axis
        xformOp:transform:units     the shot's axes and units into the set's (constant)
      /<shot's default prim>        references SHOT's default prim (on a child, so the
                                    shot root keeps its own transform ops)

The placement is what a layout artist would author by hand: the ops stay
editable in any DCC tool, and because usdcrowd authors a shot's crowd,
cameras and events in their parent's space, the whole shot follows them. The
root layer takes the shot's frames and frame rate (USD reads them only from the
root layer) and the fallback prim types that tools without usdcrowd's schemas
need to keep the crowd's groups (Blender drops a typed prim it does not know,
and with it the agents' parent).
"""

from __future__ import annotations

import os

import numpy as np

from .. import schema
from ..atomic import export_layer

# The shot's prim in the set takes this name unless one is given.
DEFAULT_NAME = "Shot"


def place_shot(shot: str | os.PathLike, into: str | os.PathLike, out: str | os.PathLike, at=(0.0, 0.0, 0.0),
               rotate: float = 0.0, name: str | None = None) -> str:
    """Write ``out``: the set ``into`` with the shot ``shot`` referenced under its default prim.

    Parameters
    ----------
    at : (3,) float
        Where the shot's origin goes, in the set's units and axes.
    rotate : float
        Degrees about the set's up axis, counter-clockwise seen from above.
    name : str, optional
        The placed prim's name (default :data:`DEFAULT_NAME`, numbered when the set has one).

    Returns
    -------
    str
        The path written.

    Raises
    ------
    StageError
        A shot without a default prim, or a set whose default prim is missing.
    """
    from pxr import Gf, Sdf, Vt

    from ..errors import StageError
    from ..scenario import open_stage, stage_frame
    from ..scenario.stageio import time_range
    from ..scenery import correction

    shot, into, out = os.fspath(shot), os.fspath(into), os.fspath(out)
    shot_stage, set_stage = open_stage(shot), open_stage(into)
    shot_root = shot_stage.GetDefaultPrim()
    if not shot_root:
        raise StageError("has no defaultPrim: a shot is placed by its default prim", file=shot,
                         attribute="defaultPrim")
    set_root = set_stage.GetDefaultPrim()
    if set_stage.GetRootLayer().defaultPrim and not set_root:
        raise StageError(f"its defaultPrim {set_stage.GetRootLayer().defaultPrim!r} is not on the stage", file=into,
                         attribute="defaultPrim")
    parent = set_root.GetPath() if set_root else Sdf.Path.absoluteRootPath
    name = name or _free_name(set_stage, parent, DEFAULT_NAME)
    if set_stage.GetPrimAtPath(parent.AppendChild(name)):
        raise StageError(f"the set already has a prim {name!r} here: give another --name", file=into,
                         prim=str(parent.AppendChild(name)))
    shot_frame, set_frame = stage_frame(shot_stage), stage_frame(set_stage)
    time = time_range(shot_stage)

    out_dir = os.path.dirname(os.path.abspath(out))
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.subLayerPaths = [_relative(into, out_dir)]
    if set_root:
        layer.defaultPrim = set_root.GetName()
    layer.pseudoRoot.SetInfo("upAxis", set_frame.up_axis)
    layer.pseudoRoot.SetInfo("metersPerUnit", set_frame.meters_per_unit)
    layer.startTimeCode, layer.endTimeCode = time.start, time.end
    layer.timeCodesPerSecond = layer.framesPerSecond = time.fps
    schema.author_fallbacks(layer)
    T = Sdf.ValueTypeNames
    with Sdf.ChangeBlock():
        for p in (parent.GetPrefixes() if parent != Sdf.Path.absoluteRootPath else []):
            Sdf.CreatePrimInLayer(layer, p).specifier = Sdf.SpecifierOver
        spec = Sdf.CreatePrimInLayer(layer, parent.AppendChild(name))
        spec.specifier, spec.typeName = Sdf.SpecifierDef, "Xform"
        # The reference goes on a child: ops on the referencing prim would replace the shot root's own.
        ref = Sdf.CreatePrimInLayer(layer, spec.path.AppendChild(shot_root.GetName()))
        ref.specifier = Sdf.SpecifierDef
        ref.referenceList.prependedItems = [Sdf.Reference(_relative(shot, out_dir), shot_root.GetPath())]
        up = "rotateZ" if set_frame.up_axis == "Z" else "rotateY"
        for op, type_name, value in (
                ("xformOp:translate", T.Double3, Gf.Vec3d(*map(float, at))),
                (f"xformOp:{up}", T.Double, float(rotate)),
                ("xformOp:transform:units", T.Matrix4d, Gf.Matrix4d(correction(shot_frame, set_frame).tolist()))):
            Sdf.AttributeSpec(spec, op, type_name).default = value
        order = Sdf.AttributeSpec(spec, "xformOpOrder", T.TokenArray, Sdf.VariabilityUniform)
        order.default = Vt.TokenArray(["xformOp:translate", f"xformOp:{up}", "xformOp:transform:units"])
    layer.customLayerData = {"usdcrowd": {"placed": {"shot": _relative(shot, out_dir), "prim": str(ref.path),
                                                     "at": Gf.Vec3d(*map(float, at)), "rotate": float(rotate)}}}
    return export_layer(layer, out)


def _free_name(stage, parent, base: str) -> str:
    """``base``, or ``base_2``, ``base_3``... the first name not taken under ``parent``."""
    k, name = 1, base
    while stage.GetPrimAtPath(parent.AppendChild(name)):
        k += 1
        name = f"{base}_{k}"
    return name


def _relative(target: str, start_dir: str) -> str:
    rel = os.path.relpath(os.path.abspath(target), start_dir)
    return rel if rel.startswith(".") else f"./{rel}"


def placement_matrix(shot_frame, set_frame, at=(0.0, 0.0, 0.0), rotate: float = 0.0) -> np.ndarray:
    """(4, 4) float64: shot stage units to set stage units, as :func:`place_shot` composes its ops."""
    from ..scenery import correction

    c, s = np.cos(np.radians(rotate)), np.sin(np.radians(rotate))
    r = np.eye(4)
    if set_frame.up_axis == "Z":
        r[:2, :2] = [[c, s], [-s, c]]
    else:                                   # about Y, counter-clockwise seen from +Y
        r[0, 0], r[0, 2], r[2, 0], r[2, 2] = c, -s, s, c
    t = np.eye(4)
    t[3, :3] = at
    return correction(shot_frame, set_frame) @ r @ t
