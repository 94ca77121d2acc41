"""Splitting a crowd layer's animation over time: USD value clips.

An Sdf layer keeps every time sample in memory until it is saved, so a long
shot authored into one layer needs memory in proportion to its length (about
0.5 KB per agent and frame). The crowd layer therefore writes its samples in
time windows, one clip layer per window (and per part layer), saved and
dropped as soon as the window is complete. The part layer holds the prims and
the ``clips`` metadata (UsdClipsAPI) that stitch the windows back together, so
every USD reader (usd-core, Blender, usdview) sees one animation::

    crowd.usdc                          prims, extents, clip sets
    crowd.clips/crowd.0000.usdc         samples of frames s0 .. s1 - 1
    crowd.clips/crowd.0001.usdc         samples of frames s1 .. s2 - 1
    crowd.clips/crowd.manifest.usdc     the attributes the clips provide

A time between the last frame of one window and the first of the next
interpolates across the two clips (USD brackets samples across clip
boundaries), so sub-frame queries (motion blur) see one continuous motion.

During a run the clips are written to a temporary folder beside the final one
(``.crowd.clips.partial-<hex>``); :func:`publish` swaps it in at the end and an
interrupted run's folder is removed by the next run (:func:`usdcrowd.atomic.clean_partials`).
"""

from __future__ import annotations

import os
import shutil
import uuid
from dataclasses import dataclass

import numpy as np

# Agent-frames of samples the writers hold together before they save a window:
# about 0.5 KB each in USD, so ~1.5 GB whatever the shot's length and however
# many processes write it. Each window costs time (its layer declares every
# agent's animated attributes again, and small layers save slower per sample):
# `python tools/bench.py author` times a crowd in one window and in several.
AGENT_FRAMES_HELD = 3_000_000
# Window length bounds, frames. Shots no longer than one window are written
# without clips (one layer, as any USD tool would write it).
MIN_WINDOW = 24
MAX_WINDOW = 480


def window_frames(agents_per_process: int, processes: int = 1) -> int:
    """Frames per clip window for ``processes`` writers of ``agents_per_process`` agents each."""
    w = AGENT_FRAMES_HELD // max(1, agents_per_process * processes)
    return int(np.clip(w, MIN_WINDOW, MAX_WINDOW))


@dataclass(frozen=True)
class ClipPlan:
    """Where and how a crowd layer's samples are split in time.

    Attributes
    ----------
    start, end : float
        The shot's first and last time code (frames are ``start + k``).
    window : int
        Frames per window; window ``k`` holds the frames from ``start + k w``
        to ``start + (k+1) w - 1`` (the last one ends at ``end``).
    folder : str
        Where the clip files are written during the run.
    asset_dir : str
        The folder as the layers name it, relative to them (``./crowd.clips``).
    """

    start: float
    end: float
    window: int
    folder: str
    asset_dir: str

    @property
    def n_windows(self) -> int:
        return max(1, int(np.ceil((self.end - self.start + 1) / self.window)))

    def window_start(self, k: int) -> float:
        return self.start + k * self.window

    def window_end(self, k: int) -> float:
        """The last frame of window ``k``."""
        return min(self.start + (k + 1) * self.window - 1, self.end)

    def windows_of(self, times: np.ndarray) -> list[tuple[int, np.ndarray]]:
        """(window, indices into ``times``) of every window some of ``times`` fall in."""
        rel = np.asarray(times, dtype=np.float64) - self.start
        k = np.minimum(np.floor(rel / self.window).astype(np.int64), self.n_windows - 1)
        return [(int(w), np.flatnonzero(k == w)) for w in np.unique(k)]

    def file_name(self, stem: str, k: int) -> str:
        return f"{stem}.{k:04d}.usdc"

    def manifest_name(self, stem: str) -> str:
        return f"{stem}.manifest.usdc"

    def metadata(self, stem: str) -> dict:
        """The clip set's fields (UsdClipsAPI), for clips named after ``stem``."""
        from pxr import Sdf, Vt

        paths = [f"{self.asset_dir}/{self.file_name(stem, k)}" for k in range(self.n_windows)]
        return {"assetPaths": Sdf.AssetPathArray(paths),
                "active": Vt.Vec2dArray([(self.window_start(k), float(k)) for k in range(self.n_windows)]),
                "manifestAssetPath": Sdf.AssetPath(f"{self.asset_dir}/{self.manifest_name(stem)}")}


def plan(final_layer: str, start: float, end: float, agents_per_process: int,
         window: int | None = None, processes: int = 1) -> ClipPlan | None:
    """The clip plan of a crowd layer written to ``final_layer``; None when one window holds the shot."""
    window = window or window_frames(agents_per_process, processes)
    if end - start + 1 <= window:
        return None
    stem = os.path.splitext(os.path.basename(final_layer))[0]
    parent = os.path.dirname(os.path.abspath(final_layer))
    folder = os.path.join(parent, f".{stem}.clips.partial-{uuid.uuid4().hex[:8]}")
    return ClipPlan(float(start), float(end), int(window), folder, f"./{stem}.clips")


def clips_folder(final_layer: str) -> str:
    """The folder the clips of ``final_layer`` end up in."""
    stem = os.path.splitext(os.path.basename(final_layer))[0]
    return os.path.join(os.path.dirname(os.path.abspath(final_layer)), f"{stem}.clips")


def publish(clip_plan: ClipPlan | None, final_layer: str) -> None:
    """Put this run's clips in place of the previous run's (removed when the shot has none now)."""
    from .. import guard

    final = clips_folder(final_layer)
    guard.check_write(final)
    old = None
    if os.path.isdir(final):
        old = os.path.join(os.path.dirname(final), f".{os.path.basename(final)}.old.partial-{uuid.uuid4().hex[:8]}")
        os.replace(final, old)
    if clip_plan is not None:
        os.replace(clip_plan.folder, final)
        guard.wrote(final)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def discard(clip_plan: ClipPlan | None) -> None:
    """Remove this run's clips (an interrupted or failed run)."""
    if clip_plan is not None:
        shutil.rmtree(clip_plan.folder, ignore_errors=True)


def anchor_roots(paths) -> list[str]:
    """The root prims under which the given prim paths live (where clip sets are anchored)."""
    return sorted({"/" + str(p).strip("/").split("/")[0] for p in paths})


def author_clip_sets(layer, name: str, clip_plan: ClipPlan, stem: str, roots: list[str]) -> None:
    """Anchor a clip set named ``name`` (one per root prim) on ``layer``'s root prims."""
    from pxr import Sdf

    for root in roots:
        spec = layer.GetPrimAtPath(root) or Sdf.CreatePrimInLayer(layer, root)
        clips = dict(spec.GetInfo("clips")) if spec.HasInfo("clips") else {}
        clips[name] = dict(clip_plan.metadata(stem), primPath=root)
        spec.SetInfo("clips", clips)
        spec.SetInfo("clipSets", Sdf.StringListOp.Create(prependedItems=[name]))
