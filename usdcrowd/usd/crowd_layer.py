"""The generated crowd layer (crowd.usdc): skeletons, animation and state.

Written with the Sdf API inside change blocks (about 2.4x faster than the Usd
API). Layout, for an agent at ``<group>/<name>``::

    class "CrowdPrototypes"            shared skeleton and skinned body
        class Skeleton "Skel"
        class Mesh "Body"
    over <group> ... {
        <def|over> SkelRoot "<name>"   CrowdAgentAPI with the resolved attributes,
            def Skeleton "Skel"        -> references the prototype
            def SkelAnimation "Anim"   rotations / translations sampled per frame,
                                       root motion in the root joint
            def Mesh "Body"            -> references the prototype, own colour

Tokens of the agent's state (behavior, animation class, health) are sampled
only where they change: tokens hold their value between samples, so this is
exact and keeps the layer small.
"""

from __future__ import annotations

import os

import numpy as np

from .. import __version__, model
from ..atomic import atomic_path
from ..character import body as body_mod
from ..character import rig
from ..character.root import apply_root_motion
from ..scenario.stageio import StageFrame

PROTOTYPES = "/CrowdPrototypes"
SKEL_PROTO = f"{PROTOTYPES}/Skel"
BODY_PROTO = f"{PROTOTYPES}/Body"
# Local bounding box of an agent around its root, canonical metres, per unit
# of scale: arms' reach while walking and the head top with margin.
_REACH = 0.6
_TOP = 1.05 * rig.HEAD_TOP


def _types():
    from pxr import Sdf

    return Sdf.ValueTypeNames


def _attr(prim_spec, name, type_name, value=None, variability=None, custom=False):
    from pxr import Sdf

    spec = Sdf.AttributeSpec(prim_spec, name, type_name,
                             variability or Sdf.VariabilityVarying, custom)
    if value is not None:
        spec.default = value
    return spec


def _prim(layer, path, type_name="", specifier=None):
    from pxr import Sdf

    spec = Sdf.CreatePrimInLayer(layer, path)
    spec.specifier = specifier if specifier is not None else Sdf.SpecifierOver
    if type_name:
        spec.typeName = type_name
    return spec


class CrowdLayerWriter:
    """Author one crowd layer, chunk by chunk, and save it atomically.

    Parameters
    ----------
    path : path-like
        Final file (``.usdc`` or ``.usda``).
    scenario : Scenario
        The resolved scenario (its agent table is written as authored values).
    frame : StageFrame
        Axes and units of the scenario; the layer is written in them.
    default_prim : str
        The scenario's defaultPrim, mirrored on the layer.
    scenario_ref : str
        How the layer names its scenario (for customLayerData).
    authored_agents : set[str]
        Paths of agents that exist in the scenario (written as ``over``);
        the others (clones) are defined here.
    """

    def __init__(self, path, scenario: model.Scenario, frame: StageFrame, default_prim: str = "",
                 scenario_ref: str = "", authored_agents: set[str] | None = None):
        from pxr import Sdf

        self.final = os.fspath(path)
        self.scenario = scenario
        self.frame = frame
        self.default_prim = default_prim
        self.scenario_ref = scenario_ref
        self.authored_agents = authored_agents or set()
        self.layer = Sdf.Layer.CreateAnonymous(os.path.splitext(self.final)[1])
        n = len(scenario.agents)
        self._lo = np.full((n, 3), np.inf)
        self._hi = np.full((n, 3), -np.inf)
        self._last_tokens: dict[str, np.ndarray] = {}
        self._scale = (scenario.agents.height / rig.HEAD_TOP).astype(np.float16).astype(np.float32)
        self._anim_paths: list = []
        self._write_static()

    # ------------------------------------------------------------------ static
    def _write_static(self):
        from pxr import Gf, Sdf, Vt

        T = _types()
        layer, sc, agents = self.layer, self.scenario, self.scenario.agents
        layer.defaultPrim = self.default_prim
        layer.startTimeCode, layer.endTimeCode = sc.time.start, sc.time.end
        layer.timeCodesPerSecond = layer.framesPerSecond = sc.time.fps
        layer.pseudoRoot.SetInfo("upAxis", self.frame.up_axis)
        layer.pseudoRoot.SetInfo("metersPerUnit", self.frame.meters_per_unit)
        layer.customLayerData = {"usdcrowd": {
            "generator": "usdcrowd simulate", "version": __version__, "seed": int(sc.seed),
            "scenario": self.scenario_ref, "agents": len(agents), "frames": sc.time.n_frames}}

        body = body_mod.build_body()
        with Sdf.ChangeBlock():
            _prim(layer, PROTOTYPES, "", Sdf.SpecifierClass)
            skel = _prim(layer, SKEL_PROTO, "Skeleton", Sdf.SpecifierClass)
            _attr(skel, "joints", T.TokenArray, Vt.TokenArray(list(rig.JOINTS)), Sdf.VariabilityUniform)
            _attr(skel, "bindTransforms", T.Matrix4dArray,
                  Vt.Matrix4dArray([Gf.Matrix4d(m.tolist()) for m in rig.BIND_SKEL]), Sdf.VariabilityUniform)
            _attr(skel, "restTransforms", T.Matrix4dArray,
                  Vt.Matrix4dArray([Gf.Matrix4d(m.tolist()) for m in rig.REST_LOCAL]), Sdf.VariabilityUniform)

            mesh = _prim(layer, BODY_PROTO, "Mesh", Sdf.SpecifierClass)
            mesh.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["SkelBindingAPI"]))
            _attr(mesh, "points", T.Point3fArray, Vt.Vec3fArray.FromNumpy(body.points))
            _attr(mesh, "normals", T.Normal3fArray, Vt.Vec3fArray.FromNumpy(body.normals)).SetInfo(
                "interpolation", "vertex")
            _attr(mesh, "faceVertexCounts", T.IntArray, Vt.IntArray.FromNumpy(body.face_vertex_counts))
            _attr(mesh, "faceVertexIndices", T.IntArray, Vt.IntArray.FromNumpy(body.face_vertex_indices))
            _attr(mesh, "subdivisionScheme", T.Token, "none", Sdf.VariabilityUniform)
            lo, hi = body.points.min(0), body.points.max(0)
            _attr(mesh, "extent", T.Float3Array, Vt.Vec3fArray([Gf.Vec3f(*lo.tolist()), Gf.Vec3f(*hi.tolist())]))
            k = body.joint_indices.shape[1]
            for name, vt, arr in (("primvars:skel:jointIndices", T.IntArray, Vt.IntArray.FromNumpy(body.joint_indices.ravel())),
                                  ("primvars:skel:jointWeights", T.FloatArray, Vt.FloatArray.FromNumpy(body.joint_weights.ravel()))):
                spec = _attr(mesh, name, vt, arr)
                spec.SetInfo("interpolation", "vertex")
                spec.SetInfo("elementSize", k)
            _attr(mesh, "primvars:skel:geomBindTransform", T.Matrix4d, Gf.Matrix4d(1.0))

            self._write_agents()

    def _write_agents(self):
        from pxr import Gf, Sdf, Vt

        T = _types()
        layer, sc, a = self.layer, self.scenario, self.scenario.agents
        stage_xform = None if self.frame.is_canonical else Gf.Matrix4d(self.frame.from_canonical.tolist())
        start_stage = self.frame.points_from_canonical(a.start)
        joints = Vt.TokenArray(list(rig.JOINTS))
        invisible = model.ROLES.index("invisibleLeader")
        # Groups carry their resolved visit profile (drawn once per group).
        for gi, gpath in enumerate(sc.groups.path):
            members = np.flatnonzero(a.group == gi)
            if members.size:
                g = _prim(layer, gpath)
                _attr(g, "crowd:visitProfile", T.Token,
                      model.VISIT_PROFILES[a.visit_profile[members[0]]], Sdf.VariabilityUniform)
        for i, path in enumerate(a.path):
            spec = _prim(layer, path, "SkelRoot",
                         Sdf.SpecifierOver if path in self.authored_agents else Sdf.SpecifierDef)
            spec.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["CrowdAgentAPI", "SkelBindingAPI"]))
            U = Sdf.VariabilityUniform
            _attr(spec, "crowd:agentId", T.Int, int(a.agent_id[i]), U)
            _attr(spec, "crowd:role", T.Token, model.ROLES[a.role[i]], U)
            _attr(spec, "crowd:characterType", T.Token, model.CHARACTER_TYPES[a.character_type[i]], U)
            _attr(spec, "crowd:personality", T.Token, model.PERSONALITIES[a.personality[i]], U)
            _attr(spec, "crowd:behavior", T.Token, model.BEHAVIORS[a.behavior[i]], U)
            _attr(spec, "crowd:condition", T.Token, model.CONDITIONS[a.condition[i]], U)
            _attr(spec, "crowd:fearResponse", T.Token, model.FEAR_RESPONSES[a.fear_response[i]], U)
            _attr(spec, "crowd:maxSlope", T.Float, float(a.max_slope[i]), U)
            _attr(spec, "crowd:behaviorMapInfluence", T.Float, float(a.map_influence[i]), U)
            _attr(spec, "crowd:color", T.Color3f, Gf.Vec3f(*a.color[i].tolist()), U)
            _attr(spec, "crowd:speed", T.Float, float(a.speed[i]), U)
            _attr(spec, "crowd:height", T.Float, float(a.height[i]), U)
            _attr(spec, "crowd:startPosition", T.Point3f, Gf.Vec3f(*start_stage[i].tolist()), U)
            Sdf.RelationshipSpec(spec, "crowd:group", custom=False).targetPathList.explicitItems = [sc.groups.path[a.group[i]]]
            if a.leader[i] >= 0:
                Sdf.RelationshipSpec(spec, "crowd:leader", custom=False).targetPathList.explicitItems = [a.path[a.leader[i]]]
            Sdf.RelationshipSpec(spec, "skel:skeleton", custom=False).targetPathList.explicitItems = [f"{path}/Skel"]
            Sdf.RelationshipSpec(spec, "skel:animationSource", custom=False).targetPathList.explicitItems = [f"{path}/Anim"]
            if a.role[i] == invisible:
                _attr(spec, "visibility", T.Token, "invisible")
            if stage_xform is not None:
                _attr(spec, "xformOp:transform:stageFrame", T.Matrix4d, stage_xform)
                _attr(spec, "xformOpOrder", T.TokenArray, Vt.TokenArray(["xformOp:transform:stageFrame"]), U)

            skel = _prim(layer, f"{path}/Skel", "Skeleton", Sdf.SpecifierDef)
            skel.referenceList.prependedItems = [Sdf.Reference(primPath=SKEL_PROTO)]
            anim = _prim(layer, f"{path}/Anim", "SkelAnimation", Sdf.SpecifierDef)
            _attr(anim, "joints", T.TokenArray, joints, U)
            s = float(self._scale[i])
            _attr(anim, "scales", T.Half3Array, Vt.Vec3hArray([Gf.Vec3h(s, s, s), Gf.Vec3h(1, 1, 1), Gf.Vec3h(1, 1, 1)]))
            _attr(anim, "rotations", T.QuatfArray)
            _attr(anim, "translations", T.Float3Array)
            body = _prim(layer, f"{path}/Body", "Mesh", Sdf.SpecifierDef)
            body.referenceList.prependedItems = [Sdf.Reference(primPath=BODY_PROTO)]
            _attr(body, "primvars:displayColor", T.Color3fArray, Vt.Vec3fArray([Gf.Vec3f(*a.color[i].tolist())])).SetInfo(
                "interpolation", "constant")
            for name in ("crowd:state:behavior", "crowd:state:animClass", "crowd:state:health"):
                _attr(spec, name, T.Token, custom=True)
            _attr(spec, "crowd:pathMethod", T.Token, None, U, custom=True)
            self._anim_paths.append((Sdf.Path(f"{path}/Anim.rotations"), Sdf.Path(f"{path}/Anim.translations"),
                                     Sdf.Path(f"{path}.crowd:state:behavior"), Sdf.Path(f"{path}.crowd:state:animClass"),
                                     Sdf.Path(f"{path}.crowd:state:health")))

    # ------------------------------------------------------------------ frames
    def write_chunk(self, frames: model.CrowdFrames, rotations: np.ndarray, translations: np.ndarray) -> None:
        """Author the time samples of consecutive frames.

        Parameters
        ----------
        frames : CrowdFrames
            The chunk's simulated state, ``t`` frames.
        rotations, translations : (t, n, 3, 4), (t, n, 3, 3) float
            Local joint pose of the canonical skeleton (usdcrowd.character.animation.animate).
        """
        from pxr import Sdf, Vt

        a = self.scenario.agents
        rot, trans, _ = apply_root_motion(rotations, translations, frames.position, frames.heading, a.height)
        rot_usd = rig.to_usd_quat_order(rot)
        # Bounds of the motion, for the SkelRoot extents written at close.
        pos = frames.position.astype(np.float64)
        self._lo = np.minimum(self._lo, pos.min(0))
        self._hi = np.maximum(self._hi, pos.max(0))
        times = [float(t) for t in frames.times]
        layer = self.layer
        quat_from, vec_from = Vt.QuatfArray.FromNumpy, Vt.Vec3fArray.FromNumpy
        with Sdf.ChangeBlock():
            for i, (rpath, tpath, *_rest) in enumerate(self._anim_paths):
                r_i, t_i = rot_usd[:, i], trans[:, i]
                for k, t in enumerate(times):
                    layer.SetTimeSample(rpath, t, quat_from(r_i[k]))
                    layer.SetTimeSample(tpath, t, vec_from(t_i[k]))
            self._write_tokens(frames)
        if self.path_method is None:
            self.path_method = frames.path_method

    path_method = None

    def _write_tokens(self, frames: model.CrowdFrames) -> None:
        layer = self.layer
        for slot, key, vocab in ((2, "behavior", model.BEHAVIORS), (3, "anim_class", model.ANIM_CLASSES),
                                 (4, "health", model.HEALTH_STATES)):
            values = getattr(frames, key)
            prev = self._last_tokens.get(key)
            changed = np.ones_like(values, dtype=bool)
            changed[1:] = values[1:] != values[:-1]
            if prev is not None:
                changed[0] = values[0] != prev
            for k, i in zip(*np.nonzero(changed)):
                layer.SetTimeSample(self._anim_paths[i][slot], float(frames.times[k]), vocab[values[k, i]])
            self._last_tokens[key] = values[-1]

    # ------------------------------------------------------------------ close
    def save(self) -> str:
        """Write extents and per-agent summaries, then save atomically. Returns the path."""
        from pxr import Gf, Sdf, Vt

        T = _types()
        a = self.scenario.agents
        scale = self._scale.astype(np.float64)
        # Extents are in the SkelRoot's space: canonical metres (the stage-frame
        # op, if any, sits above them).
        lo = self._lo - np.stack([_REACH * scale, _REACH * scale, 0 * scale], 1)
        hi = self._hi + np.stack([_REACH * scale, _REACH * scale, _TOP * scale], 1)
        with Sdf.ChangeBlock():
            for i, path in enumerate(a.path):
                spec = self.layer.GetPrimAtPath(path)
                _attr(spec, "extent", T.Float3Array, Vt.Vec3fArray([Gf.Vec3f(*lo[i].tolist()), Gf.Vec3f(*hi[i].tolist())]))
                if self.path_method is not None:
                    spec.attributes["crowd:pathMethod"].default = model.PATH_METHODS[self.path_method[i]]
        with atomic_path(self.final) as tmp:
            if not self.layer.Export(os.fspath(tmp)):
                raise OSError(f"could not write {self.final}")
        return self.final
