"""The shared body on the GPU: its levels of detail and the per-instance records.

Every character draws the same body; what differs per instance is three
skinning matrices, a palette (one colour per body region) and a track id,
packed by :func:`pack_instances` into one shader storage buffer (16 vec4 per
agent, see ``shaders.INSTANCE_STRIDE``) and applied in the vertex shader.
Each vertex carries its weights over the palette's rows, one-hot on the full
mesh and averaged where clustering merges vertices of different regions.

Levels of detail of the body (seed 004):

- ``full``: the stage's body mesh as it is;
- clustered: the same mesh after vertex clustering on 5 and 10 cm grids
  (about 550 and 170 triangles) for mid-sized characters;
- ``points``: the body's vertices ordered by an octree traversal, so that any
  prefix of the list is an evenly spread subset; a distant character draws
  the first *k* points, *k* chosen from its size on screen.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ...compiled import cache_one_process_at_a_time
from ...core.geometry import face_normals, vertex_normals

N_JOINTS = 3
# Palette rows a preview body can show (character.body.REGIONS has seven).
MAX_REGIONS = 7
# A vertex carries its weights of rows 0 to REGION_COLUMNS - 1; the last row has the rest.
REGION_COLUMNS = MAX_REGIONS - 1


@dataclass
class BodyGeometry:
    """One level of the body, ready for a vertex buffer.

    Attributes
    ----------
    vertices : (v, 15) float32
        Bind-pose position, normal, dense joint weights (legs, torso, head)
        and the weights of palette rows 0-5 (row 6 has the rest).
    indices : (3f,) int32 or None
        Triangle corners; None for a point list.
    """

    vertices: np.ndarray
    indices: np.ndarray | None

    @property
    def n_triangles(self) -> int:
        return 0 if self.indices is None else len(self.indices) // 3


@dataclass
class BodyLods:
    """The body at every level of detail (see the module docstring).

    Attributes
    ----------
    meshes : list of BodyGeometry
        The full mesh, then clustered ones, finest first.
    points : BodyGeometry
        Every vertex, in octree order.
    """

    meshes: list
    points: BodyGeometry

    @property
    def full(self) -> BodyGeometry:
        return self.meshes[0]


def dense_weights(joint_indices: np.ndarray, joint_weights: np.ndarray, n_joints: int = N_JOINTS) -> np.ndarray:
    """Scatter sparse skin weights into one column per joint.

    Parameters
    ----------
    joint_indices, joint_weights : (v, k)

    Returns
    -------
    (v, n_joints) float32
        Rows sum to 1.
    """
    v = len(joint_indices)
    w = np.zeros((v, n_joints), dtype=np.float64)
    np.add.at(w, (np.repeat(np.arange(v), joint_indices.shape[1]), joint_indices.reshape(-1)),
              joint_weights.reshape(-1))
    return (w / np.maximum(w.sum(1, keepdims=True), 1e-12)).astype(np.float32)


def cluster_mesh(points: np.ndarray, faces: np.ndarray, weights: np.ndarray, cell: float):
    """Simplify a mesh by vertex clustering on a regular grid (Lindstrom 2000).

    Vertices in the same cell merge into one placed where it best fits the
    planes of the triangles around them (the minimiser of their summed
    quadric error, pulled towards the cells' mean where that is ill-posed),
    so corners and thin limbs keep their extent instead of shrinking towards
    the mean. Weights are averaged; collapsed and duplicate triangles dropped.

    Parameters
    ----------
    points : (v, 3) float
    faces : (f, 3) int
    weights : (v, j) float
    cell : float
        Grid spacing, metres.

    Returns
    -------
    points : (v', 3) float32
    faces : (f', 3) int32
    weights : (v', j) float32
    """
    p = np.asarray(points, dtype=np.float64)
    key = np.floor(p / cell).astype(np.int64)
    _, inverse = np.unique(key, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    n = int(inverse.max()) + 1
    count = np.bincount(inverse, minlength=n).astype(np.float64)
    mean = np.stack([np.bincount(inverse, p[:, k], minlength=n) for k in range(3)], 1) / count[:, None]
    w = np.stack([np.bincount(inverse, weights[:, k], minlength=n) for k in range(weights.shape[1])], 1)
    w /= count[:, None]

    # Plane quadrics of the faces, area weighted, summed into each corner's cluster.
    fn = face_normals(p, faces, unit=False)
    area = 0.5 * np.linalg.norm(fn, axis=1)
    unit = fn / np.maximum(2.0 * area, 1e-12)[:, None]
    d = -np.einsum("fk,fk->f", unit, p[faces[:, 0]])
    A = np.zeros((n, 3, 3))
    b = np.zeros((n, 3))
    for corner in range(3):
        c = inverse[faces[:, corner]]
        np.add.at(A, c, area[:, None, None] * unit[:, :, None] * unit[:, None, :])
        np.add.at(b, c, (area * d)[:, None] * unit)
    # Tikhonov pull to the mean keeps flat or line-like clusters well posed.
    reg = 1e-3 * np.maximum(np.trace(A, axis1=1, axis2=2), 1e-9)[:, None, None] * np.eye(3)
    rhs = -b + np.einsum("nij,nj->ni", reg, mean)
    merged = np.linalg.solve(A + reg, rhs[..., None])[..., 0]
    # A representative must stay near its cell: fall back to the mean otherwise.
    far = np.linalg.norm(merged - mean, axis=1) > cell
    merged[far] = mean[far]

    f = inverse[faces]
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
    # The same triangle can survive from several source triangles: keep one
    # per vertex set (and orientation, rotated so the smallest index leads).
    lead = np.argmin(f, axis=1)
    f = np.stack([np.take_along_axis(f, ((lead + k) % 3)[:, None], 1)[:, 0] for k in range(3)], 1)
    f = np.unique(f, axis=0)
    used, remap = np.unique(f, return_inverse=True)
    return (merged[used].astype(np.float32), remap.reshape(-1, 3).astype(np.int32),
            (w[used] / w[used].sum(1, keepdims=True)).astype(np.float32))


def octree_order(points: np.ndarray, depth: int = 8) -> np.ndarray:
    """Seed 004's octree traversal: a permutation whose every prefix is spread out.

    Walking an octree by taking one point from each top-level branch in
    turn (recursively) is the same as sorting the points by their octant
    path read backwards (bit-reversed Morton code): consecutive points cycle
    through the top-level octants first.

    Parameters
    ----------
    points : (v, 3) float
    depth : int
        Octree levels.

    Returns
    -------
    (v,) int64
        Indices into ``points``.
    """
    p = np.asarray(points, dtype=np.float64)
    lo, hi = p.min(0), p.max(0)
    side = max(float((hi - lo).max()), 1e-9)
    q = np.minimum(((p - lo) / side * (1 << depth)).astype(np.int64), (1 << depth) - 1)
    key = np.zeros(len(p), dtype=np.int64)
    for level in range(depth):   # level 0 is the root's octant: least significant
        shift = depth - 1 - level
        octant = ((q[:, 0] >> shift) & 1) | (((q[:, 1] >> shift) & 1) << 1) | (((q[:, 2] >> shift) & 1) << 2)
        key |= octant << (3 * level)
    return np.argsort(key, kind="stable")


def region_weights(regions: np.ndarray | None, n: int) -> np.ndarray:
    """(n, MAX_REGIONS) float32 one-hot palette rows of ``n`` vertices (row 0 without ``regions``)."""
    r = np.zeros(n, np.int64) if regions is None else np.asarray(regions, dtype=np.int64)
    if len(r) != n or (n and (r.min() < 0 or r.max() >= MAX_REGIONS)):
        raise ValueError(f"the preview draws {MAX_REGIONS} colours per body, got rows {np.unique(r)}")
    return np.eye(MAX_REGIONS, dtype=np.float32)[r]


def body_lods(points: np.ndarray, faces: np.ndarray, joint_indices: np.ndarray, joint_weights: np.ndarray,
              cells=(0.05, 0.1), regions: np.ndarray | None = None) -> BodyLods:
    """Build every level of the shared body.

    Parameters
    ----------
    points : (v, 3) float
        Bind pose (ShotScene.body.points).
    faces : (f, 3) int
    joint_indices, joint_weights : (v, k)
    cells : sequence of float
        Clustering grids of the coarser mesh levels, metres, finest first.
    regions : (v,) int, optional
        Palette row of each vertex (ShotScene.body.regions); row 0 if omitted.
    """
    points = np.asarray(points, dtype=np.float32)
    faces = np.asarray(faces, dtype=np.int32)
    w = dense_weights(np.asarray(joint_indices), np.asarray(joint_weights))
    r = region_weights(regions, len(points))
    n = vertex_normals(points, faces)
    full = BodyGeometry(np.concatenate([points, n, w, r[:, :REGION_COLUMNS]], 1).astype(np.float32), faces.reshape(-1).copy())
    meshes = [full]
    for cell in cells:
        # Joint and region weights are averaged together, then each set renormalised.
        cp, cf, cwr = cluster_mesh(points, faces, np.concatenate([w, r], 1), cell)
        cw, cr = cwr[:, :N_JOINTS], cwr[:, N_JOINTS:]
        cw, cr = cw / cw.sum(1, keepdims=True), cr / cr.sum(1, keepdims=True)
        meshes.append(BodyGeometry(np.concatenate([cp, vertex_normals(cp, cf), cw, cr[:, :REGION_COLUMNS]], 1).astype(np.float32),
                                   cf.reshape(-1).copy()))
    order = octree_order(points)
    return BodyLods(meshes, BodyGeometry(full.vertices[order].copy(), None))


def pack_instances(skinning: np.ndarray, palettes: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """Per-instance records for the storage buffer.

    Parameters
    ----------
    skinning : (n, 3, 4, 4) float
        Row-vector skinning matrices (bind pose to world), AgentPoses.skinning.
    palettes : (n, r, 3) or (n, 3) float
        Linear RGB per palette row (r <= MAX_REGIONS); missing rows repeat row 0.
    ids : (n,) int
        Track ids (stored as uint32 bits).

    Returns
    -------
    (n, 16, 4) float32
        Rows 3j + c: column c of joint j's matrix; rows 9 + k: palette row k,
        row 9's last lane the id bits.
    """
    n = len(skinning)
    pal = _palette_rows(palettes, n)
    out = np.empty((n, 9 + MAX_REGIONS, 4), dtype=np.float32)
    # Column c of a row-vector matrix holds what dot(vec4(p, 1), .) needs.
    out[:, :9] = np.swapaxes(np.asarray(skinning), -1, -2)[:, :, :3, :].reshape(n, 9, 4)
    out[:, 9:, :3] = pal[:, :1]
    out[:, 9:9 + pal.shape[1], :3] = pal
    out[:, 9:, 3] = 0.0
    out[:, 9, 3] = np.asarray(ids, dtype=np.uint32).view(np.float32)
    return out


def _palette_rows(palettes: np.ndarray, n: int) -> np.ndarray:
    """(n, r, 3) float32 palettes of ``n`` agents, r <= MAX_REGIONS."""
    pal = np.asarray(palettes, dtype=np.float32).reshape(n, -1, 3)
    if pal.shape[1] > MAX_REGIONS:
        raise ValueError(f"the preview draws {MAX_REGIONS} colours per body, got {pal.shape[1]}")
    return pal


def _bind_translations() -> np.ndarray:
    """(3, 3) the rest pose's joint positions: its bind matrices are translations alone."""
    from ...character import rig

    if not np.allclose(rig.BIND_SKEL[:, :3, :3], np.eye(3)):
        raise AssertionError("pack_poses assumes a bind pose without rotations")
    return np.ascontiguousarray(rig.BIND_SKEL[:, 3, :3], dtype=np.float64)


def pack_poses(joints_world: np.ndarray, palettes: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """:func:`pack_instances` of the agents' skinning matrices, made from their joints in one pass.

    The rest pose has no rotation, so joint j's skinning matrix is its world
    matrix with the rest position taken off its translation (``skin(p) =
    (p - b_j) @ M_j``): a compiled loop writes the records straight from the
    joints, where forming the skinning matrices and then packing them cost
    a frame of 10,000 characters four milliseconds.

    Parameters
    ----------
    joints_world : (n, 3, 4, 4) float
        AgentPoses.joints_world.
    palettes, ids
        As :func:`pack_instances`.

    Returns
    -------
    (n, 16, 4) float32
    """
    n = len(joints_world)
    pal = _palette_rows(palettes, n)
    out = np.empty((n, 9 + MAX_REGIONS, 4), dtype=np.float32)
    _pack_poses(np.ascontiguousarray(joints_world, dtype=np.float64), _bind_translations(), np.ascontiguousarray(pal),
                np.ascontiguousarray(ids, dtype=np.uint32).view(np.float32), out)
    return out


@njit(cache=True)
def _pack_poses(joints, bind, pal, id_bits, out):
    rows = pal.shape[1]
    for i in range(joints.shape[0]):
        for j in range(3):
            for c in range(3):
                o = 3 * j + c
                t = joints[i, j, 3, c]
                for k in range(3):
                    out[i, o, k] = joints[i, j, k, c]
                    t -= bind[j, k] * joints[i, j, k, c]
                out[i, o, 3] = t
        for k in range(MAX_REGIONS):
            src = k if k < rows else 0
            for c in range(3):
                out[i, 9 + k, c] = pal[i, src, c]
            out[i, 9 + k, 3] = 0.0
        out[i, 9, 3] = id_bits[i]


cache_one_process_at_a_time(globals())
