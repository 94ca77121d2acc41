"""The dataset card: ``DATASET/README.md`` with counts per split and ``card.png`` with the distributions.

Counted from the per-frame records as the merge reads them, into fixed
histograms (memory does not grow with the dataset): boxes per frame, each
box's visibility and on-screen height, the agents per sequence, the local
crowd density around each person and the cameras by kind.
"""

from __future__ import annotations

import os
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..atomic import atomic_path
from .scenario import DENSITY_BINS, DENSITY_RADIUS


VIS_BINS = np.linspace(0.0, 1.0, 21)
HEIGHT_BINS = np.r_[0.0, np.geomspace(4.0, 8192.0, 45)]     # amodal box height, pixels


def _quantile(counts: np.ndarray, edges: np.ndarray, q: float) -> float:
    """The q-quantile of histogrammed values, interpolated within its bin."""
    c = np.cumsum(counts)
    if not c.size or c[-1] == 0:
        return 0.0
    k = int(np.searchsorted(c, q * c[-1]))
    before = c[k - 1] if k else 0
    frac = (q * c[-1] - before) / max(counts[k], 1)
    return float(edges[k] + frac * (edges[k + 1] - edges[k]))


@dataclass
class CardStats:
    """Running counts of a dataset (see the module docstring)."""

    sequences: Counter = field(default_factory=Counter)          # split -> sequences
    videos: Counter = field(default_factory=Counter)             # split -> videos (sequence x camera)
    frames: Counter = field(default_factory=Counter)             # split -> frames
    boxes: Counter = field(default_factory=Counter)              # split -> visible boxes
    tracks: Counter = field(default_factory=Counter)             # split -> tracks (per video)
    kinds: Counter = field(default_factory=Counter)              # camera kind -> videos
    agents: Counter = field(default_factory=Counter)             # agents in a sequence -> sequences
    per_frame: Counter = field(default_factory=Counter)          # visible boxes in a frame -> frames
    visibility: np.ndarray = field(default_factory=lambda: np.zeros(len(VIS_BINS) - 1, np.int64))
    height: np.ndarray = field(default_factory=lambda: np.zeros(len(HEIGHT_BINS) - 1, np.int64))
    density: np.ndarray = field(default_factory=lambda: np.zeros(len(DENSITY_BINS) - 1, np.int64))
    _split: str = ""

    def add_sequence(self, seq) -> None:
        self._split = seq.split
        self.sequences[seq.split] += 1
        self.agents[seq.agents] += 1
        if seq.density:
            self.density += np.asarray(seq.density, dtype=np.int64)

    def add_video(self, kind: str, records) -> None:
        split = self._split
        self.videos[split] += 1
        self.kinds[kind] += 1
        tracks = set()
        for rec in records:
            self.frames[split] += 1
            seen = [a for a in rec["agents"] if a["visible_pixels"] > 0]
            self.per_frame[len(seen)] += 1
            self.boxes[split] += len(seen)
            tracks.update(a["track_id"] for a in seen)
            self.visibility += np.histogram([a["visibility"] for a in seen], VIS_BINS)[0]
            self.height += np.histogram([a["bbox_amodal"][3] for a in seen if a.get("bbox_amodal") is not None],
                                        HEIGHT_BINS)[0]
        self.tracks[split] += len(tracks)


def _figure(stats: CardStats, path: Path) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 4, figsize=(15, 6.5))
    ax = ax.ravel()
    n = sorted(stats.per_frame)
    ax[0].bar(n, [stats.per_frame[k] for k in n], width=1.0, color="#4c72b0")
    ax[0].set(title="people in view per frame", xlabel="visible boxes", ylabel="frames")
    ax[1].stairs(stats.visibility, VIS_BINS, fill=True, color="#55a868")
    ax[1].set(title="visibility of each box", xlabel="visible / unoccluded pixels", ylabel="boxes")
    ax[2].stairs(stats.height, HEIGHT_BINS, fill=True, color="#c44e52")
    ax[2].set(title="on-screen height", xlabel="amodal box height (px)", ylabel="boxes", xscale="log")
    ax[2].set_xlim(4, max(8.0, HEIGHT_BINS[np.flatnonzero(stats.height).max() + 1] if stats.height.any() else 8.0))
    v = stats.visibility        # 20 bins of 0.05: heavy < 0.25, partial < 0.75, light < 0.95, none above
    levels = ["none\n>= 0.95", "light\n0.75-0.95", "partial\n0.25-0.75", "heavy\n< 0.25"]
    ax[3].bar(levels, [v[19:].sum(), v[15:19].sum(), v[5:15].sum(), v[:5].sum()], color="#8172b2")
    ax[3].set(title="occlusion", ylabel="boxes")
    a = sorted(stats.agents)
    ax[4].bar([str(k) for k in a], [stats.agents[k] for k in a], color="#937860")
    ax[4].set(title="crowd size", xlabel="agents per sequence", ylabel="sequences")
    kinds = sorted(stats.kinds)
    ax[5].bar(kinds, [stats.kinds[k] for k in kinds], color="#da8bc3")
    ax[5].set(title="cameras", ylabel="videos")
    ax[6].stairs(stats.density, DENSITY_BINS, fill=True, color="#64b5cd")
    ax[6].set(title="crowd density around each person", xlabel=f"people / m^2 within {DENSITY_RADIUS:g} m",
              ylabel="people (5 frames a sequence)")
    ax[7].axis("off")
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
    vis, h = stats.visibility, stats.height
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
- Visibility of the boxes: median {_quantile(vis, VIS_BINS, 0.5):.2f}, {vis[:10].sum() / max(vis.sum(), 1) * 100:.0f} %
  under 0.5.
- On-screen height: median {_quantile(h, HEIGHT_BINS, 0.5):.0f} px, 5th to 95th percentile
  {_quantile(h, HEIGHT_BINS, 0.05):.0f} to {_quantile(h, HEIGHT_BINS, 0.95):.0f} px.
- Crowds of {min(stats.agents, default=0)} to {max(stats.agents, default=0)} agents; local density
  (people within {DENSITY_RADIUS:g} m of each person, per m^2) median {_quantile(stats.density, DENSITY_BINS, 0.5):.2f},
  95th percentile {_quantile(stats.density, DENSITY_BINS, 0.95):.2f}.

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
