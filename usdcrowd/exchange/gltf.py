"""A shot as binary glTF 2.0: skinned characters, animated cameras and scenery, Y up, metres.

What goes in, read through :class:`~usdcrowd.scenario.shot_scene.ShotScene` (what the
renderers draw, so the GLB shows the same people in the same places):

- one node per agent under ``crowd`` (its USD path as name, id and colour
  in ``extras``) holding the joints ``legs > torso > head`` (rig.JOINTS),
  and a root node with the body mesh skinned to them (glTF places a skinned
  mesh by its joints only), see :mod:`.skins`;
- the joints' translation, rotation and scale sampled at every exported
  frame (LINEAR keys; a channel is written only where the value changes);
  an agent hidden at some frames is scaled to nothing there (STEP keys),
  one never visible is left out;
- every camera as a perspective camera on an animated node (yfov from the
  focal length and the vertical aperture, aspect from the apertures);
- scenery meshes with their UsdPreviewSurface colour, static ones placed in
  the world, animated ones on animated nodes.

Key times are seconds from the first exported frame; ``asset.extras.usdcrowd``
keeps the frame numbers and rate.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from .axes import points_to_gltf, world_to_gltf
from .document import Document, add_node, animate_matrices
from .glb import ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER, GlbBuffer
from .skins import add_crowd, sample_agents


@dataclass
class CameraTrack:
    """One camera over the exported frames.

    Attributes
    ----------
    path : str
    to_world : (t, 4, 4) float64
        Camera to glTF world, row-vector; the camera looks down its local -Z.
    yfov : (t,) float64
        Vertical field of view, radians.
    aspect, near, far : float
        Width over height of the aperture; clipping planes in metres (first frame).
    """

    path: str
    to_world: np.ndarray
    yfov: np.ndarray
    aspect: float
    near: float
    far: float


def sample_cameras(scene, times: np.ndarray) -> list[CameraTrack]:
    """Every camera of ``scene`` at ``times`` (glTF axes)."""
    from ..core.view import fov

    tracks = []
    for path in scene.camera_paths:
        views = [scene.camera(path, float(t)) for t in times]
        tracks.append(CameraTrack(path, world_to_gltf(np.array([v.cam_to_world for v in views])),
                                  np.array([fov(v.focal_length, v.vertical_aperture) for v in views]),
                                  views[0].horizontal_aperture / views[0].vertical_aperture,
                                  float(views[0].near), float(views[0].far)))
    return tracks


def build_gltf(scene, times: np.ndarray, progress: bool = False):
    """The glTF document of ``scene`` over ``times``.

    Parameters
    ----------
    scene : ShotScene
    times : (t,) float
        Time codes, increasing; the first is time 0 of the animation.
    progress : bool
        Show a progress bar over the frames.

    Returns
    -------
    pygltflib.GLTF2
        With its binary blob set (ready for ``save_binary``).
    """
    from pygltflib import GLTF2, Asset, Scene
    from tqdm import tqdm

    from .. import __version__

    times = np.asarray(times, dtype=np.float64)
    gltf = GLTF2(asset=Asset(generator=f"usdcrowd {__version__}", extras={"usdcrowd": {
        "source": os.path.abspath(scene.path), "frames": times.tolist(), "framesPerSecond": float(scene.fps)}}))
    buffer = GlbBuffer(gltf)
    seconds = ((times - times[0]) / float(scene.fps)).astype(np.float32)
    doc = Document(gltf, buffer, buffer.add(seconds, "SCALAR", bounds=True) if len(times) > 1 else None)
    with tqdm(total=len(times), desc="export glTF", unit="frame", disable=not progress, leave=False) as bar:
        agents = sample_agents(scene, times, bar)
    roots = [*add_crowd(doc, scene, agents), _add_cameras(doc, sample_cameras(scene, times)),
             _add_scenery(doc, scene, times)]
    if doc.channels:
        from pygltflib import Animation

        gltf.animations = [Animation(name="usdcrowd", channels=doc.channels, samplers=doc.samplers)]
    gltf.scenes = [Scene(name=os.path.basename(scene.path), nodes=roots)]
    gltf.scene = 0
    buffer.finish()
    return gltf


def write_glb(scene, times: np.ndarray, final: str | os.PathLike, progress: bool = False) -> dict:
    """Write ``scene`` over ``times`` to the binary glTF ``final`` (whole or not at all).

    Returns
    -------
    dict
        Counts for the command's report: agents, cameras, scenery, frames.
    """
    from ..atomic import atomic_path

    gltf = build_gltf(scene, times, progress)
    with atomic_path(final) as tmp:
        gltf.save_binary(os.fspath(tmp))
    groups = {g.name: len(g.children) for g in gltf.nodes if g.name in ("crowd", "cameras", "scenery")}
    return {**groups, "frames": len(times)}


# ---------------------------------------------------------------- cameras
def _add_cameras(doc: Document, tracks: list[CameraTrack]) -> int:
    """A perspective camera on an animated node per camera, under a ``cameras`` node."""
    from pygltflib import Camera, Perspective

    children = []
    for track in tracks:
        lens = Perspective(yfov=float(track.yfov[0]), aspectRatio=float(track.aspect),
                           znear=float(track.near), zfar=float(track.far))
        doc.gltf.cameras.append(Camera(name=track.path, type="perspective", perspective=lens))
        extras = {"usdPath": track.path}
        if np.ptp(track.yfov) > 1e-9:           # glTF cameras cannot zoom: the lens of each frame, for tools
            extras["yfovPerFrame"] = track.yfov.tolist()
        node = add_node(doc, name=track.path, camera=len(doc.gltf.cameras) - 1, extras=extras)
        animate_matrices(doc, node, track.to_world)
        children.append(node)
    return add_node(doc, name="cameras", children=children)


# ---------------------------------------------------------------- scenery
def _add_scenery(doc: Document, scene, times: np.ndarray) -> int:
    """Each scenery mesh under a ``scenery`` node: static ones in world coordinates, animated ones
    in their own, on nodes keyed over the frames.

    Raises
    ------
    StageError
        An animated piece whose transform has shear.
    """
    from ..core.errors import StageError

    children = []
    materials: dict[tuple, int] = {}
    for item in scene.scenery:
        material = _scenery_material(doc, item.material, materials)
        if not item.animated:
            world = item.local_to_world(float(times[0]))
            children.append(add_node(doc, name=item.path, mesh=_scenery_mesh(doc, item, world, material)))
            continue
        node = add_node(doc, name=item.path, mesh=_scenery_mesh(doc, item, None, material))
        try:
            animate_matrices(doc, node, world_to_gltf(np.array([item.local_to_world(float(t)) for t in times])))
        except ValueError as exc:
            raise StageError(str(exc), file=scene.path, prim=item.path) from None
        children.append(node)
    return add_node(doc, name="scenery", children=children)


def _scenery_mesh(doc: Document, item, world: np.ndarray | None, material: int) -> int:
    """A scenery mesh: vertices in glTF's world when ``world`` (4, 4) is given, else in the prim's own space."""
    from pygltflib import Attributes, Mesh, Primitive

    points = np.asarray(item.mesh.vertices, dtype=np.float64)
    faces = np.asarray(item.mesh.faces, dtype=np.uint32)
    if world is not None:
        points = points_to_gltf(points @ world[:3, :3] + world[3, :3])
        if np.linalg.det(world[:3, :3]) < 0:    # a mirroring transform baked in: keep the front faces in front
            faces = faces[:, ::-1]
    attributes = Attributes(POSITION=doc.buffer.add(points.astype(np.float32), "VEC3", ARRAY_BUFFER, bounds=True))
    indices = doc.buffer.add(np.ascontiguousarray(faces).reshape(-1), "SCALAR", ELEMENT_ARRAY_BUFFER)
    doc.gltf.meshes.append(Mesh(name=item.path, primitives=[Primitive(attributes=attributes, indices=indices,
                                                                        material=material)]))
    return len(doc.gltf.meshes) - 1


def _scenery_material(doc: Document, material, known: dict) -> int:
    """A metallic-roughness material for a UsdPreviewSurface (colour, roughness, metallic, opacity)."""
    from pygltflib import Material, PbrMetallicRoughness

    rgba = [*np.asarray(material.base_color, dtype=float).tolist(), float(material.opacity)]
    key = (*rgba, float(material.roughness), float(material.metallic))
    if key not in known:
        doc.gltf.materials.append(Material(
            pbrMetallicRoughness=PbrMetallicRoughness(baseColorFactor=rgba, metallicFactor=float(material.metallic),
                                                      roughnessFactor=float(material.roughness)),
            alphaMode="BLEND" if material.opacity < 1 else "OPAQUE", doubleSided=True))
        known[key] = len(doc.gltf.materials) - 1
    return known[key]
