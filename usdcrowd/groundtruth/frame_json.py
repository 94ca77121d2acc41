"""The per-frame annotation file: one JSON document per frame and camera.

It is the source the sequence exporters (:mod:`.mot`, :mod:`.coco`,
:mod:`.contact_sheet`) read, so a resumed render rebuilds them from frames
it did not render again. Layout: see :func:`~.annotate.annotate_frame`;
``frame_index`` (1-based position in the sequence) and ``files`` (the
frame's other outputs, relative to the output folder) are added.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence

from ..atomic import atomic_path

SCHEMA = "usdcrowd.groundtruth.frame/1"


def write(record: dict, path) -> str:
    """Write ``record`` as JSON at ``path`` atomically."""
    record = {"schema": SCHEMA, **record}
    with atomic_path(path) as tmp:
        with open(tmp, "w") as f:
            json.dump(record, f, separators=(",", ":"))
    return os.fspath(path)


def read(path) -> dict:
    """Read one frame record."""
    with open(path) as f:
        record = json.load(f)
    if record.get("schema") != SCHEMA:
        raise ValueError(f"{path}: not a usdcrowd frame record")
    return record


class Records(Sequence):
    """The frame records of a sequence, read from their files when asked for.

    A long sequence's records (a dict per agent per frame) would not fit in
    memory together; the exporters go through them one at a time.

    Parameters
    ----------
    paths : list of path-like
        One JSON file per frame, in sequence order.
    """

    def __init__(self, paths):
        self.paths = [os.fspath(p) for p in paths]

    def __len__(self) -> int:
        return len(self.paths)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return Records(self.paths[i])
        return read(self.paths[i])
