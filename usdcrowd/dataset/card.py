"""The dataset card: ``DATASET/README.md`` with counts per split and ``card.png`` with the distributions.

Counted from the per-frame records as the merge reads them (never all in
memory): boxes per frame, each box's visibility and on-screen height, the
agents per sequence and in view per frame, and the cameras by kind.
"""

from __future__ import annotations

import os
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..atomic import atomic_path


@dataclass
class CardStats:
    """Running counts of a dataset (see the module docstring)."""

    sequences: Counter = field(default_factory=Counter)          # split -> sequences
    videos: Counter = field(default_factory=Counter)             # split -> videos (sequence x camera)
    frames: Counter = field(default_factory=Counter)             # split -> frames
    boxes: Counter = field(default_factory=Counter)              # split -> visible boxes
    tracks: Counter = field(default_factory=Counter)             # split -> tracks (per video)
    kinds: Counter = field(default_factory=Counter)              # camera kind -> videos
    agents: list = field(default_factory=list)                   # agents per sequence
    per_frame: list = field(default_factory=list)                # visible boxes per frame
    visibility: list = field(default_factory=list)               # per visible box
    height: list = field(default_factory=list)                   # amodal box height, pixels
    templates: Counter = field(default_factory=Counter)
    _split: str = ""

    def add_sequence(self, seq) -> None:
        self._split = seq.split
        self.sequences[seq.split] += 1
        self.agents.append(seq.agents)

    def add_video(self, kind: str, records) -> None:
        split = self._split
        self.videos[split] += 1
        self.kinds[kind] += 1
        tracks = set()
        for rec in records:
            self.frames[split] += 1
            seen = [a for a in rec["agents"] if a["visible_pixels"] > 0]
            self.per_frame.append(len(seen))
            self.boxes[split] += len(seen)
            for a in seen:
                tracks.add(a["track_id"])
                self.visibility.append(a["visibility"])
                if a.get("bbox_amodal") is not None:
                    self.height.append(a["bbox_amodal"][3])
        self.tracks[split] += len(tracks)


def _figure(stats: CardStats, path: Path) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 3, figsize=(12, 6.5))
    ax = ax.ravel()
    ax[0].hist(stats.per_frame, bins=min(30, max(stats.per_frame + [1]) + 1), color="#4c72b0")
    ax[0].set(title="people in view per frame", xlabel="visible boxes", ylabel="frames")
    ax[1].hist(stats.visibility, bins=20, range=(0, 1), color="#55a868")
    ax[1].set(title="visibility of each box", xlabel="visible / unoccluded pixels", ylabel="boxes")
    ax[2].hist(stats.height, bins=30, color="#c44e52")
    ax[2].set(title="on-screen height", xlabel="amodal box height (px)", ylabel="boxes")
    occl = np.asarray(stats.visibility, dtype=np.float64)
    levels = ["none\n(>= 0.99)", "light\n0.75-0.99", "partial\n0.25-0.75", "heavy\n< 0.25"]
    counts = [np.sum(occl >= 0.99), np.sum((occl >= 0.75) & (occl < 0.99)),
              np.sum((occl >= 0.25) & (occl < 0.75)), np.sum(occl < 0.25)]
    ax[3].bar(levels, counts, color="#8172b2")
    ax[3].set(title="occlusion", ylabel="boxes")
    ax[4].hist(stats.agents, bins=min(20, max(len(set(stats.agents)), 1)), color="#937860")
    ax[4].set(title="crowd size", xlabel="agents per sequence", ylabel="sequences")
    kinds = sorted(stats.kinds)
    ax[5].bar(kinds, [stats.kinds[k] for k in kinds], color="#da8bc3")
    ax[5].set(title="cameras", ylabel="videos")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=80, format="png")
    plt.close(fig)
    return os.fspath(path)


def write_card(out: Path, spec, stats: CardStats) -> dict:
    """``README.md`` and ``card.png`` in the dataset folder; returns kind -> path."""
    figure = _figure(stats, Path(out) / "card.png")
    splits = [s for s in ("train", "val", "test") if stats.sequences[s]]
    rows = "\n".join(f"| {s} | {stats.sequences[s]} | {stats.videos[s]} | {stats.frames[s]:,} | "
                     f"{stats.boxes[s]:,} | {stats.tracks[s]:,} |" for s in splits)
    total = (f"| all | {sum(stats.sequences.values())} | {sum(stats.videos.values())} | "
             f"{sum(stats.frames.values()):,} | {sum(stats.boxes.values()):,} | {sum(stats.tracks.values()):,} |")
    vis = np.asarray(stats.visibility) if stats.visibility else np.zeros(1)
    h = np.asarray(stats.height) if stats.height else np.zeros(1)
    per = defaultdict(int, stats.kinds)
    text = f"""# {spec.name}

Synthetic crowd video with exact ground truth, made by `usdcrowd dataset` from
`spec.toml` (sha256 `{spec.digest()[:16]}`, seed {spec.seed}). Every sequence
is a USD stage under `sequences/` that re-makes it alone; its random draws are
in its `plan.json` and in the scenario stage's `customLayerData`.

| split | sequences | videos | frames | boxes | tracks |
|---|---|---|---|---|---|
{rows}
{total}

- Resolution {spec.resolution[0]}x{spec.resolution[1]}, render preset `{spec.preset}`,
  {spec.frames} frames per video (every {spec.stride} simulated frame(s)).
- Cameras: {", ".join(f"{per[k]} {k}" for k in sorted(per))} videos.
- Visibility of the boxes: median {np.median(vis):.2f}, {np.mean(vis < 0.5) * 100:.0f} % under 0.5.
- On-screen height: median {np.median(h):.0f} px, 5th to 95th percentile {np.percentile(h, 5):.0f} to
  {np.percentile(h, 95):.0f} px.
- Crowds of {min(stats.agents, default=0)} to {max(stats.agents, default=0)} agents.

![distributions](card.png)

## Layout

- `mot/USDCROWD-<split>/<sequence>-<camera>/`: MOTChallenge (`gt/gt.txt`, `seqinfo.ini`,
  `img1/`), plus `json/` with each frame's full record (keypoints, masks, social groups,
  events, the camera's intent); `mot/seqmaps/USDCROWD-<split>.txt` lists each split.
- `coco/<split>.json`: COCO instances with compressed RLE masks and keypoints; images carry
  `video_id` and `frame_id`, annotations `track_id`; `file_name` is relative to this folder.
- `manifest.json`: the spec, every sequence's plan and the sha256 of every file.

## Reading it

```python
from pycocotools.coco import COCO
coco = COCO("coco/train.json")
```

TrackEval (MOTChallenge's evaluation code): `GT_FOLDER=mot`, `BENCHMARK=USDCROWD`,
`SPLIT_TO_EVAL=train`, `SEQMAP_FOLDER=mot/seqmaps`.
"""
    path = Path(out) / "README.md"
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return {"card": os.fspath(path), "card_figure": figure}
