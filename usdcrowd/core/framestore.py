"""A shot's per-frame positions on disk, read back a few frames at a time.

The cameras run once the whole crowd is known and need every agent's position
at every frame, (t, n, 3) float32: 1.2 GB for 10,000 agents x 10,000 frames.
Held in memory it would make a long shot's memory grow with its length, so
:class:`FrameStore` appends each simulated chunk to an unnamed temporary file
(removed by the system when closed, even if the process is killed) and reads
frames back on demand. For the readers it looks like a read-only array.
"""

from __future__ import annotations

import os
import tempfile

import numpy as np


class FrameStore:
    """(t, n, c) float32 frames appended in chunks, kept in an unnamed file.

    Parameters
    ----------
    n : int
        Rows per frame (agents).
    channels : int
        Values per row (3: x, y, z).
    folder : path-like, optional
        Where the temporary file lives (the output folder: a disk, where the
        system's temporary folder may be memory).

    Examples
    --------
    >>> store = FrameStore(2)
    >>> store.append(np.zeros((4, 2, 3), np.float32))
    >>> store.shape, store[1].shape, store[::2].shape
    ((4, 2, 3), (2, 3), (2, 2, 3))
    """

    ndim = 3
    dtype = np.dtype(np.float32)

    def __init__(self, n: int, channels: int = 3, folder: str | os.PathLike | None = None):
        self._file = tempfile.TemporaryFile(dir=folder)
        self._frame = (int(n), int(channels))
        self._bytes = int(n) * int(channels) * self.dtype.itemsize
        self._t = 0

    def append(self, frames: np.ndarray) -> None:
        """Add ``(m, n, c)`` frames after the last ones."""
        frames = np.ascontiguousarray(frames, dtype=self.dtype)
        if frames.shape[1:] != self._frame:
            raise ValueError(f"frames of shape {frames.shape[1:]}, expected {self._frame}")
        os.pwrite(self._file.fileno(), frames.tobytes(), self._t * self._bytes)
        self._t += len(frames)

    @property
    def shape(self) -> tuple[int, int, int]:
        return (self._t,) + self._frame

    def __len__(self) -> int:
        return self._t

    def _read(self, first: int, count: int) -> np.ndarray:
        data = os.pread(self._file.fileno(), count * self._bytes, first * self._bytes)
        return np.frombuffer(data, self.dtype).reshape((count,) + self._frame)

    def __getitem__(self, key):
        rest = ()
        if isinstance(key, tuple):
            key, rest = key[0], key[1:]
        if isinstance(key, (int, np.integer)):
            k = int(key) + (self._t if key < 0 else 0)
            if not 0 <= k < self._t:
                raise IndexError(f"frame {key} of {self._t}")
            return self._read(k, 1)[0][rest] if rest else self._read(k, 1)[0]
        elif isinstance(key, slice):
            start, stop, step = key.indices(self._t)
            if step == 1:
                out = self._read(start, max(0, stop - start))
            else:
                frames = range(start, stop, step)
                out = np.stack([self._read(k, 1)[0] for k in frames]) if len(frames) else \
                    np.empty((0,) + self._frame, self.dtype)
        else:
            raise TypeError("a FrameStore is indexed by a frame or a slice of frames")
        return out[(slice(None),) + rest] if rest else out

    def __array__(self, dtype=None, copy=None):
        """Every frame in memory (for small shots and readers that need them all)."""
        out = self._read(0, self._t)
        return out.astype(dtype) if dtype is not None else out

    def close(self) -> None:
        self._file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def frame_blocks(positions, start: int = 0, size: int = 256):
    """Consecutive blocks of at most ``size`` frames of ``positions`` from frame ``start`` on, as arrays.

    ``positions`` is a (t, n, c) array or a :class:`FrameStore`: readers that
    need every frame go through a long shot this way, a block in memory at a time.
    """
    for first in range(start, len(positions), size):
        yield np.asarray(positions[first:first + size])
