"""The glTF document being assembled: its nodes and the animation keys of their values."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .axes import continuous, decompose
from .glb import GlbBuffer


@dataclass
class Document:
    """The glTF document being assembled, its binary buffer, and the animation's channels and samplers
    (all keyed at ``time_input``: seconds of the exported frames; None for a single frame)."""

    gltf: object
    buffer: GlbBuffer
    time_input: int | None
    channels: list = field(default_factory=list)
    samplers: list = field(default_factory=list)


def add_node(doc: Document, **fields) -> int:
    """Append a node (pygltflib.Node fields) and return its index."""
    from pygltflib import Node

    doc.gltf.nodes.append(Node(**fields))
    return len(doc.gltf.nodes) - 1


def animate(doc: Document, node: int, path: str, values: np.ndarray, interpolation: str = "LINEAR") -> None:
    """Set the node's ``path`` (translation, rotation, scale) to its first value, and key it over the
    frames where it changes at all.

    Parameters
    ----------
    values : (t, k) float
        One row per exported frame (k = 3, or 4 for rotations).
    """
    from pygltflib import AnimationChannel, AnimationChannelTarget, AnimationSampler

    values = np.asarray(values, dtype=np.float32)
    setattr(doc.gltf.nodes[node], path, values[0].tolist())
    if doc.time_input is None or np.all(values == values[0]):
        return
    kind = "VEC4" if values.shape[1] == 4 else "VEC3"
    doc.samplers.append(AnimationSampler(input=doc.time_input, output=doc.buffer.add(values, kind),
                                         interpolation=interpolation))
    doc.channels.append(AnimationChannel(sampler=len(doc.samplers) - 1,
                                         target=AnimationChannelTarget(node=node, path=path)))


def animate_matrices(doc: Document, node: int, matrices: np.ndarray) -> None:
    """Key a node with (t, 4, 4) row-vector matrices (glTF axes) as translation, rotation and scale."""
    translation, rotation, scale = decompose(matrices)
    animate(doc, node, "translation", translation)
    animate(doc, node, "rotation", continuous(rotation))
    animate(doc, node, "scale", scale)
