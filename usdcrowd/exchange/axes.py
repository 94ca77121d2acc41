"""From usdcrowd's canonical frame to glTF's, and matrices as translation, rotation and scale.

usdcrowd's canonical frame is Z up, metres, with USD's row-vector matrices
(``p' = p @ M``, translation in the last row). glTF is Y up, metres, with
column-vector matrices stored column-major: the 16 numbers of a row-vector
matrix read row by row are exactly glTF's column-major array of the same
transform, so matrices here stay row-vector and are flattened as they are.
"""

from __future__ import annotations

import numpy as np

# p_gltf = p_canonical @ Y_UP: x stays, canonical z (up) becomes y, canonical y becomes -z.
Y_UP = np.array([[1.0, 0.0, 0.0, 0.0],
                 [0.0, 0.0, -1.0, 0.0],
                 [0.0, 1.0, 0.0, 0.0],
                 [0.0, 0.0, 0.0, 1.0]])

# Largest difference (relative to the matrix's size) between a matrix and the TRS found for it:
# beyond it the matrix has shear, which glTF nodes cannot hold.
TRS_TOLERANCE = 1e-5


def points_to_gltf(points: np.ndarray) -> np.ndarray:
    """(..., 3) canonical points or directions to glTF's axes (same metres)."""
    return np.asarray(points, dtype=np.float64) @ Y_UP[:3, :3]


def world_to_gltf(m: np.ndarray) -> np.ndarray:
    """Change the world side of local-to-world matrices only: (..., 4, 4) -> (..., 4, 4).

    The local frame keeps its axes, which is what cameras need: a USD camera
    and a glTF camera both look down their local -Z with +Y up.
    """
    return np.asarray(m, dtype=np.float64) @ Y_UP


def frame_to_gltf(m: np.ndarray) -> np.ndarray:
    """Express (..., 4, 4) transforms between canonical frames in glTF's axes on both sides.

    For joints and bind poses: products are kept (``frame_to_gltf(a @ b) ==
    frame_to_gltf(a) @ frame_to_gltf(b)``), and a bind-pose mesh converted by
    :func:`points_to_gltf` stands upright in glTF.
    """
    return Y_UP.T @ np.asarray(m, dtype=np.float64) @ Y_UP


def decompose(m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Translation, rotation and scale of row-vector matrices, as glTF nodes hold them.

    Parameters
    ----------
    m : (..., 4, 4) float
        Row-vector matrices (``p' = p @ m``) without shear.

    Returns
    -------
    translation : (..., 3) float64
    rotation : (..., 4) float64
        Unit quaternions in glTF's order (x, y, z, w).
    scale : (..., 3) float64
        Negative on x where the matrix mirrors.

    Raises
    ------
    ValueError
        A matrix has shear (or a projective part): T * R * S cannot rebuild it.
    """
    from scipy.spatial.transform import Rotation

    m = np.asarray(m, dtype=np.float64)
    # Column-vector linear part L = R @ diag(s): glTF's scale applies first, so the scales are its column norms.
    linear = np.swapaxes(m[..., :3, :3], -1, -2)
    scale = np.linalg.norm(linear, axis=-2)
    mirrored = np.linalg.det(linear) < 0
    scale[..., 0] = np.where(mirrored, -scale[..., 0], scale[..., 0])
    safe = np.where(scale == 0, 1.0, scale)           # a node scaled to nothing keeps any rotation
    rot = linear / safe[..., None, :]
    rot = np.where((scale == 0)[..., None, :], np.eye(3), rot)
    quat = Rotation.from_matrix(rot.reshape(-1, 3, 3)).as_quat().reshape(scale.shape[:-1] + (4,))
    rebuilt = Rotation.from_quat(quat.reshape(-1, 4)).as_matrix().reshape(rot.shape) * scale[..., None, :]
    size = np.maximum(np.abs(linear).max(axis=(-2, -1)), 1.0)
    error = np.abs(rebuilt - linear).max(axis=(-2, -1)) / size
    if (error > TRS_TOLERANCE).any() or np.abs(m[..., :3, 3]).max(initial=0.0) > TRS_TOLERANCE:
        raise ValueError("the transform has shear or a projective part, which glTF nodes cannot hold")
    return m[..., 3, :3].copy(), quat, scale


def continuous(quats: np.ndarray) -> np.ndarray:
    """Quaternions with signs chosen so that each is within 90 degrees of the one before (on axis 0).

    q and -q are the same rotation, but glTF interpolates between the numbers
    of two keys: a sign flip between frames would spin the long way round.

    Parameters
    ----------
    quats : (t, ..., 4) float
        One row per key.

    Returns
    -------
    (t, ..., 4)
        A copy, of the same dtype.
    """
    q = np.array(quats)
    for k in range(1, len(q)):
        flip = np.sum(q[k] * q[k - 1], axis=-1) < 0
        q[k][flip] *= -1.0
    return q
