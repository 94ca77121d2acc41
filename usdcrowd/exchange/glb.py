"""The binary buffer of a GLB: arrays appended as buffer views with their accessors (pygltflib)."""

from __future__ import annotations

import numpy as np

# glTF's componentType codes and the element shapes of its accessor types.
_COMPONENT = {np.dtype(np.float32): 5126, np.dtype(np.uint32): 5125, np.dtype(np.uint16): 5123,
              np.dtype(np.uint8): 5121}
_ELEMENT = {"SCALAR": (), "VEC2": (2,), "VEC3": (3,), "VEC4": (4,), "MAT4": (4, 4)}
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963


class GlbBuffer:
    """Appends arrays to the one binary buffer of a glTF document.

    Parameters
    ----------
    gltf : pygltflib.GLTF2
        The document the views and accessors are added to.
    """

    def __init__(self, gltf):
        self.gltf = gltf
        self.blob = bytearray()

    def add(self, array: np.ndarray, kind: str, target: int | None = None, bounds: bool = False) -> int:
        """Append ``array`` and return the index of its accessor.

        Parameters
        ----------
        array : (count, *element) array
            float32, uint32, uint16 or uint8; ``element`` is the shape of
            ``kind`` (``(3,)`` for VEC3, ``(4, 4)`` for MAT4: a row-vector
            matrix, whose bytes are glTF's column-major array).
        kind : str
            SCALAR, VEC2, VEC3, VEC4 or MAT4.
        target : int, optional
            :data:`ARRAY_BUFFER` for vertex attributes, :data:`ELEMENT_ARRAY_BUFFER`
            for indices; None for animation and skin data.
        bounds : bool
            Record min and max (glTF requires them on positions and on
            animation inputs).
        """
        from pygltflib import Accessor, BufferView

        array = np.ascontiguousarray(array)
        if array.shape[1:] != _ELEMENT[kind] or array.dtype not in _COMPONENT:
            raise ValueError(f"a {kind} accessor of {array.dtype}, not of shape {array.shape}")
        self.blob += b"\0" * (-len(self.blob) % 4)          # every component type is aligned on 4 bytes here
        view = BufferView(buffer=0, byteOffset=len(self.blob), byteLength=array.nbytes, target=target)
        self.blob += array.tobytes()
        self.gltf.bufferViews.append(view)
        flat = array.reshape(len(array), -1)
        accessor = Accessor(bufferView=len(self.gltf.bufferViews) - 1, componentType=_COMPONENT[array.dtype],
                            count=len(array), type=kind,
                            min=flat.min(axis=0).tolist() if bounds else None,
                            max=flat.max(axis=0).tolist() if bounds else None)
        self.gltf.accessors.append(accessor)
        return len(self.gltf.accessors) - 1

    def finish(self) -> None:
        """Attach the buffer to the document (call once, after the last :meth:`add`)."""
        from pygltflib import Buffer

        self.blob += b"\0" * (-len(self.blob) % 4)
        self.gltf.buffers = [Buffer(byteLength=len(self.blob))]
        self.gltf.set_binary_blob(bytes(self.blob))
