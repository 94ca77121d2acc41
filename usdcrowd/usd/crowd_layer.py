"""The generated crowd layer (crowd.usdc): skeletons, animation and state.

Written with the Sdf API inside change blocks (about 2.4x faster than the Usd
API). Layout, for an agent at ``<group>/<name>``::

    class "<default prim>/CrowdPrototypes"   shared skeleton and skinned body
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

Large crowds are split into part layers (crowd.part000.usdc, ...) that
crowd.usdc sublayers; each part is authored and saved by its own process,
because writing and serialising time samples is single-threaded in USD and
dominates the cost (about 2 s per million samples here).
"""

from __future__ import annotations

import multiprocessing as mp
import os

import numpy as np

from .. import __version__
from ..core import model
from ..atomic import export_layer
from ..character import appearance
from ..character import body as body_mod
from ..character import rig
from ..character.animation import Animator
from ..character.kernels import root_motion
from ..character.root import root_scale
from ..scenario.stageio import StageFrame
from ..schema import USER_PROPERTIES
from . import clips
from .agent_prims import AgentPrims
from .specs import new_attribute, new_prim, set_palette, value_types

# Under the default prim, so a stage that references the shot gets them too (USD drops relationship
# targets outside a reference's scope: bodies would lose their materials).
PROTOTYPES = "CrowdPrototypes"
# Outside the (abstract) prototype class, so DCC tools import them as any material.
MATERIALS = "CrowdMaterials"


def shared_paths(default_prim: str) -> tuple[str, str, str]:
    """``(skeleton prototype, body prototype, materials scope)`` paths of a crowd layer."""
    root = f"/{default_prim}" if default_prim else ""
    return f"{root}/{PROTOTYPES}/Skel", f"{root}/{PROTOTYPES}/Body", f"{root}/{MATERIALS}"
# Local bounding box of an agent around its root, canonical metres, per unit
# of scale: arms' reach while walking and the head top with margin.
_REACH = 0.6
_TOP = 1.05 * rig.HEAD_TOP


# Below this many agents a single process writes everything (spawning
# workers costs about a second).
PARALLEL_MIN_AGENTS = 1500
# Agents per part layer. Saving a usdc layer costs more per sample as the
# layer grows (2.1 us at 1,000 agents x 300 frames, 3.1 us at 5,000), so a
# worker writes several layers of about this size rather than one.
AGENTS_PER_PART = 1000


def _layer_metadata(layer, scenario: model.Scenario, frame: StageFrame, default_prim: str) -> None:
    layer.defaultPrim = default_prim
    layer.startTimeCode, layer.endTimeCode = scenario.time.start, scenario.time.end
    layer.timeCodesPerSecond = layer.framesPerSecond = scenario.time.fps
    layer.pseudoRoot.SetInfo("upAxis", frame.up_axis)
    layer.pseudoRoot.SetInfo("metersPerUnit", frame.meters_per_unit)
    # Readers tell generated layers by this (scenario.events.is_generated_layer).
    layer.customLayerData = {"usdcrowd": {"generator": "usdcrowd simulate", "version": __version__}}


def _write_prototypes(layer, default_prim: str) -> None:
    """The skeleton and skinned body every agent references."""
    from pxr import Gf, Sdf, Vt

    T = value_types()
    body = body_mod.build_body()
    skel_proto, body_proto, materials = shared_paths(default_prim)
    if default_prim and not layer.GetPrimAtPath(f"/{default_prim}"):
        new_prim(layer, f"/{default_prim}")            # an over: the scenario defines it
    new_prim(layer, skel_proto.rsplit("/", 1)[0], "", Sdf.SpecifierClass)
    skel = new_prim(layer, skel_proto, "Skeleton", Sdf.SpecifierClass)
    new_attribute(skel, "joints", T.TokenArray, Vt.TokenArray(list(rig.JOINTS)), Sdf.VariabilityUniform)
    new_attribute(skel, "bindTransforms", T.Matrix4dArray,
          Vt.Matrix4dArray([Gf.Matrix4d(m.tolist()) for m in rig.BIND_SKEL]), Sdf.VariabilityUniform)
    new_attribute(skel, "restTransforms", T.Matrix4dArray,
          Vt.Matrix4dArray([Gf.Matrix4d(m.tolist()) for m in rig.REST_LOCAL]), Sdf.VariabilityUniform)

    mesh = new_prim(layer, body_proto, "Mesh", Sdf.SpecifierClass)
    mesh.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["SkelBindingAPI"]))
    new_attribute(mesh, "points", T.Point3fArray, Vt.Vec3fArray.FromNumpy(body.points))
    new_attribute(mesh, "normals", T.Normal3fArray, Vt.Vec3fArray.FromNumpy(body.normals)).SetInfo("interpolation", "vertex")
    new_attribute(mesh, "faceVertexCounts", T.IntArray, Vt.IntArray.FromNumpy(body.face_vertex_counts))
    new_attribute(mesh, "faceVertexIndices", T.IntArray, Vt.IntArray.FromNumpy(body.face_vertex_indices))
    new_attribute(mesh, "subdivisionScheme", T.Token, "none", Sdf.VariabilityUniform)
    lo, hi = body.points.min(0), body.points.max(0)
    new_attribute(mesh, "extent", T.Float3Array, Vt.Vec3fArray([Gf.Vec3f(*lo.tolist()), Gf.Vec3f(*hi.tolist())]))
    k = body.joint_indices.shape[1]
    for name, vt, arr in (("primvars:skel:jointIndices", T.IntArray, Vt.IntArray.FromNumpy(body.joint_indices.ravel())),
                          ("primvars:skel:jointWeights", T.FloatArray, Vt.FloatArray.FromNumpy(body.joint_weights.ravel()))):
        spec = new_attribute(mesh, name, vt, arr)
        spec.SetInfo("interpolation", "vertex")
        spec.SetInfo("elementSize", k)
    new_attribute(mesh, "primvars:skel:geomBindTransform", T.Matrix4d, Gf.Matrix4d(1.0))
    _write_regions(layer, mesh, body, body_proto, materials)


def _write_regions(layer, mesh, body, body_proto: str, materials: str) -> None:
    """What the body is dressed in: an indexed displayColor and one material per region.

    Each vertex indexes a row of its agent's palette (``primvars:displayColor:indices``
    here, the values on each agent's Body), and one GeomSubset per region binds
    a UsdPreviewSurface of the region's roughness whose diffuseColor reads the
    displayColor primvar, as DCC tools expect of per-vertex colour.
    """
    from pxr import Sdf, Vt

    T = value_types()
    regions = body_mod.REGIONS
    plain = appearance.plain_palettes(np.full((1, 3), 0.5))[0]
    set_palette(mesh, plain)
    new_attribute(mesh, "primvars:displayColor:indices", T.IntArray, Vt.IntArray.FromNumpy(body.regions))
    rough = appearance.roughness()
    faces = body.regions[body.face_vertex_indices.reshape(-1, 3)]
    # A face takes the region most of its corners have (the first corner's on a three-way tie).
    face_region = np.where(faces[:, 1] == faces[:, 2], faces[:, 1], faces[:, 0])
    new_prim(layer, materials, "Scope", Sdf.SpecifierDef)
    for k, name in enumerate(regions):
        title = name.capitalize()
        mat_path = f"{materials}/{title}"
        mat = new_prim(layer, mat_path, "Material", Sdf.SpecifierDef)
        surface = new_prim(layer, f"{mat_path}/Surface", "Shader", Sdf.SpecifierDef)
        new_attribute(surface, "info:id", T.Token, "UsdPreviewSurface", Sdf.VariabilityUniform)
        new_attribute(surface, "inputs:roughness", T.Float, float(rough[k]))
        color = new_attribute(surface, "inputs:diffuseColor", T.Color3f)
        color.connectionPathList.explicitItems = [Sdf.Path(f"{mat_path}/DisplayColor.outputs:result")]
        new_attribute(surface, "outputs:surface", T.Token)
        reader = new_prim(layer, f"{mat_path}/DisplayColor", "Shader", Sdf.SpecifierDef)
        new_attribute(reader, "info:id", T.Token, "UsdPrimvarReader_float3", Sdf.VariabilityUniform)
        new_attribute(reader, "inputs:varname", T.String, "displayColor")
        new_attribute(reader, "outputs:result", T.Float3)
        out = new_attribute(mat, "outputs:surface", T.Token)
        out.connectionPathList.explicitItems = [Sdf.Path(f"{mat_path}/Surface.outputs:surface")]

        subset = new_prim(layer, f"{body_proto}/{title}", "GeomSubset", Sdf.SpecifierDef)
        subset.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["MaterialBindingAPI"]))
        new_attribute(subset, "elementType", T.Token, "face", Sdf.VariabilityUniform)
        new_attribute(subset, "familyName", T.Token, "materialBind", Sdf.VariabilityUniform)
        new_attribute(subset, "indices", T.IntArray, Vt.IntArray.FromNumpy(np.flatnonzero(face_region == k).astype(np.int32)))
        Sdf.RelationshipSpec(subset, "material:binding", custom=False).targetPathList.explicitItems = [mat_path]
    new_attribute(mesh, "subsetFamily:materialBind:familyType", T.Token, "partition", Sdf.VariabilityUniform)


def _write_group_profiles(layer, scenario: model.Scenario) -> None:
    """Groups carry their resolved visit profile (drawn once per group) and their agent count."""
    from pxr import Sdf

    a = scenario.agents
    for gi, gpath in enumerate(scenario.groups.path):
        members = np.flatnonzero(a.group == gi)
        spec = new_prim(layer, gpath)
        new_attribute(spec, f"{USER_PROPERTIES}agents", value_types().Int, int(members.size), Sdf.VariabilityUniform,
                      custom=True)
        if members.size:
            new_attribute(spec, "crowd:visitProfile", value_types().Token,
                  model.VISIT_PROFILES[a.visit_profile[members[0]]], Sdf.VariabilityUniform)


def write_group_properties(layer, stage, group_paths: list[str]) -> None:
    """Each group's authored ``crowd:`` values again as user properties (numbers, strings, tokens)."""
    from pxr import Sdf

    T = value_types()
    kinds = {bool: T.Bool, int: T.Int, float: T.Double, str: T.String}
    with Sdf.ChangeBlock():
        for path in group_paths:
            prim = stage.GetPrimAtPath(path)
            if not prim:
                continue
            for attr in prim.GetAuthoredAttributes():
                name = attr.GetName()
                if not name.startswith("crowd:") or attr.GetNumTimeSamples():
                    continue
                value = attr.Get()
                value = str(value) if attr.GetTypeName() in (T.Token, T.String) else value
                if type(value) in kinds:
                    new_attribute(new_prim(layer, path), f"userProperties:{name}", kinds[type(value)], value,
                          Sdf.VariabilityUniform, custom=True)


_TOKEN_SLOTS = (("behavior", model.BEHAVIORS), ("anim_class", model.ANIM_CLASSES), ("health", model.HEALTH_STATES))
# Written when the frames say who is present (a replay's people come and go): UsdGeom's visibility.
_PRESENCE_SLOT = ("present", ("inherited", "invisible"))


class _AgentPart:
    """Authors the prims and time samples of a subset of the agents into one layer."""

    def __init__(self, layer, scenario: model.Scenario, frame: StageFrame, rows: np.ndarray, authored: set[str],
                 clip_plan: clips.ClipPlan | None = None, stem: str = "", parents: dict | None = None,
                 default_prim: str = ""):
        self.layer = layer
        self.parents = parents or {}
        self._protos = shared_paths(default_prim)
        self.scenario = scenario
        self.frame = frame
        self.rows = np.asarray(rows)
        self.authored = authored
        self._last: dict[str, np.ndarray] = {}
        self._paths: list = []
        self._slots = _TOKEN_SLOTS
        self._height = scenario.agents.height[self.rows]
        self._scale = root_scale(self._height)
        self._animator = Animator(1.0 / scenario.time.fps, self._height)
        a = scenario.agents
        self._palette = a.palette if a.palette is not None else appearance.plain_palettes(a.color)
        # Samples go to time-window clip layers (saved as each window completes) when planned.
        self._clips, self._stem = clip_plan, stem
        self._windows: dict = {}
        self._declared = None           # the attributes every clip layer declares (_clip_layer)
        from pxr import Sdf

        self._roots: list = []          # SkelRoot spec per agent, for finish()
        # Start positions in the stage's axes and units, all at once.
        starts = dict(zip(self.rows.tolist(), frame.points_from_canonical(scenario.agents.start[self.rows]).tolist()))
        prims = AgentPrims(layer, scenario, frame, authored, self.parents, self._protos, self._palette, starts)
        with Sdf.ChangeBlock():
            for i, scale in zip(self.rows.tolist(), self._scale.tolist()):
                root, samples = prims.write(i, scale)
                self._roots.append(root)
                self._paths.append(samples)
            if clip_plan is not None and len(self.rows):
                clips.author_clip_sets(layer, stem.replace(".", "_"), clip_plan, stem,
                                       clips.anchor_roots(scenario.agents.path[i] for i in self.rows))

    def write_frames(self, frames: model.CrowdFrames) -> None:
        """Animate this part's agents over a chunk (``frames`` holds only them) and author it."""
        rot, trans = self._animator(frames)
        rot_usd, trans = root_motion(rot, trans, frames.position, frames.heading, self._scale)
        tokens = {key: getattr(frames, key) for key, _ in _TOKEN_SLOTS}
        if frames.present is not None:
            self._track_presence()
            leader = self.scenario.agents.role[self.rows] == model.ROLES.index("invisibleLeader")
            tokens["present"] = (~np.asarray(frames.present, bool) | leader[None, :]).astype(np.int8)
        self.write_samples(frames.times, rot_usd, trans, tokens)

    def _track_presence(self) -> None:
        """From the first chunk that says who is present: visibility is sampled per agent (time samples
        override the invisible default an invisible leader has, so those are sampled invisible)."""
        from pxr import Sdf

        if self._slots is not _TOKEN_SLOTS:
            return
        if self._windows or self._last:
            raise ValueError("presence must be given from the first chunk on")
        self._slots = _TOKEN_SLOTS + (_PRESENCE_SLOT,)
        with Sdf.ChangeBlock():
            for j, i in enumerate(self.rows):
                path = self.scenario.agents.path[i]
                spec = self.layer.GetPrimAtPath(path)
                if "visibility" not in spec.attributes:
                    new_attribute(spec, "visibility", value_types().Token)
                self._paths[j] = self._paths[j] + (Sdf.Path(f"{path}.visibility"),)

    def write_samples(self, times: np.ndarray, rot_usd: np.ndarray, trans: np.ndarray, tokens: dict) -> None:
        """Samples of this part's agents, into this layer or into the clip windows they fall in.

        Parameters
        ----------
        times : (t,) float
        rot_usd : (t, m, 3, 4) float32, quaternions in USD's (x, y, z, w) order
        trans : (t, m, 3, 3) float32
        tokens : dict of (t, m) int8 codes, keyed like CrowdFrames' fields
        """
        times = np.asarray(times, dtype=np.float64)
        # Tokens hold their value, so they are written only where they change.
        changed = {}
        for key, _ in self._slots:
            values = tokens[key]
            changed[key] = np.ones_like(values, dtype=bool)
            changed[key][1:] = values[1:] != values[:-1]
            if key in self._last:
                changed[key][0] = values[0] != self._last[key]
            self._last[key] = values[-1]
        if self._clips is None:
            self._author(self.layer, times, rot_usd, trans, tokens, changed)
            return
        for k, idx in self._clips.windows_of(times):
            sub = {key: c[idx] for key, c in changed.items()}
            if times[idx[0]] == self._clips.window_start(k):
                # A clip answers only for its own frames: each starts with every token.
                for c in sub.values():
                    c[0] = True
            self._author(self._window(k), times[idx], rot_usd[idx], trans[idx],
                         {key: v[idx] for key, v in tokens.items()}, sub)
        for k in [k for k in self._windows if self._clips.window_end(k) <= times[-1]]:
            self._save_window(k)

    def _author(self, layer, times: np.ndarray, rot_usd, trans, tokens: dict, changed: dict) -> None:
        from pxr import Sdf, Vt

        times = [float(t) for t in times]
        n_t, n_j = len(times), rot_usd.shape[2]
        # One Vt array per agent for the whole chunk, sliced per frame: a slice
        # of a Vt array is cheaper than a Vt array made from a numpy row.
        frames = list(zip(times, (slice(k * n_j, (k + 1) * n_j) for k in range(n_t))))
        rot_agent = np.ascontiguousarray(np.swapaxes(rot_usd, 0, 1)).reshape(-1, n_t * n_j, 4)
        trans_agent = np.ascontiguousarray(np.swapaxes(trans, 0, 1)).reshape(-1, n_t * n_j, 3)
        set_sample = layer.SetTimeSample
        with Sdf.ChangeBlock():
            for j, (rpath, tpath, *_rest) in enumerate(self._paths):
                r_j, t_j = Vt.QuatfArray.FromNumpy(rot_agent[j]), Vt.Vec3fArray.FromNumpy(trans_agent[j])
                for t, k in frames:
                    set_sample(rpath, t, r_j[k])
                    set_sample(tpath, t, t_j[k])
            for slot, (key, vocab) in enumerate(self._slots, start=2):
                values = tokens[key]
                for k, j in zip(*np.nonzero(changed[key])):
                    set_sample(self._paths[j][slot], times[k], vocab[values[k, j]])

    def _clip_layer(self):
        """An empty layer declaring the attributes the clips provide (a window, or the manifest).

        Declared once per part and copied: every window declares the same attributes.
        """
        from pxr import Sdf

        if self._declared is None:
            T = value_types()
            self._declared = Sdf.Layer.CreateAnonymous(".usdc")
            kinds = (T.QuatfArray, T.Float3Array, T.Token, T.Token, T.Token, T.Token)
            with Sdf.ChangeBlock():
                for paths in self._paths:
                    for path, kind in zip(paths, kinds):
                        prim = (self._declared.GetPrimAtPath(path.GetPrimPath())
                                or Sdf.CreatePrimInLayer(self._declared, path.GetPrimPath()))
                        Sdf.AttributeSpec(prim, path.name, kind, Sdf.VariabilityVarying,
                                          path.name.startswith("crowd:state"))
        layer = Sdf.Layer.CreateAnonymous(".usdc")
        layer.TransferContent(self._declared)
        return layer

    def _window(self, k: int):
        layer = self._windows.get(k)
        if layer is None:
            layer = self._windows[k] = self._clip_layer()
            layer.startTimeCode, layer.endTimeCode = self._clips.window_start(k), self._clips.window_end(k)
            layer.timeCodesPerSecond = layer.framesPerSecond = self.scenario.time.fps
        return layer

    def _save_window(self, k: int) -> None:
        os.makedirs(self._clips.folder, exist_ok=True)
        export_layer(self._windows.pop(k), os.path.join(self._clips.folder, self._clips.file_name(self._stem, k)))

    def finish(self, lo: np.ndarray, hi: np.ndarray, path_method: np.ndarray | None) -> None:
        """Extents (m, 3) in the SkelRoots' canonical space, and the path method per agent."""
        from pxr import Sdf, Vt

        T = value_types()
        boxes = np.stack([lo, hi], axis=1).astype(np.float32)
        with Sdf.ChangeBlock():
            for j, spec in enumerate(self._roots):
                new_attribute(spec, "extent", T.Float3Array, Vt.Vec3fArray.FromNumpy(boxes[j]))
                if path_method is not None:
                    spec.attributes["crowd:pathMethod"].default = model.PATH_METHODS[path_method[j]]
        if self._clips is not None:
            for k in sorted(self._windows):
                self._save_window(k)
            os.makedirs(self._clips.folder, exist_ok=True)
            export_layer(self._clip_layer(), os.path.join(self._clips.folder, self._clips.manifest_name(self._stem)))


# A pipe whose other end (a part writer) has gone.
_LOST = (BrokenPipeError, ConnectionResetError, EOFError)


def _part_worker(conn):
    """A process that owns some part layers: its work, then commands, arrive over ``conn``.

    When the coordinator is gone (interrupted, failed), the worker ends
    quietly: the coordinator reports what happened, once.
    """
    from ..interrupts import worker_ignores_interrupts

    worker_ignores_interrupts()             # Ctrl-C is the coordinator's to handle: it stops this process
    try:
        _part_work(conn, *conn.recv())
        # Its layers are saved and the coordinator has its answer: ending here spares tearing down
        # millions of samples one by one (a fifth of a second at 5,000 agents), which the coordinator
        # would wait for.
        os._exit(0)
    except _LOST:
        pass
    except Exception as exc:
        # A message cut short ("got end of file during message": the coordinator was interrupted while
        # sending it), or a failure before the command loop: the coordinator, if it still listens, reports
        # it; nothing is printed here (a traceback after its one-line message would be noise).
        try:
            conn.send(("error", f"{exc.__class__.__name__}: {exc}"))
        except (*_LOST, OSError):
            pass


def _part_work(conn, layer_paths, scenario, frame, row_sets, authored, default_prim, clip_plan, parents=None):
    from pxr import Sdf

    from .. import schema

    schema.register()
    parts = []
    for rows, path in zip(row_sets, layer_paths):
        layer = Sdf.Layer.CreateAnonymous(".usdc")
        _layer_metadata(layer, scenario, frame, default_prim)
        parts.append(_AgentPart(layer, scenario, frame, rows, authored, clip_plan,
                                os.path.splitext(os.path.basename(path))[0], parents, default_prim))
    # Columns of each part within the chunks this worker receives.
    bounds = np.cumsum([0] + [len(rows) for rows in row_sets])
    conn.send(("ready", None))
    while True:
        cmd, payload = conn.recv()
        try:
            if cmd == "frames":
                for part, lo, hi in zip(parts, bounds[:-1], bounds[1:]):
                    part.write_frames(payload.agents(slice(lo, hi)) if len(parts) > 1 else payload)
                conn.send(("ok", None))
            elif cmd == "finish":
                for part, path, lo, hi in zip(parts, layer_paths, bounds[:-1], bounds[1:]):
                    part.finish(*(None if x is None else x[lo:hi] for x in payload))
                    export_layer(part.layer, path)
                conn.send(("ok", None))
                return
            else:
                return
        except OSError as exc:          # a full disk: the coordinator raises it as it is
            conn.send(("oserror", (exc.errno, exc.strerror, exc.filename)))
            return
        except Exception as exc:       # report, the coordinator raises
            conn.send(("error", f"{exc.__class__.__name__}: {exc}"))
            return


def _start_ignoring_sigint(proc) -> None:
    """Start a part writer deaf to Ctrl-C and kill while it starts (see :func:`usdcrowd.interrupts.signals_held`).

    The terminal sends SIGINT to the whole process group; the coordinator, not
    each worker, decides what to clean up (it terminates them in
    :meth:`CrowdLayerWriter.abort`), and workers must not print tracebacks.
    """
    from ..interrupts import children_deaf_to_ctrl_c

    with children_deaf_to_ctrl_c():
        proc.start()


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
    workers : int, optional
        Part layers written in parallel; default: one per core when the crowd
        has at least PARALLEL_MIN_AGENTS agents, else 1 (no extra process).
    clip_frames : int, optional
        Frames per value-clip window (:mod:`usdcrowd.usd.clips`); default: as
        many as keep the writers' samples near ``clips.AGENT_FRAMES_HELD`` together.
        A shot no longer than one window is written without clips.
    parents : dict, optional
        ``{parent path: (4, 4) or (t, 4, 4)}`` local-to-world of the agents' parents on the scenario
        stage (:meth:`~usdcrowd.scenario.parent_space.ParentSpace.table`); agents are authored in their
        parent's space. Missing parents are the identity.
    """

    def __init__(self, path, scenario: model.Scenario, frame: StageFrame, default_prim: str = "",
                 scenario_ref: str = "", authored_agents: set[str] | None = None, workers: int | None = None,
                 clip_frames: int | None = None, parents: dict | None = None):
        from pxr import Sdf

        self.final = os.fspath(path)
        self.scenario = scenario
        n = len(scenario.agents)
        if workers is None:
            workers = min(os.cpu_count() or 1, 8) if n >= PARALLEL_MIN_AGENTS else 1
        workers = max(1, min(workers, n))
        self._lo = np.full((n, 3), np.inf)
        self._hi = np.full((n, 3), -np.inf)
        self._path_method = None
        self.layer = Sdf.Layer.CreateAnonymous(os.path.splitext(self.final)[1])
        _layer_metadata(self.layer, scenario, frame, default_prim)
        self.layer.customLayerData = {"usdcrowd": {
            "generator": "usdcrowd simulate", "version": __version__, "seed": int(scenario.seed),
            "scenario": scenario_ref, "agents": n, "frames": scenario.time.n_frames, "workers": workers}}
        authored = authored_agents or set()
        self._splits = np.array_split(np.arange(n), workers)
        self.clip_plan = clips.plan(self.final, scenario.time.start, scenario.time.end,
                                    max(map(len, self._splits)), clip_frames, workers)
        self._local = None
        self._workers = []
        self._saving = False
        if workers == 1:
            self._write_shared(default_prim)
            self._local = _AgentPart(self.layer, scenario, frame, self._splits[0], authored, self.clip_plan,
                                     os.path.splitext(os.path.basename(self.final))[0], parents, default_prim)
            return
        # Each worker splits its agents into layers of about AGENTS_PER_PART.
        layer_rows = [np.array_split(rows, max(1, round(len(rows) / AGENTS_PER_PART))) for rows in self._splits]
        stem, ext = os.path.splitext(os.path.basename(self.final))
        self.part_paths = [os.path.join(os.path.dirname(self.final), f"{stem}.part{k:03d}{ext}")
                           for k in range(sum(map(len, layer_rows)))]
        ctx = mp.get_context("spawn")      # a fresh interpreter: pxr and fork do not mix
        for _ in self._splits:
            here, there = ctx.Pipe()
            proc = ctx.Process(target=_part_worker, daemon=True, args=(there,))
            _start_ignoring_sigint(proc)
            # Only the worker may hold its end: were it also open here, a send to
            # a worker that died would block on a full pipe instead of failing.
            there.close()
            self._workers.append((proc, here))
        # Every worker is started before any is sent its work: a send waits for its worker to start up
        # and read it, and the others start up meanwhile. The work goes over the pipe, not in the
        # start-up pickle: while a start-up pickle is written, the parent itself holds the pipe's other
        # end, so a worker that died at its start would leave a large one blocked forever; a send to it
        # fails at once.
        first = 0
        for (proc, here), rows, row_sets in zip(self._workers, self._splits, layer_rows):
            paths = self.part_paths[first:first + len(row_sets)]
            first += len(row_sets)
            try:
                here.send((paths, scenario, frame, row_sets, {scenario.agents.path[i] for i in rows} & authored,
                           default_prim, self.clip_plan, parents))
            except _LOST:
                raise self._died(proc) from None
        # Their "ready" is collected with the other replies in save(): the
        # workers build their agents' prims while this builds the prototypes and the caller simulates.
        self._pending = {proc.pid: 1 for proc, _ in self._workers}
        self._write_shared(default_prim)
        self.layer.subLayerPaths = [f"./{os.path.basename(p)}" for p in self.part_paths]

    def _write_shared(self, default_prim: str) -> None:
        """The prototypes every agent references and the groups' profiles, into the crowd layer itself."""
        from pxr import Sdf

        with Sdf.ChangeBlock():
            _write_prototypes(self.layer, default_prim)
            _write_group_profiles(self.layer, self.scenario)

    def _died(self, proc) -> RuntimeError:
        """Stop everything and describe a part writer that is gone."""
        proc.join(5.0)
        self.abort()
        return RuntimeError(f"crowd layer part writer {proc.pid} died (exit code {proc.exitcode})")

    def _send(self, proc, conn, message) -> None:
        try:
            conn.send(message)
        except _LOST:
            raise self._died(proc) from None
        self._pending[proc.pid] += 1

    def _collect(self) -> None:
        """Wait for every outstanding reply of every worker; a worker that dies is an error, not a hang."""
        for proc, conn in self._workers:
            while self._pending[proc.pid]:
                if not conn.poll(1.0):
                    if not proc.is_alive():
                        raise self._died(proc)
                    continue
                try:
                    status, detail = conn.recv()
                except _LOST:
                    raise self._died(proc) from None
                self._pending[proc.pid] -= 1
                if status == "oserror":
                    self.abort()
                    raise OSError(*detail)
                if status == "error":
                    self.abort()
                    raise RuntimeError(f"crowd layer part writer failed: {detail}")

    def write_chunk(self, frames: model.CrowdFrames) -> None:
        """Animate and author the time samples of consecutive frames.

        Each part animates its own agents (:class:`usdcrowd.character.animation.Animator`,
        whose blends and head turns carry over from the previous chunk), so
        with part layers the animation runs in the workers too.

        Parameters
        ----------
        frames : CrowdFrames
            The chunk's simulated state, ``t`` frames of every agent.
        """
        pos = frames.position.astype(np.float64)
        self._lo = np.minimum(self._lo, pos.min(0))
        self._hi = np.maximum(self._hi, pos.max(0))
        if self._path_method is None:
            self._path_method = np.asarray(frames.path_method)
        if self._local is not None:
            self._local.write_frames(frames)
            return
        # No waiting here: the workers animate and author this chunk while the
        # caller simulates the next one.
        for (proc, conn), rows in zip(self._workers, self._splits):
            # Each worker's agents are a run of consecutive rows: a slice copies fastest.
            self._send(proc, conn, ("frames", frames.agents(slice(rows[0], rows[-1] + 1))))

    def start_saving(self) -> None:
        """Hand the part writers their extents and let them save, without waiting.

        The caller may do other work (cameras, pictures) while they save; :meth:`save`
        then waits for them. Calling it is optional.
        """
        if self._local is not None or self._saving:
            return
        lo, hi = self._extents()
        pm = self._path_method
        for (proc, conn), rows in zip(self._workers, self._splits):
            self._send(proc, conn, ("finish", (lo[rows], hi[rows], None if pm is None else pm[rows])))
        self._saving = True

    def _extents(self) -> tuple[np.ndarray, np.ndarray]:
        scale = root_scale(self.scenario.agents.height)
        # Extents are in the SkelRoot's space: canonical metres (the stage-frame
        # op, if any, sits above them).
        lo = self._lo - np.stack([_REACH * scale, _REACH * scale, 0 * scale], 1)
        hi = self._hi + np.stack([_REACH * scale, _REACH * scale, _TOP * scale], 1)
        return lo, hi

    def save(self) -> str:
        """Write extents and per-agent summaries, then save every layer atomically. Returns the path."""
        if self._local is not None:
            self._local.finish(*self._extents(), self._path_method)
        else:
            self.start_saving()
            self._collect()
            for proc, _ in self._workers:
                proc.join()
        clips.publish(self.clip_plan, self.final)
        return export_layer(self.layer, self.final)

    def abort(self) -> None:
        """Stop the workers and remove any part already written."""
        for proc, conn in self._workers:
            if proc.is_alive():
                proc.terminate()
        for p in getattr(self, "part_paths", []):
            if os.path.exists(p):
                os.unlink(p)
        clips.discard(self.clip_plan)
