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
