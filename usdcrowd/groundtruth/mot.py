"""MOTChallenge export: ``gt/gt.txt`` and ``seqinfo.ini`` (MOT16/17 layout).

``gt.txt`` has one line per agent and frame,
``frame,id,bb_left,bb_top,bb_width,bb_height,conf,class,visibility``:

- ``frame``: 1-based index of the frame in the rendered sequence (the time
  code of each index is in ``frames.csv`` beside it);
- ``id``: the agent's track id (``crowd:agentId``);
- the box: the full (amodal) body box, MOTChallenge's convention, with
  1-based pixel coordinates (``bb_left = x + 1``); it may leave the image;
- ``conf``: 1 (to be evaluated), 0 for agents that are not people;
- ``class``: 1 (pedestrian), 8 (distractor) for non-human characters;
- ``visibility``: visible pixels / pixels rendered alone, in [0, 1].

Agents enter when at least one pixel centre of their body is in view.
``img1/`` holds the display frames under MOT's names (hard links when possible).
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from .. import guard
from ..atomic import atomic_path

PEDESTRIAN, DISTRACTOR = 1, 8


def write_mot(records, out_dir, name: str = "usdcrowd", fps: float = 24.0,
              images: list[str | None] | None = None) -> str:
    """Write a MOTChallenge sequence folder from frame records.

    Parameters
    ----------
    records : sequence of dict
        Frame records in sequence order (see :mod:`.frame_json`; a
        :class:`.frame_json.Records` reads them one at a time).
    out_dir : path-like
        The sequence folder (``gt/gt.txt``, ``seqinfo.ini``, ``frames.csv``, ``img1/``).
    name : str
        Sequence name.
    fps : float
        Frame rate of the rendered sequence (time codes per second / stride).
    images : list of path or None, optional
        Display PNG of each record, linked into ``img1/`` as ``000001.png``...

    Returns
    -------
    str
        Path of ``gt/gt.txt``.
    """
    out = Path(out_dir)
    gt = out / "gt" / "gt.txt"
    guard.make_dir(gt.parent)
    times = []
    # Frame by frame: records may be read from disk one at a time (frame_json.Records).
    with atomic_path(gt) as tmp, open(tmp, "w") as f:
        for index, rec in enumerate(records, start=1):
            times.append(rec["time"])
            for a in rec["agents"]:
                if a.get("bbox_amodal") is None:
                    continue
                x, y, bw, bh = a["bbox_amodal"]
                human = a.get("character_type", "human") == "human"
                f.write(f"{index},{a['track_id']},{x + 1:.2f},{y + 1:.2f},{bw:.2f},{bh:.2f},"
                        f"{1 if human else 0},{PEDESTRIAN if human else DISTRACTOR},{a['visibility']:.4f}\n")
    first = records[0] if len(records) else {}
    w, h = first.get("width", 0), first.get("height", 0)
    with atomic_path(out / "seqinfo.ini") as tmp:
        tmp.write_text(f"[Sequence]\nname={name}\nimDir=img1\nframeRate={fps:g}\nseqLength={len(records)}\n"
                       f"imWidth={w}\nimHeight={h}\nimExt=.png\n")
    with atomic_path(out / "frames.csv") as tmp:
        tmp.write_text("frame,time_code\n" + "".join(f"{i},{t:g}\n" for i, t in enumerate(times, 1)))
    if images:
        img_dir = out / "img1"
        guard.make_dir(img_dir)
        for i, src in enumerate(images, start=1):
            if src is None or not os.path.exists(src):
                continue
            dst = img_dir / f"{i:06d}.png"
            if dst.exists():
                dst.unlink()
            try:
                os.link(src, dst)
            except OSError:
                shutil.copyfile(src, dst)
    return os.fspath(gt)


def read_mot(path) -> list[tuple]:
    """Parse a gt.txt: list of (frame, id, left, top, width, height, conf, class, visibility)."""
    rows = []
    for line in Path(path).read_text().splitlines():
        if line.strip():
            f, i, x, y, w, h, c, k, v = line.split(",")
            rows.append((int(f), int(i), float(x), float(y), float(w), float(h), int(c), int(k), float(v)))
    return rows
