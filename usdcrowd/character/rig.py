"""The three-joint skeleton (seed 003: legs, torso, head) and its maths.

Canonical character: 1.75 m tall, standing at the origin, facing +X, Z up,
metres. Per-agent height and placement are applied by the SkelRoot's
transform, never here.

Matrix convention: USD's row-vector one throughout, so arrays can be handed
to ``Gf.Matrix4d`` / ``Vt.Matrix4dArray`` unchanged:

- a point transforms as ``p' = p @ M`` (homogeneous row vector), the
  translation sits in the last row ``M[3, :3]``;
- a child's skeleton-space matrix is ``local @ parent_skel``.

Quaternions are ``(..., 4)`` float arrays ordered ``(w, x, y, z)``, unit,
Hamilton product. With the row convention the skeleton-space rotation of a
child is ``quat_multiply(q_parent_skel, q_local)`` (the usual order).
``Vt.QuatfArray.FromNumpy`` wants ``(x, y, z, w)`` instead: see
:func:`to_usd_quat_order`.
"""

from __future__ import annotations

import numpy as np

JOINTS = ("legs", "legs/torso", "legs/torso/head")
PARENT = (-1, 0, 1)

PELVIS_HEIGHT = 0.95  # legs joint: hips, where both legs swing from
WAIST_HEIGHT = 1.05  # torso joint: bends above the pelvis
NECK_HEIGHT = 1.50  # head joint
HEAD_TOP = 1.75  # canonical body height
EYE_HEIGHT = 1.63  # eye level of the canonical body

# Rest pose: no rotation, joints stacked on the Z axis.
REST_TRANSLATIONS = np.array([[0.0, 0.0, PELVIS_HEIGHT],
                              [0.0, 0.0, WAIST_HEIGHT - PELVIS_HEIGHT],
                              [0.0, 0.0, NECK_HEIGHT - WAIST_HEIGHT]])
REST_ROTATIONS = np.tile(np.array([1.0, 0.0, 0.0, 0.0]), (3, 1))

KEYPOINT_NAMES = ("pelvis", "waist", "neck", "headTop", "ground")


# --------------------------------------------------------------------------
# Quaternions, (..., 4) as (w, x, y, z)
# --------------------------------------------------------------------------

def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b`` (apply ``b`` first, then ``a``).

    Parameters
    ----------
    a, b : (..., 4) float
        Quaternions (w, x, y, z); broadcast against each other.

    Returns
    -------
    (..., 4) float
    """
    a, b = np.asarray(a), np.asarray(b)
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    # Written into one preallocated array: stacking four temporaries costs
    # as much again, and this product is the animation writer's hot loop.
    out = np.empty(np.broadcast_shapes(a.shape, b.shape), dtype=np.result_type(a, b, np.float32))
    out[..., 0] = aw * bw - ax * bx - ay * by - az * bz
    out[..., 1] = aw * bx + ax * bw + ay * bz - az * by
    out[..., 2] = aw * by - ax * bz + ay * bw + az * bx
    out[..., 3] = aw * bz + ax * by - ay * bx + az * bw
    return out


def wrap_angle(a):
    """Angles (radians) wrapped into [-pi, pi)."""
    return np.mod(np.asarray(a) + np.pi, 2.0 * np.pi) - np.pi


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """Conjugate (the inverse of a unit quaternion), (..., 4)."""
    return np.asarray(q) * np.array([1.0, -1.0, -1.0, -1.0])


def quat_from_axis_angle(axis, angle) -> np.ndarray:
    """Rotation by ``angle`` radians about ``axis`` (right-hand rule).

    Parameters
    ----------
    axis : (..., 3) float
        Rotation axis, need not be unit.
    angle : (...) float
        Radians; broadcast against ``axis[..., 0]``.

    Returns
    -------
    (..., 4) float
        Unit quaternions (w, x, y, z).
    """
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    half = 0.5 * np.asarray(angle, dtype=np.float64)
    out = np.empty(np.broadcast_shapes(axis.shape[:-1], half.shape) + (4,))
    out[..., 0] = np.cos(half)
    sin = np.sin(half)
    for k in range(3):
        if axis.ndim == 1 and axis[k] == 0.0:      # coordinate axes: skip the zero products
            out[..., k + 1] = 0.0
        else:
            out[..., k + 1] = sin * axis[..., k]
    return out


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """3x3 rotation matrices in the ROW-vector convention: ``v' = v @ R``.

    This is the transpose of the textbook (column-vector) matrix, and what
    ``Gf.Matrix4d().SetRotate(Gf.Quatd(w, x, y, z))`` puts in the upper-left
    block.

    Parameters
    ----------
    q : (..., 4) float
        Unit quaternions (w, x, y, z).

    Returns
    -------
    (..., 3, 3) float
    """
    w, x, y, z = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)
    col = np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], axis=-2)
    return np.swapaxes(col, -1, -2)


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors ``v`` (..., 3) by unit quaternions ``q`` (..., 4)."""
    return np.einsum("...i,...ij->...j", v, quat_to_matrix(q))


def quat_angle(q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
    """Angle in radians of the rotation taking ``q0`` to ``q1``, (...) in [0, pi]."""
    d = np.abs(np.sum(np.asarray(q0) * np.asarray(q1), axis=-1))
    return 2.0 * np.arccos(np.clip(d, 0.0, 1.0))


def quat_slerp(q0: np.ndarray, q1: np.ndarray, t) -> np.ndarray:
    """Spherical linear interpolation along the shorter arc.

    Parameters
    ----------
    q0, q1 : (..., 4) float
        Unit quaternions.
    t : (...) float
        0 gives ``q0``, 1 gives ``q1``; broadcast against ``q0[..., 0]``.

    Returns
    -------
    (..., 4) float
        Unit quaternions.
    """
    q0 = np.asarray(q0, dtype=np.float64)
    q1 = np.asarray(q1, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)[..., None]
    d = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(d < 0, -q1, q1)  # q and -q are the same rotation
    d = np.abs(d)
    theta = np.arccos(np.clip(d, 0.0, 1.0))
    s = np.sin(theta)
    near = s < 1e-6  # nearly equal: the weights below are 0/0, lerp is exact enough
    safe = np.where(near, 1.0, s)
    w0 = np.where(near, 1.0 - t, np.sin((1.0 - t) * theta) / safe)
    w1 = np.where(near, t, np.sin(t * theta) / safe)
    q = w0 * q0 + w1 * q1
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def to_usd_quat_order(q: np.ndarray) -> np.ndarray:
    """Reorder (w, x, y, z) quaternions for ``Vt.QuatfArray.FromNumpy``.

    ``GfQuatf`` stores its imaginary part first, so ``FromNumpy`` reads each
    row as (x, y, z, w) even though the ``Gf.Quatf(w, x, y, z)`` constructor
    takes the real part first.

    Parameters
    ----------
    q : (..., 4) float
        (w, x, y, z).

    Returns
    -------
    (..., 4) same dtype, C-contiguous
        (x, y, z, w).
    """
    return np.ascontiguousarray(np.roll(np.asarray(q), -1, axis=-1))


# --------------------------------------------------------------------------
# Skeleton
# --------------------------------------------------------------------------

def compose_local(rotations: np.ndarray, translations: np.ndarray) -> np.ndarray:
    """Local joint matrices from rotations and translations (scale 1).

    Parameters
    ----------
    rotations : (..., 3, 4) float
        Joint-local quaternions (w, x, y, z).
    translations : (..., 3, 3) float
        Joint-local translations, metres.

    Returns
    -------
    (..., 3, 4, 4) float64
        Row-vector matrices (translation in the last row).
    """
    rotations = np.asarray(rotations, dtype=np.float64)
    translations = np.asarray(translations, dtype=np.float64)
    shape = np.broadcast_shapes(rotations.shape[:-1], translations.shape[:-1])
    m = np.zeros(shape + (4, 4))
    m[..., :3, :3] = quat_to_matrix(rotations)
    m[..., 3, :3] = translations
    m[..., 3, 3] = 1.0
    return m


def local_to_skel(local: np.ndarray) -> np.ndarray:
    """Concatenate local matrices down the hierarchy: ``skel = local @ parent_skel``.

    Parameters
    ----------
    local : (..., 3, 4, 4) float
        Joint-local matrices.

    Returns
    -------
    (..., 3, 4, 4) float64
        Skeleton-space matrices.
    """
    local = np.asarray(local, dtype=np.float64)
    skel = np.empty_like(local)
    for j, p in enumerate(PARENT):  # parents come first in JOINTS
        skel[..., j, :, :] = local[..., j, :, :] if p < 0 else local[..., j, :, :] @ skel[..., p, :, :]
    return skel


REST_LOCAL = compose_local(REST_ROTATIONS, REST_TRANSLATIONS)
BIND_SKEL = local_to_skel(REST_LOCAL)
_BIND_INV = np.linalg.inv(BIND_SKEL)


def skinning_transforms(skel: np.ndarray) -> np.ndarray:
    """``inverse(BIND_SKEL) @ skel`` per joint, as UsdSkel computes them.

    Parameters
    ----------
    skel : (..., 3, 4, 4) float
        Skeleton-space joint matrices.

    Returns
    -------
    (..., 3, 4, 4) float64
    """
    return _BIND_INV @ np.asarray(skel, dtype=np.float64)


def skin_points(points: np.ndarray, joint_indices: np.ndarray, joint_weights: np.ndarray,
                skinning: np.ndarray, geom_bind: np.ndarray | None = None) -> np.ndarray:
    """Linear blend skinning, matching UsdSkel's ``ComputeSkinnedPoints``.

    Parameters
    ----------
    points : (v, 3) float
        Bind-pose points in the mesh's own space.
    joint_indices : (v, k) int
        Influencing joints of each point.
    joint_weights : (v, k) float
        Their weights (expected to sum to 1 per row).
    skinning : (..., 3, 4, 4) float
        Skinning transforms (:func:`skinning_transforms`).
    geom_bind : (4, 4) float, optional
        ``skel:geomBindTransform``, applied to the points first; identity if
        None.

    Returns
    -------
    (..., v, 3) float64
        Skinned points in skeleton space.
    """
    p = np.asarray(points, dtype=np.float64)
    if geom_bind is not None:
        g = np.asarray(geom_bind, dtype=np.float64)
        p = p @ g[:3, :3] + g[3, :3]
    skinning = np.asarray(skinning, dtype=np.float64)
    # Blend the matrices per point (cheaper than skinning k times): (..., v, 4, 4).
    m = np.einsum("vk,...vkij->...vij", np.asarray(joint_weights, dtype=np.float64),
                  skinning[..., np.asarray(joint_indices), :, :])
    return np.einsum("vi,...vij->...vj", p, m[..., :3, :3]) + m[..., 3, :3]


def joint_positions(skel: np.ndarray) -> np.ndarray:
    """Skeleton-space joint origins, (..., 3, 3) from (..., 3, 4, 4)."""
    return np.asarray(skel)[..., 3, :3].copy()


def keypoints(skel: np.ndarray) -> np.ndarray:
    """Named skeleton-space points for tracking ground truth.

    Parameters
    ----------
    skel : (..., 3, 4, 4) float
        Skeleton-space joint matrices.

    Returns
    -------
    (..., 5, 3) float64
        Rows in :data:`KEYPOINT_NAMES` order: pelvis, waist, neck, head top
        (follows the head's rotation), and the ground point under the pelvis
        (z = 0).
    """
    skel = np.asarray(skel, dtype=np.float64)
    joints = joint_positions(skel)
    top = np.array([0.0, 0.0, HEAD_TOP - NECK_HEIGHT, 1.0]) @ skel[..., 2, :, :]
    ground = joints[..., 0, :] * np.array([1.0, 1.0, 0.0])
    return np.concatenate([joints, top[..., None, :3], ground[..., None, :]], axis=-2)
