"""A shot stage -> one Mitsuba scene, built once per sequence.

Everything static (scenery meshes in world space, materials, lights, the
integrator) is translated here. What moves is exposed through
``mi.traverse`` and updated per frame by :mod:`.frame`:

- every character is one block of a single merged mesh ``agents`` (one
  parameter update and one BVH refit per frame, not hundreds); a
  ``mesh_attribute`` texture reads each agent's clothing colour per vertex
  and the face attribute ``face_gtid`` its track id;
- scenery whose transform is time-varying keeps its local vertices here and
  is re-posed per frame;
- the sensor's ``to_world`` and field of view.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...core.shading import SCENERY_ID_BASE
from ...core.view import CameraView
from ...scenario.shot_scene import ShotScene
from .camera import sensor_dict
from .integrator import integrator_dict
from .lights import emitters, has_shape, is_uniform_sky, light_id
from .materials import agent_bsdf_dict, bsdf_dict, usd_uv_to_mitsuba
from .meshes import flat_or_smooth, make_mesh
from .variant import single_threaded_build

AGENTS_KEY = "agents"
SENSOR_KEY = "sensor"


@dataclass
class AnimatedScenery:
    """Scenery re-posed per frame: its key in the scene and its local geometry."""

    key: str
    item: object                 # SceneryItem
    flip: bool                   # the transform mirrors: faces were re-wound at build time


@dataclass
class BuiltScene:
    """The Mitsuba scene and what the per-frame update needs to know about it.

    Attributes
    ----------
    scene : mi.Scene
    params : mi.SceneParameters
        ``mi.traverse(scene)``.
    agent_ids : (n,) int32
        Track id of each agent block of the ``agents`` mesh, in
        ``ShotScene.agent_paths`` order.
    n_body_vertices : int
        Vertices per agent block.
    animated : list[AnimatedScenery]
    id_paths : dict[int, str]
        Every ground-truth id (agents' track ids and scenery ids) -> prim path.
    """

    scene: object
    params: object
    agent_ids: np.ndarray
    n_body_vertices: int
    animated: list[AnimatedScenery] = field(default_factory=list)
    id_paths: dict[int, str] = field(default_factory=dict)


def posed_scenery(item, time) -> tuple[np.ndarray, bool]:
    """(v, 3) world vertices of a scenery item at ``time`` and whether its transform mirrors."""
    m = item.local_to_world(time)
    return item.mesh.vertices @ m[:3, :3] + m[3, :3], bool(np.linalg.det(m[:3, :3]) < 0)


def agent_vertices(shot: ShotScene, poses, skinned: np.ndarray | None = None) -> np.ndarray:
    """(n*v, 3) float32 world vertices of all agents; hidden agents collapse to a point (never hit).

    ``skinned`` is ``shot.skinned_vertices(poses)`` where the caller has it
    already ((n, v, 3), left as it is): skinning 200 bodies costs 0.06 s.
    """
    verts = shot.skinned_vertices(poses) if skinned is None else skinned
    hidden = ~poses.visible
    if hidden.any():
        verts = verts.copy() if skinned is not None else verts
        verts[hidden] = poses.joints_world[hidden, 0, 3, :3][:, None, :].astype(np.float32)
    return verts.reshape(-1, 3)


def build_scene(shot: ShotScene, cam: CameraView, width: int, height: int, spp: int, max_depth: int,
                time: float, sampler: str = "independent") -> BuiltScene:
    """Translate the shot at ``time`` into a Mitsuba scene.

    Parameters
    ----------
    shot : ShotScene
    cam : CameraView
        The camera at ``time``.
    width, height : int
        Film size.
    spp : int
        Beauty samples per pixel.
    max_depth : int
        Longest light path (2 = direct light only); the path tracer is
        :mod:`.integrator`'s (a shadow ray to every light but a uniform sky)
        for up to ``integrator.MAX_LIGHTS`` such lights, Mitsuba's ``path``
        above.
    time : float
        Time code the agents and animated scenery are first posed at.
    sampler : str
        Mitsuba sampler of the beauty.

    Returns
    -------
    BuiltScene
    """
    import mitsuba as mi

    # A uniform sky (and the default one a stage without lights gets, below) takes no shadow rays.
    integrator = integrator_dict(sum(not is_uniform_sky(light) for light in shot.lights), max_depth)
    scene: dict = {"type": "scene", "integrator": integrator,
                   SENSOR_KEY: sensor_dict(cam, width, height, spp, sampler=sampler)}
    id_paths: dict[int, str] = {}
    animated = _add_scenery(scene, id_paths, shot, time)
    scene.update(emitters(shot.lights, shot.frame.up_axis))
    id_paths.update({light_id(k): light.path for k, light in enumerate(shot.lights) if has_shape(light)})
    agent_ids, nv = _add_agents(scene, id_paths, shot, time)
    if not any(k.startswith("light_") for k in scene):
        # A stage without lights still shows something: a dim grey sky.
        scene["light_default"] = {"type": "constant", "radiance": {"type": "rgb", "value": [0.5, 0.5, 0.5]}}
    with single_threaded_build():       # a BVH that does not depend on thread timing
        loaded = mi.load_dict(scene)
    return BuiltScene(loaded, mi.traverse(loaded), agent_ids, nv, animated, id_paths)


def _add_scenery(scene: dict, id_paths: dict[int, str], shot: ShotScene, time: float) -> list[AnimatedScenery]:
    """Put every scenery mesh, posed at ``time``, in ``scene`` (and its id in ``id_paths``); the animated ones."""
    import mitsuba as mi

    animated = []
    bsdf_cache: dict[str, object] = {}
    for k, item in enumerate(shot.scenery):
        key = f"scenery_{k}"
        mat_key = repr(item.material)
        if mat_key not in bsdf_cache:
            bsdf_cache[mat_key] = mi.load_dict(bsdf_dict(item.material))
        verts, flip = posed_scenery(item, time)
        faces = item.mesh.faces[:, ::-1] if flip else item.mesh.faces
        m3 = item.local_to_world(time)[:3, :3]
        normals = flat_or_smooth(item.mesh.vertices, item.mesh.faces, item.mesh.normals)
        if normals is not None:
            normals = normals @ np.linalg.inv(m3).T                    # normals transform by the inverse transpose
            normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
        uv = usd_uv_to_mitsuba(item.mesh.uv) if item.mesh.uv is not None else None
        scene[key] = make_mesh(item.path, verts, faces, item.shape_id, normals=normals, uv=uv,
                               bsdf=bsdf_cache[mat_key])
        id_paths[int(item.shape_id)] = item.path
        if item.animated:
            animated.append(AnimatedScenery(key, item, flip))
    return animated


def _add_agents(scene: dict, id_paths: dict[int, str], shot: ShotScene, time: float) -> tuple[np.ndarray, int]:
    """Put every agent, posed at ``time``, in ``scene`` as one merged mesh; (agent ids, vertices per body)."""
    import mitsuba as mi

    paths = shot.agent_paths
    agent_ids = np.zeros(0, dtype=np.int32)
    nv = 0
    if paths:
        poses = shot.agents(time)
        agent_ids = poses.agent_ids.astype(np.int32)
        if np.any(agent_ids <= 0) or np.any(agent_ids >= SCENERY_ID_BASE):
            raise ValueError("agent ids must be in [1, SCENERY_ID_BASE)")
        body = shot.body
        nv, nf, n = len(body.points), len(body.faces), len(paths)
        faces = (body.faces[None] + (np.arange(n) * nv)[:, None, None]).reshape(-1, 3)
        # Each vertex takes its region's row of its agent's palette.
        colors = poses.palette[:, body.regions].reshape(-1, 3)
        # Roughness is per face, as the materials bound to the body's face subsets are.
        rough = None if body.roughness is None else np.tile(body.roughness, n)
        scene[AGENTS_KEY] = make_mesh("agents", agent_vertices(shot, poses), faces, np.repeat(agent_ids, nf),
                                      vertex_color=colors, face_roughness=rough,
                                      bsdf=mi.load_dict(agent_bsdf_dict(rough is not None)), smooth=True)
        id_paths.update({int(i): p for i, p in zip(agent_ids, paths)})
    return agent_ids, nv
