"""The crowd in glTF: one skin per agent on the three joints of usdcrowd's rig, keyed at each frame.

Every agent's body mesh shares the body's positions, normals, joints,
weights and triangles; its colours (COLOR_0, linear RGB) are its own. The
joints' values come from :meth:`ShotScene.agents <usdcrowd.scenario.shot_scene.ShotScene.agents>`,
what the renderers draw.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..character import rig
from .axes import continuous, decompose, frame_to_gltf, points_to_gltf
from .document import Document, add_node, animate
from .glb import ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER

JOINT_NAMES = tuple(name.rsplit("/", 1)[-1] for name in rig.JOINTS)     # legs, torso, head


@dataclass
class AgentTracks:
    """Every agent's joints over the exported frames, as glTF node values.

    Attributes
    ----------
    paths : list[str]
    ids : (n,) int
    palette : (n, r, 3) float32
        Linear RGB per body region (``ShotScene.body.regions`` indexes r).
    visible : (t, n) bool
    translation : (t, n, j, 3) float32
        The root joint's in the world, the others' in their parent's frame (glTF axes).
    rotation : (t, n, j, 4) float32
        Unit quaternions (x, y, z, w), continuous over t.
    scale : (t, n, j, 3) float32
    """

    paths: list
    ids: np.ndarray
    palette: np.ndarray
    visible: np.ndarray
    translation: np.ndarray
    rotation: np.ndarray
    scale: np.ndarray


def sample_agents(scene, times: np.ndarray, bar=None) -> AgentTracks:
    """Pose every agent at ``times`` and express its joints as glTF node values.

    Parameters
    ----------
    scene : ShotScene
    times : (t,) float
        Time codes.
    bar : tqdm, optional
        Advanced by one per frame.

    Raises
    ------
    StageError
        A joint transform with shear (glTF nodes hold translation, rotation, scale only).
    """
    n, j = len(scene.agent_paths), len(rig.JOINTS)
    shape = (len(times), n, j)
    # float32 from the start: glTF keeps nothing finer, and a large crowd's keys are many.
    trans, rot, scale = (np.zeros(shape + (k,), np.float32) for k in (3, 4, 3))
    visible = np.zeros((len(times), n), dtype=bool)
    poses = None
    for k, t in enumerate(times):
        poses = scene.agents(float(t))
        visible[k] = poses.visible
        local = _joint_locals(poses.joints_world)
        try:
            trans[k], rot[k], scale[k] = decompose(frame_to_gltf(local))
        except ValueError as exc:
            _fail_shear(scene, local, float(t), exc)
        if bar is not None:
            bar.update(1)
    if poses is None:
        palette, ids = np.zeros((0, 1, 3), np.float32), np.zeros(0, np.int32)
    else:                                       # no palette: one colour all over
        palette = poses.palette if poses.palette is not None else poses.color[:, None, :]
        ids = poses.agent_ids
    return AgentTracks(list(scene.agent_paths), ids, palette, visible, trans, continuous(rot), scale)


def _joint_locals(joints_world: np.ndarray) -> np.ndarray:
    """(n, j, 4, 4) joint-to-world -> the root's world matrix and each other joint's in its parent."""
    local = np.array(joints_world, dtype=np.float64)
    for j, parent in enumerate(rig.PARENT):
        if parent >= 0:
            local[:, j] = joints_world[:, j] @ np.linalg.inv(joints_world[:, parent])
    return local


def _fail_shear(scene, local: np.ndarray, time: float, exc: ValueError):
    """Name the first agent whose joints glTF cannot hold."""
    from ..core.errors import StageError

    for row, path in enumerate(scene.agent_paths):
        try:
            decompose(frame_to_gltf(local[row]))
        except ValueError:
            raise StageError(f"{exc} (its joints at time {time:g})", file=scene.path, prim=path) from None
    raise StageError(f"{exc} (at time {time:g})", file=scene.path)


@dataclass
class _Body:
    """Accessors every agent's body mesh shares."""

    positions: int
    normals: int
    joints: int
    weights: int
    indices: int
    inverse_binds: int
    material: int
    regions: np.ndarray         # (v,) row of an agent's palette per vertex


def _add_body(doc: Document, scene) -> _Body:
    """The shared skinned body: bind-pose vertices (glTF axes), their joints and weights, the triangles."""
    import trimesh
    from pygltflib import Material, PbrMetallicRoughness

    from ..core.shading import Material as UsdMaterial

    body = scene.body
    points = points_to_gltf(body.points)
    faces = np.asarray(body.faces, dtype=np.uint32)
    normals = trimesh.Trimesh(points, faces, process=False).vertex_normals
    joints, weights = _four_influences(body.joint_indices, body.joint_weights)
    inverse_binds = frame_to_gltf(np.linalg.inv(rig.BIND_SKEL)).astype(np.float32)
    doc.gltf.materials.append(Material(name="body", pbrMetallicRoughness=PbrMetallicRoughness(
        baseColorFactor=[1.0, 1.0, 1.0, 1.0], metallicFactor=0.0, roughnessFactor=UsdMaterial().roughness)))
    buf = doc.buffer
    return _Body(buf.add(points.astype(np.float32), "VEC3", ARRAY_BUFFER, bounds=True),
                 buf.add(normals.astype(np.float32), "VEC3", ARRAY_BUFFER),
                 buf.add(joints, "VEC4", ARRAY_BUFFER), buf.add(weights, "VEC4", ARRAY_BUFFER),
                 buf.add(faces.reshape(-1), "SCALAR", ELEMENT_ARRAY_BUFFER),
                 buf.add(inverse_binds, "MAT4"), len(doc.gltf.materials) - 1, np.asarray(body.regions))


def _four_influences(joint_indices: np.ndarray, joint_weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """glTF's JOINTS_0 and WEIGHTS_0 from UsdSkel's k influences per vertex.

    With three joints every vertex fits in one set of four whatever k is:
    the weights are summed per joint (a joint may be named twice in USD),
    normalised, and written heaviest first; empty slots are joint 0 with
    weight 0.

    Parameters
    ----------
    joint_indices, joint_weights : (v, k)

    Returns
    -------
    joints : (v, 4) uint8
    weights : (v, 4) float32
        Rows sum to 1 (a vertex without weight follows the root joint).
    """
    n_joints = len(rig.JOINTS)
    idx = np.asarray(joint_indices, dtype=np.int64)
    dense = np.zeros((len(idx), n_joints))
    np.add.at(dense, (np.arange(len(idx))[:, None], np.clip(idx, 0, n_joints - 1)), np.asarray(joint_weights))
    total = dense.sum(axis=1, keepdims=True)
    dense = np.where(total > 0, dense / np.where(total > 0, total, 1.0), np.eye(n_joints)[0])
    # Heaviest first; a slot without weight names joint 0 (glTF's validators ask for it).
    order = np.argsort(-dense, axis=1, kind="stable")
    heaviest = np.take_along_axis(dense, order, axis=1)
    weights = np.zeros((len(idx), 4), np.float32)
    joints = np.zeros((len(idx), 4), np.uint8)
    weights[:, :n_joints] = heaviest
    joints[:, :n_joints] = np.where(heaviest > 0, order, 0)
    return joints, weights


def add_crowd(doc: Document, scene, tracks: AgentTracks) -> list[int]:
    """One node tree per agent that is visible at some exported frame, under a ``crowd`` node.

    Returns
    -------
    list of int
        The scene's root nodes: ``crowd``, then the agents' skinned body nodes (roots, as glTF
        asks: only their joints place them).
    """
    from pygltflib import Skin

    body = _add_body(doc, scene) if len(tracks.paths) else None
    colours: dict[bytes, int] = {}              # agents dressed alike share their COLOR_0
    children, bodies = [], []
    for row in np.flatnonzero(tracks.visible.any(axis=0)):
        agent = add_node(doc, name=tracks.paths[row], extras={
            "usdPath": tracks.paths[row], "agentId": int(tracks.ids[row]),
            "color": np.asarray(tracks.palette[row, 0], dtype=float).tolist()})
        joints = _add_joints(doc, tracks, row)
        doc.gltf.skins.append(Skin(name=tracks.paths[row], inverseBindMatrices=body.inverse_binds,
                                   joints=joints, skeleton=joints[0]))
        mesh = _add_agent_mesh(doc, body, tracks.palette[row], colours, tracks.paths[row])
        bodies.append(add_node(doc, name=f"{tracks.paths[row]}/Body", mesh=mesh, skin=len(doc.gltf.skins) - 1))
        doc.gltf.nodes[agent].children = [joints[0]]
        if not tracks.visible[:, row].all():    # hidden at some frames: nothing to see there
            shown = tracks.visible[:, row].astype(np.float32)[:, None]
            animate(doc, agent, "scale", np.repeat(shown, 3, axis=1), interpolation="STEP")
        children.append(agent)
    return [add_node(doc, name="crowd", children=children), *bodies]


def _add_joints(doc: Document, tracks: AgentTracks, row: int) -> list[int]:
    """The agent's joint nodes, parents first, keyed over the frames."""
    nodes = []
    for j, parent in enumerate(rig.PARENT):
        node = add_node(doc, name=JOINT_NAMES[j])
        animate(doc, node, "translation", tracks.translation[:, row, j])
        animate(doc, node, "rotation", tracks.rotation[:, row, j])
        animate(doc, node, "scale", tracks.scale[:, row, j])
        if parent >= 0:
            doc.gltf.nodes[nodes[parent]].children.append(node)
        nodes.append(node)
    return nodes


def _add_agent_mesh(doc: Document, body: _Body, palette: np.ndarray, colours: dict, name: str) -> int:
    """The body mesh with the agent's colours (vertex colours from its palette)."""
    from pygltflib import Attributes, Mesh, Primitive

    rgb = np.ascontiguousarray(np.asarray(palette, dtype=np.float32)[body.regions])
    key = rgb.tobytes()
    if key not in colours:
        colours[key] = doc.buffer.add(rgb, "VEC3", ARRAY_BUFFER)
    attributes = Attributes(POSITION=body.positions, NORMAL=body.normals, JOINTS_0=body.joints,
                            WEIGHTS_0=body.weights, COLOR_0=colours[key])
    doc.gltf.meshes.append(Mesh(name=f"{name}/Body", primitives=[Primitive(
        attributes=attributes, indices=body.indices, material=body.material)]))
    return len(doc.gltf.meshes) - 1
