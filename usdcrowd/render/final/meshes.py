"""numpy triangles -> Mitsuba meshes that carry their ground-truth id.

Every mesh in the scene has a face attribute ``face_gtid``: the id of the
agent or scenery prim each triangle belongs to; the analytic shapes of
sphere lights carry theirs as a constant texture under the same name
(:func:`id_texture`). The ground-truth pass reads it at the hit with
``eval_attribute_3``, so ids never depend on the order of
``scene.shapes()`` (which changes between runs). An id is split in two
16-bit halves stored as floats, ``(id >> 16, id & 0xFFFF, 0)``: float32
holds every integer below 2**24 exactly, but scenery ids start at 2**24.
"""

from __future__ import annotations

import numpy as np

from ...core.geometry import face_normals

GTID_ATTRIBUTE = "face_gtid"


def encode_ids(ids: np.ndarray) -> np.ndarray:
    """(f,) uint32 ids -> (f, 3) float32 halves for the face attribute."""
    ids = np.asarray(ids, dtype=np.uint32)
    return np.stack([ids >> 16, ids & 0xFFFF, np.zeros_like(ids)], -1).astype(np.float32)


def decode_ids(halves: np.ndarray) -> np.ndarray:
    """(..., 3) float halves (as read at hits) -> (...) uint32 ids."""
    h = np.rint(np.asarray(halves)).astype(np.uint32)
    return (h[..., 0] << 16) | h[..., 1]


def id_texture(shape_id: int):
    """A constant texture holding ``shape_id`` (encoded as :func:`encode_ids`), for a shape without faces."""
    import mitsuba as mi

    texel = encode_ids(np.array([shape_id])).reshape(1, 1, 3)
    return mi.load_dict({"type": "bitmap", "bitmap": mi.Bitmap(texel), "raw": True, "filter_type": "nearest"})


def float_buffer(values: np.ndarray):
    """A flat float32 Dr.Jit buffer of the current variant (``mi.Float`` is a plain float in scalar ones)."""
    import mitsuba as mi

    flat = np.ascontiguousarray(values, dtype=np.float32).ravel()
    if mi.variant().startswith("scalar"):
        import drjit as dr

        return dr.scalar.ArrayXf(flat)
    return mi.Float(flat)


def uint_buffer(values: np.ndarray):
    """A flat uint32 Dr.Jit buffer of the current variant."""
    import mitsuba as mi

    flat = np.ascontiguousarray(values, dtype=np.uint32).ravel()
    if mi.variant().startswith("scalar"):
        import drjit as dr

        return dr.scalar.ArrayXu(flat)
    return mi.UInt32(flat)


def make_mesh(name: str, vertices: np.ndarray, faces: np.ndarray, face_ids, normals: np.ndarray | None = None,
              uv: np.ndarray | None = None, vertex_color: np.ndarray | None = None,
              face_roughness: np.ndarray | None = None, bsdf=None, emitter=None,
              smooth: bool = False):
    """Build an ``mi.Mesh`` from arrays.

    Parameters
    ----------
    name : str
        Mesh name (shown in Mitsuba's messages).
    vertices : (v, 3) float
        World positions, metres.
    faces : (f, 3) int
        Counter-clockwise seen from the front.
    face_ids : int or (f,) int
        Ground-truth id of each face (0: background).
    normals : (v, 3) float, optional
        Vertex normals; without them (and ``smooth`` False) Mitsuba shades flat.
    uv : (v, 2) float, optional
        Texture coordinates in Mitsuba's convention (v = 0 at the image's top).
    vertex_color : (v, 3) float, optional
        Linear RGB, read by a ``mesh_attribute`` texture named ``vertex_color``.
    face_roughness : (f,) float, optional
        Read by a ``mesh_attribute`` texture named ``face_roughness``.
    bsdf, emitter : mitsuba objects, optional
    smooth : bool
        Without ``normals``: let Mitsuba compute area-weighted vertex normals,
        and recompute them whenever ``vertex_positions`` is updated (skinned
        characters).

    Returns
    -------
    mi.Mesh
    """
    import mitsuba as mi

    vertices = np.ascontiguousarray(vertices, dtype=np.float32)
    faces = np.ascontiguousarray(faces, dtype=np.uint32)
    props = mi.Properties()
    if bsdf is not None:
        props["bsdf"] = bsdf
    if emitter is not None:
        props["emitter"] = emitter
    mesh = mi.Mesh(name, len(vertices), len(faces), props, has_vertex_normals=normals is not None or smooth,
                   has_vertex_texcoords=uv is not None)
    params = mi.traverse(mesh)
    params["vertex_positions"] = float_buffer(vertices)
    params["faces"] = uint_buffer(faces)
    if normals is not None:
        params["vertex_normals"] = float_buffer(normals)
    if uv is not None:
        params["vertex_texcoords"] = float_buffer(uv)
    params.update()
    ids = np.broadcast_to(np.asarray(face_ids, dtype=np.uint32), (len(faces),))
    mesh.add_attribute(GTID_ATTRIBUTE, 3, float_buffer(encode_ids(ids)))
    if vertex_color is not None:
        mesh.add_attribute("vertex_color", 3, float_buffer(vertex_color))
    if face_roughness is not None:
        mesh.add_attribute("face_roughness", 1, float_buffer(face_roughness))
    return mesh


def flat_or_smooth(vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray | None,
                   max_angle_deg: float = 40.0) -> np.ndarray | None:
    """Keep vertex normals only where they describe a smooth surface.

    Primitives built by trimesh (a Cube) share corner vertices between faces,
    so their averaged normals would round a box's edges in the shading. If
    any face's vertex normal leans more than ``max_angle_deg`` from the face
    normal, return None (flat shading); else ``normals``.
    """
    if normals is None or len(faces) == 0:
        return None
    fn = face_normals(vertices, faces)
    vn = normals[faces]
    vn = vn / np.maximum(np.linalg.norm(vn, axis=2, keepdims=True), 1e-12)
    cos = np.einsum("fk,fvk->fv", fn, vn)
    return normals if cos.min() >= np.cos(np.radians(max_angle_deg)) else None
