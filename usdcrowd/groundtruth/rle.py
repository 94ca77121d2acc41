"""COCO run-length encoding of masks, in numpy (no pycocotools needed to write).

COCO's uncompressed RLE: the mask is read in column-major (Fortran) order;
``counts`` alternate runs of 0 and 1, starting with a (possibly empty) run
of 0. pycocotools' ``frPyObjects`` turns it into the compressed form.
"""

from __future__ import annotations

import numpy as np


def encode_pixels(flat_cm: np.ndarray, height: int, width: int) -> dict:
    """RLE of a mask given by its pixels' column-major indices.

    Parameters
    ----------
    flat_cm : (k,) int
        ``x * height + y`` of every pixel in the mask, any order, no repeats.
    height, width : int

    Returns
    -------
    dict
        ``{"size": [height, width], "counts": [int, ...]}``.
    """
    idx = np.sort(np.asarray(flat_cm, dtype=np.int64))
    total = height * width
    if idx.size == 0:
        return {"size": [int(height), int(width)], "counts": [int(total)]}
    breaks = np.flatnonzero(np.diff(idx) != 1) + 1
    starts = idx[np.concatenate([[0], breaks])]
    ends = idx[np.concatenate([breaks - 1, [idx.size - 1]])] + 1          # exclusive
    gaps = starts - np.concatenate([[0], ends[:-1]])
    counts = np.empty(2 * len(starts) + 1, dtype=np.int64)
    counts[0:-1:2] = gaps
    counts[1::2] = ends - starts
    counts[-1] = total - ends[-1]
    if counts[-1] == 0:
        counts = counts[:-1]
    return {"size": [int(height), int(width)], "counts": counts.tolist()}


def encode(mask: np.ndarray) -> dict:
    """RLE of a (h, w) bool mask."""
    h, w = mask.shape
    return encode_pixels(np.flatnonzero(np.asarray(mask, bool).T.ravel()), h, w)


def decode(rle: dict) -> np.ndarray:
    """(h, w) bool mask of an uncompressed RLE."""
    h, w = rle["size"]
    counts = np.asarray(rle["counts"], dtype=np.int64)
    values = np.arange(len(counts)) % 2 == 1
    return np.repeat(values, counts).reshape(w, h).T
