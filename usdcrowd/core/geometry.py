"""Gprims as triangles: what the simulation and the renderers see of scenery.

Meshes are fan-triangulated; implicit gprims (Cube, Sphere, Cylinder, Cone,
Capsule, Plane) are tessellated with trimesh. Geometry stays in the prim's
local space and stage units; callers apply the world matrix.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class MeshData:
    """A triangle mesh in its own (local) space.

    Attributes
    ----------
    vertices : (v, 3) float32
        Positions in the prim's local space and the stage's units; the
        prim's local-to-world matrix (times the stage frame's map to
        canonical) brings them to world metres.
    faces : (f, 3) int32
    normals : (v, 3) float32 or None
    uv : (v, 2) float32 or None
    """

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None = None
    uv: np.ndarray | None = None


def triangulate(counts: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Fan-triangulate USD polygons: (f, 3) int32."""
    counts = np.asarray(counts, dtype=np.int64)
    indices = np.asarray(indices, dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    n_tri = np.maximum(counts - 2, 0)
    face = np.repeat(np.arange(len(counts)), n_tri)
    k = np.arange(n_tri.sum()) - np.repeat(np.cumsum(n_tri) - n_tri, n_tri)
    base = starts[face]
    return np.stack([indices[base], indices[base + k + 1], indices[base + k + 2]], 1).astype(np.int32)


def _check_topology(prim, points: np.ndarray, counts: np.ndarray, indices: np.ndarray) -> None:
    """A mesh whose faces cannot be built is the user's mistake: one line naming the prim and attribute."""
    from .errors import StageError

    def fail(message, attribute):
        raise StageError.at(prim, attribute, message)

    if not np.isfinite(points).all():
        fail("points must be finite numbers", "points")
    if len(counts) and counts.min() < 3:
        fail(f"a face has {int(counts.min())} vertices (at least 3)", "faceVertexCounts")
    if int(counts.sum()) != len(indices):
        fail(f"the faces use {int(counts.sum())} indices but faceVertexIndices has {len(indices)}",
             "faceVertexCounts")
    if len(indices) and (indices.min() < 0 or indices.max() >= len(points)):
        bad = int(indices.min() if indices.min() < 0 else indices.max())
        fail(f"index {bad} is outside the {len(points)} points", "faceVertexIndices")


def _dimension(prim, name: str) -> float:
    """An implicit gprim's size, radius, height, width or length: a finite number >= 0."""
    from .errors import StageError

    value = prim.GetAttribute(name).Get()
    if value is None or not np.isfinite(value) or value < 0:
        raise StageError.at(prim, name, f"must be a finite number >= 0, got {value}")
    return float(value)


def mesh_of(prim) -> MeshData | None:
    """Triangles of a gprim in its local space (stage units; scaled later by the world matrix)."""
    import trimesh
    from pxr import UsdGeom

    if prim.IsA(UsdGeom.Mesh):
        m = UsdGeom.Mesh(prim)
        points = m.GetPointsAttr().Get()
        if points is None or len(points) == 0:
            return None
        counts = np.asarray(m.GetFaceVertexCountsAttr().Get() or [], dtype=np.int64)
        indices = np.asarray(m.GetFaceVertexIndicesAttr().Get() or [], dtype=np.int64)
        _check_topology(prim, np.asarray(points, dtype=np.float64), counts, indices)
        faces = triangulate(counts, indices)
        if m.GetOrientationAttr().Get() == UsdGeom.Tokens.leftHanded:
            faces = faces[:, ::-1].copy()
        uv = None
        st = UsdGeom.PrimvarsAPI(prim).GetPrimvar("st")
        if st and st.GetInterpolation() in ("vertex", "varying"):
            uv = np.array(st.Get(), dtype=np.float32)
        return MeshData(np.array(points, dtype=np.float32), faces, None, uv)
    if prim.IsA(UsdGeom.Cube):
        size = _dimension(prim, "size")
        t = trimesh.creation.box(extents=(size, size, size))
    elif prim.IsA(UsdGeom.Sphere):
        t = trimesh.creation.icosphere(subdivisions=3, radius=_dimension(prim, "radius"))
    elif prim.IsA(UsdGeom.Cylinder) or prim.IsA(UsdGeom.Cone) or prim.IsA(UsdGeom.Capsule):
        schema_cls = (UsdGeom.Cylinder if prim.IsA(UsdGeom.Cylinder) else
                      UsdGeom.Cone if prim.IsA(UsdGeom.Cone) else UsdGeom.Capsule)
        g = schema_cls(prim)
        r, h = _dimension(prim, "radius"), _dimension(prim, "height")
        if schema_cls is UsdGeom.Cylinder:
            t = trimesh.creation.cylinder(radius=r, height=h, sections=32)
        elif schema_cls is UsdGeom.Cone:
            t = trimesh.creation.cone(radius=r, height=h, sections=32)
            t.apply_translation((0, 0, -h / 2))
        else:
            t = trimesh.creation.capsule(radius=r, height=h, count=(16, 16))
        axis = g.GetAxisAttr().Get()
        if axis == "X":
            t.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (0, 1, 0)))
        elif axis == "Y":
            t.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, (1, 0, 0)))
    elif prim.IsA(UsdGeom.Plane):
        w, l = _dimension(prim, "width"), _dimension(prim, "length")
        verts = np.array([[-w / 2, -l / 2, 0], [w / 2, -l / 2, 0], [w / 2, l / 2, 0], [-w / 2, l / 2, 0]], np.float32)
        return MeshData(verts, np.array([[0, 1, 2], [0, 2, 3]], np.int32))
    else:
        return None
    return MeshData(np.asarray(t.vertices, dtype=np.float32), np.asarray(t.faces, dtype=np.int32),
                    np.asarray(t.vertex_normals, dtype=np.float32))


def face_normals(points: np.ndarray, faces: np.ndarray, unit: bool = True) -> np.ndarray:
    """(f, 3) float64 normals of triangles ``faces`` ((f, 3) int) over ``points`` ((v, 3) float),
    counter-clockwise; of length twice the triangle's area when ``unit`` is False."""
    p = np.asarray(points, dtype=np.float64)
    fn = np.cross(p[faces[:, 1]] - p[faces[:, 0]], p[faces[:, 2]] - p[faces[:, 0]])
    return fn / np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-12) if unit else fn


def vertex_normals(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals, (v, 3) float32 (zero-area vertices get +Z)."""
    fn = face_normals(points, faces, unit=False)
    n = np.zeros((len(points), 3))
    for k in range(3):
        np.add.at(n, faces[:, k], fn)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.where(length > 1e-12, n / np.maximum(length, 1e-12), [0.0, 0.0, 1.0])
    return n.astype(np.float32)
