"""A shot stage as renderers see it, frame by frame, in canonical units.

Both renderers (the Mitsuba final path and the OpenGL preview) and the
ground-truth exporters read the stage through :class:`ShotScene`, so they
agree on every vertex, light and lens. Everything returned is numpy, in Z-up
metres (the stage's upAxis and metersPerUnit are undone here), with USD's
row-vector matrix convention (``p' = p @ M``).

Static things (scenery meshes, materials, lights, the shared body) are read
once; what moves (agents' skeletons, animated scenery, cameras) is read per
time code.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..character import rig
from ..core.geometry import MeshData, mesh_of
# The shared types live in the pure core; imported here for renderers and old imports.
from ..character.poses import AgentPoses
from ..core.shading import SCENERY_ID_BASE, Light, Material, distant_illuminance
from .stageio import unpacked
from .stageio import camera_frame, camera_lens
from ..core.view import CameraView

__all__ = ["SCENERY_ID_BASE", "AgentPoses", "CameraView", "Light", "Material", "SceneryItem", "ShotScene",
           "color_temperature_rgb"]


@dataclass
class SceneryItem:
    """One piece of static or animated scenery."""

    path: str
    shape_id: int
    mesh: MeshData
    material: Material
    animated: bool
    _prim: object = field(repr=False, default=None)
    _scene: object = field(repr=False, default=None)

    def local_to_world(self, time) -> np.ndarray:
        """(4, 4) mesh space to canonical world at ``time``."""
        return self._scene._world(self._prim, time)


class ShotScene:
    """Read a shot stage for rendering.

    Parameters
    ----------
    path : path-like
        The shot (or any) stage.
    stage : Usd.Stage, optional
        Already opened.
    """

    def __init__(self, path: str | os.PathLike, stage=None):
        from . import open_stage, stage_frame
        from .stageio import time_range

        self.path = os.fspath(path)
        self.stage = stage or open_stage(self.path)
        self.frame = stage_frame(self.stage)
        self._to_canonical = self.frame.to_canonical
        self._xf_caches: dict[float, object] = {}
        # The root layer's frames, or the shot's under a layer that moves or edits it.
        time = time_range(self.stage) if self._has_time_range() else None
        self.time_codes = time.codes if time is not None else np.arange(self.stage.GetStartTimeCode(),
                                                                         self.stage.GetEndTimeCode() + 0.5)
        self.fps = self.stage.GetTimeCodesPerSecond()
        self._scan()

    def _has_time_range(self) -> bool:
        """Whether the root layer or a sublayer of it authors the frames (else USD's 0-0 stands)."""
        return any(layer.HasStartTimeCode() and layer.HasEndTimeCode()
                   for layer in self.stage.GetLayerStack(includeSessionLayers=False))

    # ------------------------------------------------------------- traversal
    def _scan(self) -> None:
        from pxr import Usd, UsdGeom, UsdLux

        from .. import schema

        self._agent_prims, self._scenery_prims, self._light_prims, self._camera_prims = [], [], [], []
        it = iter(Usd.PrimRange(self.stage.GetPseudoRoot(), Usd.TraverseInstanceProxies()))
        for prim in it:
            if prim.IsA(UsdGeom.Imageable) and UsdGeom.Imageable(prim).GetPurposeAttr().Get() in ("guide", "proxy"):
                it.PruneChildren()
                continue
            if schema.agent_id(prim) is not None:
                self._agent_prims.append(prim)
                it.PruneChildren()
            elif prim.IsA(UsdGeom.Camera):
                self._camera_prims.append(prim)
            elif prim.HasAPI(UsdLux.LightAPI):
                self._light_prims.append(prim)
            elif prim.IsA(UsdGeom.Gprim):
                self._scenery_prims.append(prim)

    def _xf(self, time):
        from pxr import Usd, UsdGeom

        key = float(time)
        cache = self._xf_caches.get(key)
        if cache is None:
            if len(self._xf_caches) > 8:
                self._xf_caches.clear()
            cache = self._xf_caches[key] = UsdGeom.XformCache(Usd.TimeCode(key))
        return cache

    def _world(self, prim, time) -> np.ndarray:
        """(4, 4) prim-to-canonical-world at ``time``."""
        m = np.array(self._xf(time).GetLocalToWorldTransform(prim), dtype=np.float64)
        return m @ self._to_canonical

    def check_times(self, times) -> None:
        """Refuse time codes outside the shot's range (a ``--frames`` typo would render held poses).

        Raises
        ------
        StageError
        """
        from ..core.errors import StageError

        times = np.asarray(times, dtype=np.float64)
        if len(self.time_codes) == 0 or len(times) == 0:
            return
        lo, hi = float(self.time_codes[0]), float(self.time_codes[-1])
        outside = times[(times < lo - 1e-6) | (times > hi + 1e-6)]
        if len(outside):
            raise StageError(f"frame {outside[0]:g} is outside the shot's frames {lo:g}-{hi:g}", file=self.path,
                             attribute="--frames")

    # --------------------------------------------------------------- cameras
    @property
    def camera_paths(self) -> list[str]:
        return [str(p.GetPath()) for p in self._camera_prims]

    def camera(self, path: str | None, time) -> CameraView:
        """The camera at ``path`` (default: the first one) at ``time``.

        Raises
        ------
        StageError
            If the stage has no camera, or ``path`` is not a camera.
        """
        from pxr import UsdGeom

        from ..core.errors import StageError

        if path is None:
            if not self._camera_prims:
                raise StageError("the stage has no camera", file=self.path)
            prim = self._camera_prims[0]
        else:
            prim = self.stage.GetPrimAtPath(path)
            if not prim or not prim.IsA(UsdGeom.Camera):
                found = ", ".join(self.camera_paths) or "none"
                raise StageError(f"not a camera (cameras: {found})", file=self.path, prim=path)
        cam = UsdGeom.Camera(prim)
        m = camera_frame(self._xf(time).GetLocalToWorldTransform(prim), self.frame)
        # In the units of the layers that authored them (a camera referenced from a centimetre file).
        focal, h_ap, v_ap, near, far = camera_lens(cam, time, self.frame)
        _check_lens(prim, time, focal=focal, horizontalAperture=h_ap, verticalAperture=v_ap,
                    near=float(near), far=float(far), matrix=m)
        state = prim.GetAttribute("crowd:camera:state")
        tracked = prim.GetAttribute("crowd:camera:trackedEvent")
        f_stop, focus = _lens_focus(cam, time, self.frame)
        return CameraView(str(prim.GetPath()), float(time), m, focal, h_ap, v_ap, near, far,
                          str(state.Get(time)) if state and state.HasValue() else None,
                          str(tracked.Get(time) or "") if tracked and tracked.HasValue() else None,
                          _toric_of(prim, time), f_stop, focus, _cut_of(prim, time))

    # --------------------------------------------------------------- scenery
    @cached_property
    def scenery(self) -> list[SceneryItem]:
        """Every gprim that is not part of an agent, with its material."""
        from pxr import UsdGeom

        items = []
        for k, prim in enumerate(self._scenery_prims):
            mesh = mesh_of(prim)
            if mesh is None or len(mesh.faces) == 0:
                continue
            xf = UsdGeom.Xformable(prim)
            animated = bool(xf.TransformMightBeTimeVarying()) or _ancestors_animated(prim)
            items.append(SceneryItem(str(prim.GetPath()), SCENERY_ID_BASE + k, mesh, _material_of(prim),
                                     animated, prim, self))
        return items

    # ---------------------------------------------------------------- lights
    @cached_property
    def lights(self) -> list[Light]:
        """The stage's UsdLux lights (read at the start time; lights are static here)."""
        t = self.stage.GetStartTimeCode()
        return [light for light in (_light_of(p, self._world(p, t), self.frame.meters_per_unit, self.frame.up_axis)
                                    for p in self._light_prims) if light is not None]

    # ---------------------------------------------------------------- agents
    @cached_property
    def body(self):
        """The shared skinned body (points, faces, joint indices and weights) read from the stage."""
        from ..character.body import build_body

        for agent in self._agent_rigs:
            body = _read_body(agent) if agent.body is not None else None
            if body is not None:
                if self._vertex_colours is not None:        # colours flattened per vertex by a DCC tool
                    body.regions = self._vertex_colours[0]
                return body
        b = build_body()
        # No body on the stage, so no palettes either: one colour per agent.
        return _Body(b.points, b.face_vertex_indices.reshape(-1, 3), b.joint_indices, b.joint_weights,
                     np.zeros(len(b.points), np.int32), None)

    @cached_property
    def _agent_rigs(self) -> list[_AgentRig]:
        """Where each animated agent's pose and body live (agents without an animation are not drawn)."""
        return [r for r in (_rig_of(prim) for prim in self._agent_prims) if r is not None]

    @cached_property
    def _vertex_colours(self):
        """(regions, palettes) when the bodies' colours come one per vertex, else None.

        usdcrowd authors a body's colours as an indexed primvar: one colour per
        region of the palette (:mod:`usdcrowd.character.appearance`). A DCC tool
        exports them flattened, one per vertex: the regions are found again as
        the vertices that share their colour on every agent.
        """
        first = next((a.body for a in self._agent_rigs if a.body is not None), None)
        flat = _flat_colours(first) if first is not None else None
        if flat is None:
            return None
        n_points = len(flat)
        colours = np.stack([_colours_per_vertex(a, n_points) for a in self._agent_rigs])   # (n, v, 3)
        flat = np.ascontiguousarray(colours.transpose(1, 0, 2).reshape(n_points, -1))
        _, firsts, regions = np.unique(flat, axis=0, return_index=True, return_inverse=True)
        rows = _region_order(regions.reshape(-1))
        return np.argsort(rows)[regions.reshape(-1)].astype(np.int32), colours[:, firsts[rows]]

    @cached_property
    def _agent_static(self):
        from .. import schema

        rows = int(self.body.regions.max()) + 1 if len(self.body.regions) else 1
        paths = [str(a.prim.GetPath()) for a in self._agent_rigs]
        ids = [schema.agent_id(a.prim) for a in self._agent_rigs]
        if self._vertex_colours is not None:
            palettes = self._vertex_colours[1]
        else:
            palettes = [_palette_of(a, rows) for a in self._agent_rigs]
        palettes = np.array(palettes, dtype=np.float32).reshape(-1, rows, 3)
        return paths, np.array(ids, dtype=np.int32), palettes

    @property
    def agent_paths(self) -> list[str]:
        return self._agent_static[0]

    def agent_row(self, name: str) -> int:
        """Row in :attr:`agent_paths` of an agent given by prim path, or by its name when that is unique.

        Raises
        ------
        StageError
            No such agent, or more than one with that name.
        """
        from ..core.errors import StageError

        hits = [i for i, p in enumerate(self.agent_paths) if p == name or p.rsplit("/", 1)[-1] == name]
        if len(hits) != 1:
            raise StageError(f"{'no' if not hits else 'more than one'} agent named {name!r} "
                             f"({'give its prim path' if hits else 'not an agent of this shot'})",
                             file=self.path, prim=name)
        return hits[0]

    def agents(self, time, rows=None) -> AgentPoses:
        """Every agent's joints in the world at ``time`` (or only those at ``rows`` of :attr:`agent_paths`)."""
        from pxr import UsdGeom

        paths, ids, palettes = self._agent_static
        rows = np.arange(len(paths)) if rows is None else np.asarray(rows, dtype=np.int64)
        paths, ids, palettes = [paths[k] for k in rows], ids[rows], palettes[rows]
        n = len(paths)
        rot = np.zeros((n, 3, 4))
        trans = np.zeros((n, 3, 3))
        scale = np.ones((n, 3, 3))
        root = np.zeros((n, 4, 4))
        visible = np.zeros(n, dtype=bool)
        t = float(time)
        for i, k in enumerate(rows):
            agent = self._agent_rigs[k]
            r, tr, s = agent.rotations.Get(t), agent.translations.Get(t), agent.scales.Get(t)
            order = agent.order                 # the animation's joints in rig.JOINTS order
            rot[i] = [(q.GetReal(), *q.GetImaginary()) for q in (r[int(j)] for j in order)]
            trans[i] = np.array(tr)[order]
            if s:
                scale[i] = np.array(s)[order]
            # The joints live in the Skeleton's space (UsdSkel), which a DCC tool may move under transforms
            # of its own; usdcrowd's Skeleton sits untransformed under the agent.
            root[i] = self._world(agent.skeleton, t)
            visible[i] = UsdGeom.Imageable(agent.prim).ComputeVisibility(t) != UsdGeom.Tokens.invisible
        bad = ~(np.isfinite(rot).all(axis=(1, 2)) & np.isfinite(trans).all(axis=(1, 2))
                & np.isfinite(scale).all(axis=(1, 2)) & np.isfinite(root).all(axis=(1, 2)))
        if bad.any():
            self._fail_pose(int(rows[np.argmax(bad)]), int(np.argmax(bad)), t, rot, trans, scale)
        local = rig.compose_local(rot, trans)
        local[..., :3, :3] *= scale[..., :, None]        # UsdSkel: scale, then rotate, then translate
        joints = rig.local_to_skel(local) @ root[:, None]
        return AgentPoses(t, paths, ids, visible, palettes[:, 0], joints, palettes)

    def _fail_pose(self, row: int, i: int, t: float, rot, trans, scale) -> None:
        """A damaged animation (NaN or inf) is one line naming its layer, prim, attribute and time."""
        from ..core.errors import StageError

        agent = self._agent_rigs[row]
        for values, query in ((rot[i], agent.rotations), (trans[i], agent.translations), (scale[i], agent.scales)):
            if not np.isfinite(values).all():
                attr = query.GetAttribute()
                raise StageError.at(attr.GetPrim(), attr.GetName(), f"not a finite value at time {t:g}")
        raise StageError(f"the agent's transform is not finite at time {t:g}", file=self.path,
                         prim=self.agent_paths[row])

    def skinned_vertices(self, poses: AgentPoses) -> np.ndarray:
        """(n, v, 3) float32 world positions of every agent's body vertices."""
        b = self.body
        return rig.skin_points(b.points, b.joint_indices, b.joint_weights, poses.skinning).astype(np.float32)


@dataclass
class _Body:
    points: np.ndarray          # (v, 3) bind pose
    faces: np.ndarray           # (f, 3)
    joint_indices: np.ndarray   # (v, k)
    joint_weights: np.ndarray   # (v, k)
    regions: np.ndarray         # (v,) int32 row of an agent's palette (AgentPoses.palette)
    roughness: np.ndarray | None  # (f,) float32 per face, from the materials bound to the body's subsets


@dataclass
class _AgentRig:
    """Where one agent's pose and body live on the stage.

    usdcrowd binds an agent's Skeleton and SkelAnimation on its SkelRoot,
    with the Skeleton and the Body as its children; a DCC tool may bind them
    elsewhere (Blender: the animation on the Skeleton, the Mesh bound to it,
    each under a transform of its own). UsdSkel's bindings say which is which.
    """

    prim: object            # the agent (schema.agent_id)
    skeleton: object        # its Skeleton prim: the space of the joints
    body: object | None     # the Mesh skinned by that skeleton, None if it has none
    rotations: object       # Usd.AttributeQuery of the SkelAnimation's rotations
    translations: object
    scales: object
    order: np.ndarray       # (3,) row of each of rig.JOINTS in the animation's joints


def _rig_of(prim) -> _AgentRig | None:
    """An agent's :class:`_AgentRig`, or None when no animation is bound to its skeleton.

    Raises
    ------
    StageError
        The animation lacks one of usdcrowd's joints.
    """
    from pxr import Usd

    skeleton, anim = skeleton_and_animation(prim)
    if anim is None:
        return None
    order = _rig_rows(anim.GetJointsAttr().Get() or [], anim.GetPrim(), "joints")
    return _AgentRig(prim, skeleton, _skinned_mesh(prim, skeleton), Usd.AttributeQuery(anim.GetRotationsAttr()),
                     Usd.AttributeQuery(anim.GetTranslationsAttr()), Usd.AttributeQuery(anim.GetScalesAttr()), order)


def skeleton_and_animation(prim) -> tuple:
    """(Skeleton prim, UsdSkel.Animation) that pose an agent, as UsdSkel binds them; None for what is missing.

    The skeleton is the one bound on the agent (``skel:skeleton``) or else the
    first beneath it; the animation is the one bound on that skeleton or
    inherited from an ancestor (``skel:animationSource``), which is where
    usdcrowd (on the SkelRoot) and Blender (on the Skeleton) put it.
    """
    from pxr import UsdSkel

    skeleton = _skeleton_of(prim)
    if skeleton is None:
        return None, None
    anim = UsdSkel.BindingAPI(skeleton).GetInheritedAnimationSource()
    return skeleton, (UsdSkel.Animation(anim) if anim and anim.IsA(UsdSkel.Animation) else None)


def _skeleton_of(prim):
    """The Skeleton prim an agent binds (skel:skeleton on it or an ancestor), else the first one beneath it."""
    from pxr import Usd, UsdSkel

    bound = UsdSkel.BindingAPI(prim).GetInheritedSkeleton()
    if bound:
        return bound.GetPrim()
    return next((p for p in Usd.PrimRange(prim, Usd.TraverseInstanceProxies()) if p.IsA(UsdSkel.Skeleton)), None)


def _skinned_mesh(prim, skeleton):
    """The first Mesh beneath an agent that the agent's skeleton skins, or None."""
    from pxr import Usd, UsdGeom, UsdSkel

    for p in Usd.PrimRange(prim, Usd.TraverseInstanceProxies()):
        if p.IsA(UsdGeom.Mesh):
            bound = UsdSkel.BindingAPI(p).GetInheritedSkeleton()
            if bound and bound.GetPrim() == skeleton:
                return p
    return None


def _rig_rows(names, prim, attribute: str) -> np.ndarray:
    """Row of each of usdcrowd's joints (rig.JOINTS) in a list of joint names: UsdSkel matches joints by name.

    Raises
    ------
    StageError
        A joint of the rig is not in the list.
    """
    from ..core.errors import StageError

    names = [str(n) for n in names]
    missing = [j for j in rig.JOINTS if j not in names]
    if missing:
        raise StageError.at(prim, attribute, f"has no joint {missing[0]!r} (usdcrowd's skeleton has "
                                             f"{', '.join(rig.JOINTS)})")
    return np.array([names.index(j) for j in rig.JOINTS], dtype=np.int64)


def _read_body(agent: _AgentRig) -> _Body | None:
    """The body an agent's skeleton skins, in usdcrowd's joint order and bind space; None if not triangles.

    Raises
    ------
    StageError
        The skeleton's bind pose is not usdcrowd's (skinning by the rig's
        bind pose would misplace the vertices), or the mesh is skinned by a
        joint the rig does not have.
    """
    from pxr import UsdGeom, UsdSkel

    mesh = UsdGeom.Mesh(agent.body)
    counts = np.array(mesh.GetFaceVertexCountsAttr().Get() or [])
    if not len(counts) or not np.all(counts == 3):
        return None
    skeleton = UsdSkel.Skeleton(agent.skeleton)
    _check_bind_pose(skeleton)
    binding = UsdSkel.BindingAPI(agent.body)
    k = binding.GetJointIndicesPrimvar().GetElementSize()
    # A mesh's joint indices index its own skel:joints when it has them, else its skeleton's joints.
    mesh_joints = binding.GetJointsAttr().Get() or skeleton.GetJointsAttr().Get()
    to_rig = _to_rig_index([str(n) for n in mesh_joints], agent.body)
    points = np.array(mesh.GetPointsAttr().Get(), dtype=np.float64)
    geom_bind = binding.GetGeomBindTransformAttr().Get()
    if geom_bind is not None:          # the mesh's own space to the skeleton's bind space (UsdSkel)
        g = np.array(geom_bind, dtype=np.float64)
        points = points @ g[:3, :3] + g[3, :3]
    faces = np.array(mesh.GetFaceVertexIndicesAttr().Get(), dtype=np.int32).reshape(-1, 3)
    regions, roughness = _body_dress(mesh, len(points), faces)
    return _Body(points.astype(np.float32), faces,
                 to_rig[np.array(binding.GetJointIndicesAttr().Get(), dtype=np.int32).reshape(-1, k)],
                 np.array(binding.GetJointWeightsAttr().Get(), dtype=np.float32).reshape(-1, k), regions, roughness)


def _to_rig_index(names: list[str], prim) -> np.ndarray:
    """(len(names),) index in rig.JOINTS of each joint name.

    Raises
    ------
    StageError
        A name is not one of the rig's joints.
    """
    from ..core.errors import StageError

    unknown = [n for n in names if n not in rig.JOINTS]
    if unknown:
        raise StageError.at(prim, "skel:joints", f"is skinned by joint {unknown[0]!r}, which usdcrowd's skeleton "
                                                 f"({', '.join(rig.JOINTS)}) does not have")
    return np.array([rig.JOINTS.index(n) for n in names], dtype=np.int32)


def _check_bind_pose(skeleton) -> None:
    """Refuse a skeleton whose bind transforms (matched by joint name) are not usdcrowd's rig's.

    Raises
    ------
    StageError
    """
    from ..core.errors import StageError

    binds = skeleton.GetBindTransformsAttr().Get()
    if binds is None:
        return
    rows = _rig_rows(skeleton.GetJointsAttr().Get() or [], skeleton.GetPrim(), "joints")
    binds = np.array(binds, dtype=np.float64)
    if binds.shape[1:] != (4, 4) or len(binds) <= rows.max() or not np.allclose(binds[rows], rig.BIND_SKEL,
                                                                                  atol=1e-4):
        raise StageError.at(skeleton.GetPrim(), "bindTransforms",
                            "is not usdcrowd's bind pose (the skeleton was rebound in another tool), so its body "
                            "cannot be skinned as the shot's characters are")


def _flat_colours(mesh_prim) -> np.ndarray | None:
    """(v, 3) displayColor of a mesh that has one, unindexed, per vertex (as DCC tools export it), else None."""
    from pxr import UsdGeom

    pv = UsdGeom.PrimvarsAPI(mesh_prim).GetPrimvar("displayColor")
    if not pv or pv.IsIndexed() or pv.GetInterpolation() not in (UsdGeom.Tokens.vertex, UsdGeom.Tokens.varying):
        return None
    values, points = pv.Get(), UsdGeom.Mesh(mesh_prim).GetPointsAttr().Get()
    if values is None or points is None or len(values) != len(points) or len(points) < 2:
        return None
    return np.array(values, dtype=np.float32)


def _region_order(regions: np.ndarray) -> np.ndarray:
    """Found regions in the order of usdcrowd's body (character.body.REGIONS: the top first, the colour an
    agent is known by) where the body is ours, vertex for vertex; else as found."""
    from ..character.body import build_body

    ours = build_body().regions
    labels = np.arange(regions.max() + 1)
    if len(ours) != len(regions):
        return labels
    # Each found region takes the place of the region of ours most of its vertices are in.
    meant = [np.bincount(ours[regions == r]).argmax() for r in labels]
    return labels[np.argsort(meant, kind="stable")]


def _colours_per_vertex(agent: _AgentRig, n_points: int) -> np.ndarray:
    """(n_points, 3) colour of each vertex of an agent's body (its displayColor, indices applied), else its crowd:color.

    Raises
    ------
    StageError
        Its body has neither one colour nor one per vertex (bodies are shared).
    """
    from pxr import UsdGeom

    from ..core.errors import StageError

    pv = UsdGeom.PrimvarsAPI(agent.body).GetPrimvar("displayColor") if agent.body is not None else None
    colours = pv.ComputeFlattened() if pv and pv.HasValue() else None
    if colours is None or len(colours) == 0:
        return np.broadcast_to(_palette_of(agent, 1)[0], (n_points, 3))
    colours = np.array(colours, dtype=np.float32).reshape(-1, 3)
    if len(colours) not in (1, n_points):
        raise StageError.at(agent.body, "primvars:displayColor",
                            f"has {len(colours)} vertex colours where the other agents' bodies have {n_points}")
    return np.broadcast_to(colours, (n_points, 3))


def _palette_of(agent: _AgentRig, rows: int) -> np.ndarray:
    """(rows, 3) colours of an agent's palette: its body's displayColor values, else its crowd:color.

    Raises
    ------
    StageError
        There are neither one colour nor ``rows`` of them.
    """
    from pxr import Gf

    from ..character.appearance import fit_problem
    from ..core.errors import StageError

    c = agent.prim.GetAttribute("crowd:color").Get() or Gf.Vec3f(0.6, 0.6, 0.6)
    dc = agent.body.GetAttribute("primvars:displayColor").Get() if agent.body is not None else None
    dc = np.array(dc if dc else [c], dtype=np.float32).reshape(-1, 3)
    problem = fit_problem(len(dc), rows)
    if problem:
        raise StageError.at(agent.body, "primvars:displayColor", problem)
    return np.broadcast_to(dc, (rows, 3))       # one colour dresses the whole body


def _body_dress(mesh, n_points: int, faces: np.ndarray):
    """(regions, roughness) of a body mesh: displayColor's vertex indices and its subsets' materials.

    A body without indexed vertex colours has one region; without material
    subsets, no roughness of its own (None).
    """
    from pxr import UsdGeom

    from ..core.errors import StageError

    pv = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("displayColor")
    regions = np.zeros(n_points, np.int32)
    if pv and pv.IsIndexed():
        idx = np.array(pv.GetIndices(), dtype=np.int32)
        if len(idx) != n_points or (len(idx) and idx.min() < 0):
            raise StageError.at(mesh.GetPrim(), "primvars:displayColor:indices",
                                f"has {len(idx)} entries for {n_points} points (vertex interpolation needs one each)")
        regions = idx
    subsets = UsdGeom.Subset.GetGeomSubsets(mesh, UsdGeom.Tokens.face, "materialBind")
    if not subsets:
        return regions, None
    roughness = np.full(len(faces), Material().roughness, np.float32)
    for subset in subsets:
        chosen = np.array(subset.GetIndicesAttr().Get() or [], dtype=np.int64)
        roughness[chosen[(chosen >= 0) & (chosen < len(faces))]] = _material_of(subset.GetPrim()).roughness
    return regions, roughness


def _check_lens(prim, time, *, focal, horizontalAperture, verticalAperture, near, far, matrix) -> None:
    """A camera no renderer can use is the user's mistake: one line naming the layer, the camera and the attribute."""
    from ..core.errors import StageError

    from ..core.view import lens_problem

    def fail(attribute, message):
        raise StageError.at(prim, attribute, f"{message} at time {float(time):g}")

    for name, value in (("focalLength", focal), ("horizontalAperture", horizontalAperture),
                        ("verticalAperture", verticalAperture), ("clippingRange", (near, far))):
        problem = lens_problem(name, value)
        if problem:
            fail(name, problem)
    if not np.isfinite(matrix).all():
        fail("xformOp:transform", "the camera's transform is not finite")


def _lens_focus(cam, time, frame) -> tuple[float, float]:
    """(fStop, focusDistance in metres) of a UsdGeom.Camera; (0, 0) where unusable (a pinhole)."""
    from .stageio import authoring_meters_per_unit

    f_stop = cam.GetFStopAttr().Get(time)
    attr = cam.GetFocusDistanceAttr()
    focus = attr.Get(time)
    if f_stop is None or focus is None or not (np.isfinite(f_stop) and np.isfinite(focus)):
        return 0.0, 0.0
    if f_stop <= 0 or focus <= 0:
        return 0.0, 0.0
    return float(f_stop), float(focus) * authoring_meters_per_unit(attr, time, frame)


def _toric_of(prim, time) -> dict | None:
    """A toric camera's authored intent at ``time`` (ToricCameraAPI), or None for other cameras."""
    from .. import schema

    if not prim.HasAPI(schema.TORIC_CAMERA_API):
        return None

    def get(name, default=None):
        attr = prim.GetAttribute(f"crowd:toric:{name}")
        value = attr.Get(time) if attr else None
        return default if value is None else value

    return {"behavior": str(get("behavior", "")), "shot_size": str(get("shotSize", "")),
            "smoothed": bool(get("smoothed", False)), "target_a": str(get("targetA", "")),
            "target_b": str(get("targetB", "")), "p_a": [float(v) for v in get("pA", (0.0, 0.0))],
            "p_b": [float(v) for v in get("pB", (0.0, 0.0))], "theta": float(get("theta", 0.0)),
            "phi": float(get("phi", 0.0))}


def _cut_of(prim, time) -> dict | None:
    """A cut camera's record at ``time`` (CutCameraAPI): the camera on air and why, or None for others."""
    from .. import schema

    if not prim.HasAPI(schema.CUT_CAMERA_API):
        return None

    def get(name, default):
        attr = prim.GetAttribute(f"crowd:cut:{name}")
        value = attr.Get(time) if attr else None
        return default if value is None else value

    return {"on_air": str(get("camera", "")), "event": str(get("event", "")), "shot": int(get("shot", 0)),
            "reason": str(get("reason", ""))}


def _ancestors_animated(prim) -> bool:
    from pxr import UsdGeom

    p = prim.GetParent()
    while p and not p.IsPseudoRoot():
        if p.IsA(UsdGeom.Xformable) and UsdGeom.Xformable(p).TransformMightBeTimeVarying():
            return True
        p = p.GetParent()
    return False


def _material_of(prim) -> Material:
    """UsdPreviewSurface inputs of the bound material, else displayColor/displayOpacity."""
    from pxr import UsdGeom, UsdShade

    mat = Material()
    pv = UsdGeom.PrimvarsAPI(prim)
    dc = pv.GetPrimvar("displayColor")
    if dc and dc.Get():
        mat.base_color = np.array(dc.Get()[0], dtype=np.float64)
    do = pv.GetPrimvar("displayOpacity")
    if do and do.Get():
        mat.opacity = float(do.Get()[0])
    material, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
    if not material:
        return mat
    shader = material.ComputeSurfaceSource()[0]
    if not shader or shader.GetIdAttr().Get() != "UsdPreviewSurface":
        return mat
    for name, attr in (("diffuseColor", "base_color"), ("roughness", "roughness"),
                       ("metallic", "metallic"), ("opacity", "opacity")):
        inp = shader.GetInput(name)
        if not inp:
            continue
        source = inp.GetConnectedSource()
        if source and name == "diffuseColor":
            tex = UsdShade.Shader(source[0].GetPrim())
            file_in = tex.GetInput("file")
            if file_in and file_in.Get() is not None:
                mat.base_color_texture = unpacked(file_in.Get().resolvedPath) or None
            continue
        value = inp.Get()
        if value is not None:
            setattr(mat, attr, np.array(value, dtype=np.float64) if attr == "base_color" else float(value))
    return mat


def color_temperature_rgb(kelvin: float) -> np.ndarray:
    """Linear sRGB tint of a black body at ``kelvin``, normalised to luminance 1.

    Planck's law integrated against the CIE 1931 observer (colour-science),
    valid at any temperature (a crater's 1,200 K glow as well as daylight),
    as UsdLux's colorTemperature asks for a black body.
    """
    import colour

    sd = colour.sd_blackbody(float(kelvin), colour.SpectralShape(360, 830, 5))
    xyz = colour.sd_to_XYZ(sd, method="Integration")
    rgb = np.clip(colour.XYZ_to_RGB(xyz / xyz[1], "sRGB", apply_cctf_encoding=False), 0.0, None)
    return rgb / (0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2])


def _light_of(prim, to_world: np.ndarray, mpu: float, up_axis: str = "Z") -> Light | None:
    from pxr import UsdLux

    from ..core.errors import StageError
    from .lights import light_problems

    for attribute, problem in light_problems(prim)[:1]:        # what `usdcrowd validate` reports
        raise StageError.at(prim, attribute, problem)
    api = UsdLux.LightAPI(prim)
    rgb = np.array(api.GetColorAttr().Get(), dtype=np.float64)
    if api.GetEnableColorTemperatureAttr().Get():
        rgb = rgb * color_temperature_rgb(api.GetColorTemperatureAttr().Get())
    intensity = float(api.GetIntensityAttr().Get()) * 2.0 ** float(api.GetExposureAttr().Get())
    kind = {"DistantLight": "distant", "DomeLight": "dome", "DomeLight_1": "dome", "SphereLight": "sphere",
            "RectLight": "rect", "DiskLight": "disk", "CylinderLight": "cylinder"}.get(str(prim.GetTypeName()))
    if kind is None:
        return None
    m = to_world.copy()
    scale = np.linalg.norm(m[:3, :3], axis=1)
    m[:3, :3] /= scale[:, None]
    light = Light(str(prim.GetPath()), kind, rgb, intensity, m, normalize=bool(api.GetNormalizeAttr().Get()))
    s = float(scale.mean())           # to_world already holds metersPerUnit
    if kind == "distant":
        light.angle = float(UsdLux.DistantLight(prim).GetAngleAttr().Get())
        light.intensity *= distant_illuminance(light.angle, light.normalize)
    elif kind == "dome":
        f = UsdLux.DomeLight(prim).GetTextureFileAttr().Get()
        light.texture = (unpacked(f.resolvedPath) or None) if f else None
        if str(prim.GetTypeName()) == "DomeLight_1":
            pole = str(UsdLux.DomeLight_1(prim).GetPoleAxisAttr().Get() or "scene")
            light.pole_axis = up_axis if pole == "scene" else pole
    elif kind == "sphere":
        light.radius = float(UsdLux.SphereLight(prim).GetRadiusAttr().Get()) * s
    elif kind == "rect":
        r = UsdLux.RectLight(prim)
        light.width, light.height = float(r.GetWidthAttr().Get()) * s, float(r.GetHeightAttr().Get()) * s
    elif kind == "disk":
        light.radius = float(UsdLux.DiskLight(prim).GetRadiusAttr().Get()) * s
    elif kind == "cylinder":
        c = UsdLux.CylinderLight(prim)
        light.radius, light.length = float(c.GetRadiusAttr().Get()) * s, float(c.GetLengthAttr().Get()) * s
    return light
