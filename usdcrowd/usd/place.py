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
from ..core.errors import StageError
from ..scenario.ranges import MAX_EXTENT

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
    path : str
        The stage written.
    prim : str
        The prim that places the shot (``<set's default prim>/<name>``).
    offset : int
        What the shot's agent ids were moved by (:func:`id_offset`; 0 when the set holds none of them).

    Raises
    ------
    StageError
        A shot or a set without a default prim, or --at too far from the origin.
    """
    from pxr import Gf, Sdf

    from ..scenario import open_stage, stage_frame
    from ..scenario.stageio import time_range
    from ..scenario.stageio import correction

    shot, into, out = os.fspath(shot), os.fspath(into), os.fspath(out)
    shot_stage, set_stage = open_stage(shot), open_stage(into)
    shot_root, parent = _roots(shot_stage, shot, set_stage, into)
    offset = id_offset(shot_stage, set_stage)
    name = name or _free_name(set_stage, parent, DEFAULT_NAME)
    if set_stage.GetPrimAtPath(parent.AppendChild(name)):
        raise StageError(f"the set already has a prim {name!r} here: give another --name", file=into,
                         prim=str(parent.AppendChild(name)))
    shot_frame, set_frame = stage_frame(shot_stage), stage_frame(set_stage)
    reach = float(np.abs(np.asarray(at, dtype=np.float64)).max()) * set_frame.meters_per_unit
    if reach > MAX_EXTENT:
        raise StageError(f"--at is {reach:.3g} m from the set's origin: a scene stays within "
                         f"{MAX_EXTENT / 1000:g} km of it", file=into, attribute="--at")
    time = _frames(time_range(shot_stage), set_stage)

    out_dir = os.path.dirname(os.path.abspath(out))
    layer = _layer_over(into, out_dir, parent.name, set_frame, time)
    with Sdf.ChangeBlock():
        spec, ref = _placement(layer, parent, name, shot_root.GetName(), at, rotate, set_frame.up_axis,
                               correction(shot_frame, set_frame))
        ref.referenceList.prependedItems = [Sdf.Reference(_relative(shot, out_dir), shot_root.GetPath())]
        lenses = convert_lenses(layer, shot_stage, shot_root.GetPath(), ref.path, set_frame)
        if offset:
            shift_ids(layer, shot_stage, shot_root.GetPath(), ref.path, offset)
    shot_time = time_range(shot_stage)
    layer.customLayerData = {"usdcrowd": {"placed": {"shot": _relative(shot, out_dir), "prim": str(ref.path),
                                                     "at": Gf.Vec3d(*map(float, at)), "rotate": float(rotate),
                                                     "frames": Gf.Vec2d(shot_time.start, shot_time.end),
                                                     "lensesConverted": lenses, "idOffset": offset}}}
    return export_layer(layer, out), str(spec.path), offset


def _layer_over(into: str, out_dir: str, default_prim: str, set_frame, time):
    """A new root layer over the set: its axes and units, the frames, the fallback prim types."""
    from pxr import Sdf

    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.subLayerPaths = [_relative(into, out_dir)]
    layer.defaultPrim = default_prim
    layer.pseudoRoot.SetInfo("upAxis", set_frame.up_axis)
    layer.pseudoRoot.SetInfo("metersPerUnit", set_frame.meters_per_unit)
    layer.startTimeCode, layer.endTimeCode = time.start, time.end
    layer.timeCodesPerSecond = layer.framesPerSecond = time.fps
    schema.author_fallbacks(layer)
    return layer


def _placement(layer, parent, name: str, child: str, at, rotate: float, up_axis: str, units: np.ndarray):
    """The placing Xform (``parent``/``name``: translate, turn about the up axis, units) and its child
    ``child`` that will hold the reference (ops on the referencing prim would replace the shot root's own).
    Inside the caller's change block; returns both prim specs."""
    from pxr import Gf, Sdf, Vt

    T = Sdf.ValueTypeNames
    for p in parent.GetPrefixes():
        Sdf.CreatePrimInLayer(layer, p).specifier = Sdf.SpecifierOver
    spec = Sdf.CreatePrimInLayer(layer, parent.AppendChild(name))
    spec.specifier, spec.typeName = Sdf.SpecifierDef, "Xform"
    up = "rotateZ" if up_axis == "Z" else "rotateY"
    for op, type_name, value in (("xformOp:translate", T.Double3, Gf.Vec3d(*map(float, at))),
                                 (f"xformOp:{up}", T.Double, float(rotate)),
                                 ("xformOp:transform:units", T.Matrix4d, Gf.Matrix4d(units.tolist()))):
        Sdf.AttributeSpec(spec, op, type_name).default = value
    order = Sdf.AttributeSpec(spec, "xformOpOrder", T.TokenArray, Sdf.VariabilityUniform)
    order.default = Vt.TokenArray(["xformOp:translate", f"xformOp:{up}", "xformOp:transform:units"])
    ref = Sdf.CreatePrimInLayer(layer, spec.path.AppendChild(child))
    ref.specifier = Sdf.SpecifierDef
    return spec, ref


def _roots(shot_stage, shot: str, set_stage, into: str):
    """The shot's default prim and the set's (where the shot goes).

    Raises
    ------
    StageError
        Either has no default prim, or names one that is not there.
    """
    for stage, path, what in ((shot_stage, shot, "a shot is placed by its default prim"),
                              (set_stage, into, "the shot goes under the set's default prim")):
        named = stage.GetRootLayer().defaultPrim
        if not named:
            raise StageError(f"has no defaultPrim: {what} (set one in its root layer)", file=path,
                             attribute="defaultPrim")
        if not stage.GetDefaultPrim():
            raise StageError(f"its defaultPrim {named!r} is not on the stage", file=path, attribute="defaultPrim")
    return shot_stage.GetDefaultPrim(), set_stage.GetDefaultPrim().GetPath()


def id_offset(shot_stage, set_stage) -> int:
    """How far the shot's agent ids must move so that none is one the set already holds (0 when none
    is): the next thousand above the set's highest id. Two characters with one id would share a track
    in the ground truth (the same shot placed twice, or two shots both numbered from 100)."""
    from ..schema import agent_prims

    have = {i for _, i in agent_prims(set_stage)} - {None, -1}
    mine = {i for _, i in agent_prims(shot_stage)} - {None, -1}
    if not have & mine:
        return 0
    return 1000 * (max(have) // 1000 + 1) - 1000 * (min(mine) // 1000)


def shift_ids(layer, shot_stage, shot_root, placed_root, offset: int) -> None:
    """Author, over the placed shot, every agent id moved by ``offset`` (the schema's and Blender's
    custom property) and every event's time-sampled member ids with them."""
    from pxr import Sdf, Vt

    from ..schema import EVENT, USER_PROPERTIES, agent_prims

    def over(prim, name, value_of):
        attr = prim.GetAttribute(name)
        if not attr or not attr.HasAuthoredValue():
            return
        target = Sdf.Path(str(prim.GetPath()).replace(str(shot_root), str(placed_root), 1))
        spec = Sdf.AttributeSpec(Sdf.CreatePrimInLayer(layer, target), name, attr.GetTypeName(),
                                 attr.GetVariability(), attr.IsCustom())
        for t in attr.GetTimeSamples():
            layer.SetTimeSample(spec.path, t, value_of(attr.Get(t)))
        if not attr.GetTimeSamples():
            spec.default = value_of(attr.Get())

    for prim, _ in agent_prims(shot_stage):
        for name in ("crowd:agentId", f"{USER_PROPERTIES}agentId"):
            over(prim, name, lambda v: int(v) + offset)
    for prim in shot_stage.Traverse():
        if prim.GetTypeName() == EVENT:
            over(prim, "crowd:memberIds", lambda v: Vt.IntArray([int(i) + offset for i in (v or [])]))


def _frames(shot_time, set_stage):
    """The shot's frames, widened to the set's own when it has some (a set holding another shot)."""
    from ..core import model
    from ..scenario.stageio import time_range

    if not set_stage.GetRootLayer().HasStartTimeCode():
        return shot_time
    own = time_range(set_stage)
    return model.TimeRange(min(own.start, shot_time.start), max(own.end, shot_time.end), shot_time.fps)


# Camera attributes in scene units (lens values in tenths of one, USD's convention).
LENS_ATTRIBUTES = ("focalLength", "horizontalAperture", "verticalAperture", "horizontalApertureOffset",
                   "verticalApertureOffset", "clippingRange", "focusDistance")


def convert_lenses(layer, shot_stage, shot_root, placed_root, set_frame) -> int:
    """Author the lens of every camera of the shot in the set's units, under ``placed_root`` in ``layer``.

    USD reads a camera's lens and clipping range in the units of the stage that composes it, and a
    reference does not convert them: a metre shot's 35 mm lens (0.35) would be a 0.35 mm one in a
    centimetre set, for Blender, usd-core and a flattened file. Only needed when the units differ.

    Returns
    -------
    int
        Cameras converted.
    """
    from pxr import Gf, Sdf, UsdGeom

    from ..scenario import stage_frame
    from ..scenario.stageio import lens_scale

    frame = stage_frame(shot_stage)
    n = 0
    for prim in shot_stage.Traverse():
        if not prim.IsA(UsdGeom.Camera) or not prim.GetPath().HasPrefix(shot_root):
            continue
        target = Sdf.Path(str(prim.GetPath()).replace(str(shot_root), str(placed_root), 1))
        converted = False
        for name in LENS_ATTRIBUTES:
            attr = prim.GetAttribute(name)
            if not attr or not attr.HasAuthoredValue():
                continue
            times = attr.GetTimeSamples() or [None]
            values = []
            for t in times:
                ratio = lens_scale(attr, t if t is not None else 0.0, frame, set_frame.meters_per_unit)
                v = attr.Get(t) if t is not None else attr.Get()
                values.append((t, Gf.Vec2f(v[0] * ratio, v[1] * ratio) if name == "clippingRange" else v * ratio,
                               ratio))
            if all(r == 1.0 for _, _, r in values):
                continue
            spec = Sdf.CreatePrimInLayer(layer, target)
            over = Sdf.AttributeSpec(spec, name, attr.GetTypeName())
            for t, v, _ in values:
                if t is None:
                    over.default = v
                else:
                    layer.SetTimeSample(over.path, t, v)
            converted = True
        n += converted
    return n


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
    from ..scenario.stageio import correction

    c, s = np.cos(np.radians(rotate)), np.sin(np.radians(rotate))
    r = np.eye(4)
    if set_frame.up_axis == "Z":
        r[:2, :2] = [[c, s], [-s, c]]
    else:                                   # about Y, counter-clockwise seen from +Y
        r[0, 0], r[0, 2], r[2, 0], r[2, 2] = c, -s, s, c
    t = np.eye(4)
    t[3, :3] = at
    return correction(shot_frame, set_frame) @ r @ t
