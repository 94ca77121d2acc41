"""The skinned low-poly body bound to the three-joint skeleton.

A concatenation of closed trimesh primitives (legs, feet, torso, arms, neck,
head, nose, eyes, mouth), so the whole is watertight without any boolean union. Points are
in the canonical character space, which is also skeleton space: 1.75 m tall,
feet at z = 0, facing +X (feet and nose point that way).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from .rig import HEAD_TOP, NECK_HEIGHT, PELVIS_HEIGHT, WAIST_HEIGHT

# Blend zones (metres, bind pose) where a vertex's weight moves between two
# joints, so the mesh bends instead of shearing at the joints.
WAIST_BLEND = (PELVIS_HEIGHT - 0.07, WAIST_HEIGHT + 0.03)
NECK_BLEND = (NECK_HEIGHT - 0.04, NECK_HEIGHT + 0.06)

# What each vertex is dressed in; rows of an agent's palette (character.appearance).
# "top" comes first: it is the colour a character is known by where only one is drawn.
# The eyes' whites, and the "face": irises and mouth. Without them a pose
# detector (BlazePose) takes a character facing the camera for one seen from
# behind; whites show on dark skin, the dark marks on light skin.
REGIONS = ("top", "trousers", "skin", "hair", "shoes", "eye_whites", "face")
HAIRLINE = HEAD_TOP - 0.075     # the crown is hair all round
NAPE = HEAD_TOP - 0.16          # hair reaches down to here at the back of the head


@dataclass(frozen=True)
class Body:
    """Bind-pose body mesh and its skin weights.

    Attributes
    ----------
    points : (v, 3) float32
        Bind-pose points, skeleton space.
    face_vertex_counts : (f,) int32
        All 3.
    face_vertex_indices : (3f,) int32
    normals : (v, 3) float32
        Vertex normals.
    joint_indices : (v, 2) int32
        Influencing joints, heaviest first.
    joint_weights : (v, 2) float32
        Matching weights, rows sum to 1, sorted descending.
    regions : (v,) int32
        Row of :data:`REGIONS` each vertex belongs to.
    mesh : trimesh.Trimesh
        The same geometry as a trimesh.
    """

    points: np.ndarray
    face_vertex_counts: np.ndarray
    face_vertex_indices: np.ndarray
    normals: np.ndarray
    joint_indices: np.ndarray
    joint_weights: np.ndarray
    regions: np.ndarray
    mesh: trimesh.Trimesh

    @property
    def triangle_count(self) -> int:
        return len(self.face_vertex_counts)


def _smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _capsule(bottom: float, top: float, radius: float, count, xy=(0.0, 0.0)):
    """Vertical capsule spanning z in [bottom, top]."""
    import trimesh

    m = trimesh.creation.capsule(height=top - bottom - 2 * radius, radius=radius, count=count)
    m.apply_translation([xy[0], xy[1], 0.5 * (bottom + top)])
    return m


def _ellipsoid(center, radii, subdivisions):
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=subdivisions)
    m.apply_scale(radii)
    m.apply_translation(center)
    return m


def _parts():
    """(mesh, kind, dress) triples; kind picks the weighting rule, dress the region (:func:`_regions`)."""
    import trimesh

    parts = []
    for side in (1.0, -1.0):
        parts.append((_capsule(0.0, PELVIS_HEIGHT + 0.03, 0.075, [12, 8], (0.0, 0.1 * side)), "legs", "trousers"))
        foot = trimesh.creation.box(extents=[0.24, 0.095, 0.07])
        foot.apply_translation([0.06, 0.1 * side, 0.035])
        parts.append((foot, "legs", "shoes"))
        # Sleeve and hand are separate closed parts, so the colour changes at the wrist.
        parts.append((_capsule(0.90, 1.46, 0.045, [10, 6], (0.0, 0.235 * side)), "torso", "top"))
        parts.append((_ellipsoid([0.0, 0.235 * side, 0.88], [0.035, 0.03, 0.055], 1), "torso", "skin"))
    torso = _capsule(PELVIS_HEIGHT - 0.1, NECK_HEIGHT, 0.18, [16, 8])
    torso.apply_transform(np.diag([0.65, 1.0, 1.0, 1.0]))  # flatter front to back
    parts.append((torso, "torso", "top"))
    neck = trimesh.creation.cylinder(radius=0.05, height=0.14, sections=12)
    neck.apply_translation([0.0, 0.0, NECK_HEIGHT])
    parts.append((neck, "neck", "skin"))
    head = _ellipsoid([0.0, 0.0, 0.0], [0.105, 0.09, 0.12], 2)
    head.apply_translation([0.0, 0.0, HEAD_TOP - head.bounds[1, 2]])  # top exactly at 1.75
    parts.append((head, "head", "head"))
    parts.append((_ellipsoid([0.1, 0.0, HEAD_TOP - 0.13], [0.025, 0.02, 0.025], 0), "head", "skin"))
    parts.extend((m, "head", dress) for m, dress in _face(head))
    return parts


def _face(head) -> list:
    """(mesh, dress) of the eyes (whites, irises in front) and the mouth: flat ellipsoids half sunk into the
    front of the head, an adult's proportions (eyes 6.6 cm apart, 3 cm above the nose's tip; the mouth 3.5 cm
    below it, 5 cm wide)."""
    c = head.bounds.mean(axis=0)
    r = 0.5 * (head.bounds[1] - head.bounds[0])

    def on_front(y, z):
        """The head's front surface at (y, z): x on the ellipsoid."""
        return c[0] + r[0] * np.sqrt(max(1.0 - ((y - c[1]) / r[1]) ** 2 - ((z - c[2]) / r[2]) ** 2, 0.0))

    nose_z = HEAD_TOP - 0.13
    out = []
    for y in (0.033, -0.033):
        x = on_front(y, nose_z + 0.03)
        out.append((_ellipsoid([x - 0.004, y, nose_z + 0.03], [0.01, 0.016, 0.01], 1), "eye_whites"))
        out.append((_ellipsoid([x + 0.004, y, nose_z + 0.03], [0.004, 0.007, 0.007], 1), "face"))
    out.append((_ellipsoid([on_front(0.0, nose_z - 0.035) - 0.003, 0.0, nose_z - 0.035], [0.008, 0.025, 0.006], 1),
                "face"))
    return out


def _regions(p: np.ndarray, dress: str) -> np.ndarray:
    """(v,) rows of REGIONS for one part's vertices ``p`` (v, 3): a part's own, or skin and hair on the head."""
    code = {name: k for k, name in enumerate(REGIONS)}
    if dress == "head":
        # The face looks along +X: hair covers the crown and, behind the ears, down to the nape.
        hair = (p[:, 2] > HAIRLINE) | ((p[:, 2] > NAPE) & (p[:, 0] < -0.02))
        return np.where(hair, code["hair"], code["skin"])
    return np.full(len(p), code[dress])


def _weights(z: np.ndarray, kind: str):
    """(v, 2) joint indices and weights for one part's vertices at heights z."""
    one = np.ones_like(z)
    if kind == "legs":
        return np.stack([0 * one, 1 * one], -1), np.stack([one, 0 * one], -1)
    if kind == "head":
        return np.stack([2 * one, 1 * one], -1), np.stack([one, 0 * one], -1)
    lo, hi, a, b = ((*WAIST_BLEND, 0, 1) if kind == "torso" else (*NECK_BLEND, 1, 2))
    wb = _smoothstep((z - lo) / (hi - lo))  # weight of the upper joint b
    return np.stack([a * one, b * one], -1), np.stack([1.0 - wb, wb], -1)


@functools.lru_cache(maxsize=None)
def build_body() -> Body:
    """The canonical body (cached: every call returns the same object).

    Returns
    -------
    Body
        About 1,850 triangles, watertight, 1.75 m tall.
    """
    import trimesh        # here, not at the top: the crowd layer's part writers import this module, never build

    parts = _parts()
    idx, wts = zip(*(_weights(m.vertices[:, 2], kind) for m, kind, _ in parts))
    # process=False: keep every part's vertices as they are, so the weights
    # stay aligned and touching parts are never merged into non-manifold edges.
    offsets = np.cumsum([0] + [len(m.vertices) for m, _, _ in parts])
    mesh = trimesh.Trimesh(vertices=np.concatenate([m.vertices for m, _, _ in parts]),
                           faces=np.concatenate([m.faces + o for (m, _, _), o in zip(parts, offsets)]),
                           process=False)
    regions = np.concatenate([_regions(np.asarray(m.vertices), dress) for m, _, dress in parts])
    idx, wts = np.concatenate(idx), np.concatenate(wts)
    order = np.argsort(-wts, axis=1, kind="stable")
    idx = np.take_along_axis(idx, order, axis=1)
    wts = np.take_along_axis(wts, order, axis=1)
    faces = mesh.faces.astype(np.int32)
    return Body(points=mesh.vertices.astype(np.float32),
                face_vertex_counts=np.full(len(faces), 3, np.int32),
                face_vertex_indices=faces.reshape(-1),
                normals=np.asarray(mesh.vertex_normals, dtype=np.float32),
                joint_indices=idx.astype(np.int32),
                joint_weights=wts.astype(np.float32),
                regions=regions.astype(np.int32),
                mesh=mesh)
