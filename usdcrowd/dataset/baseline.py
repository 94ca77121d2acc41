"""A baseline to check a dataset's evaluation end to end: noisy detections and an IoU tracker.

Detections are the ground truth's visible pedestrians, each dropped with
probability ``drop`` and its box jittered by ``jitter`` of its size (seeded).
The tracker is Bochinski et al.'s IoU tracker (AVSS 2017): each track takes
the detection of the next frame that overlaps its last box most, if their
IoU reaches ``sigma_iou``; a track not continued ends; unmatched detections
start tracks; tracks shorter than ``t_min`` frames are dropped. Its output
is a MOTChallenge tracker file (``frame,id,left,top,width,height,conf,-1,-1,-1``),
one per sequence, under ``trackers/USDCROWD-<split>/<name>/data/``, where
TrackEval looks for it.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .. import guard
from ..atomic import atomic_path
from .layout import BENCHMARK, mot_dir


def read_gt(path) -> np.ndarray:
    """(k, 9) float64 rows of a gt.txt (frame, id, left, top, width, height, conf, class, visibility)."""
    rows = np.loadtxt(path, delimiter=",", ndmin=2)
    return rows.reshape(-1, 9)


def noisy_detections(gt: np.ndarray, rng: np.random.Generator, drop: float = 0.1,
                     jitter: float = 0.05) -> np.ndarray:
    """(d, 6) detections (frame, left, top, width, height, score) from a gt.txt's visible pedestrians."""
    keep = (gt[:, 6] == 1) & (gt[:, 7] == 1) & (gt[:, 8] > 0)
    det = gt[keep][:, [0, 2, 3, 4, 5]].copy()
    det = det[rng.random(len(det)) >= drop]
    size = np.repeat(det[:, 3:5], 2, axis=1)
    det[:, 1:5] += jitter * size * rng.standard_normal((len(det), 4))
    det[:, 3:5] = np.maximum(det[:, 3:5], 1.0)
    return np.c_[det, np.ones(len(det))]


def iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n, m) IoU of (n, 4) and (m, 4) boxes given as left, top, width, height."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    lo = np.maximum(a[:, None, :2], b[None, :, :2])
    hi = np.minimum(a[:, None, :2] + a[:, None, 2:], b[None, :, :2] + b[None, :, 2:])
    inter = np.prod(np.clip(hi - lo, 0.0, None), axis=-1)
    union = a[:, None, 2] * a[:, None, 3] + b[None, :, 2] * b[None, :, 3] - inter
    return inter / np.maximum(union, 1e-12)


def iou_tracker(detections: np.ndarray, sigma_iou: float = 0.3, t_min: int = 2) -> np.ndarray:
    """(k, 6) tracked boxes (frame, id, left, top, width, height) from (d, 6) detections."""
    active: list[list] = []          # each: list of (frame, box)
    finished: list[list] = []
    frames = np.unique(detections[:, 0]) if len(detections) else []
    for f in frames:
        det = detections[detections[:, 0] == f]
        free = np.ones(len(det), dtype=bool)
        still = []
        for track in active:
            last_frame, box = track[-1]
            scores = iou(box[None], det[:, 1:5])[0] if len(det) else np.zeros(0)
            scores[~free] = -1.0
            j = int(np.argmax(scores)) if len(scores) else -1
            if last_frame == f - 1 and j >= 0 and scores[j] >= sigma_iou:
                track.append((f, det[j, 1:5]))
                free[j] = False
                still.append(track)
            else:
                finished.append(track)
        active = still + [[(f, det[j, 1:5])] for j in np.flatnonzero(free)]
    finished += active
    rows = []
    for tid, track in enumerate((t for t in finished if len(t) >= t_min), start=1):
        rows += [(f, tid, *box) for f, box in track]
    return np.array(sorted(rows), dtype=np.float64).reshape(-1, 6)


def write_tracker(path, tracked: np.ndarray) -> str:
    """A MOTChallenge tracker file."""
    path = Path(path)
    guard.make_dir(path.parent)
    with atomic_path(path) as tmp, open(tmp, "w") as f:
        for fr, tid, x, y, w, h in tracked:
            f.write(f"{int(fr)},{int(tid)},{x:.2f},{y:.2f},{w:.2f},{h:.2f},1,-1,-1,-1\n")
    return os.fspath(path)


def run_baseline(root, split: str, name: str = "iou", seed: int = 0, drop: float = 0.1,
                 jitter: float = 0.05) -> list[str]:
    """Track every sequence of a split; returns the tracker files written."""
    rng = np.random.default_rng(seed)
    out = []
    for gt in sorted(mot_dir(root, split).glob("*/gt/gt.txt")):
        seq = gt.parent.parent.name
        tracked = iou_tracker(noisy_detections(read_gt(gt), rng, drop, jitter))
        out.append(write_tracker(Path(root) / "trackers" / f"{BENCHMARK}-{split}" / name / "data" / f"{seq}.txt",
                                 tracked))
    return out


def ground_truth_as_tracker(root, split: str, name: str = "gt") -> list[str]:
    """The ground truth's pedestrians written as a tracker's output (it must score 1 against itself)."""
    out = []
    for gt in sorted(mot_dir(root, split).glob("*/gt/gt.txt")):
        rows = read_gt(gt)
        rows = rows[(rows[:, 6] == 1) & (rows[:, 7] == 1)]
        out.append(write_tracker(Path(root) / "trackers" / f"{BENCHMARK}-{split}" / name / "data"
                                 / f"{gt.parent.parent.name}.txt", rows[:, :6]))
    return out


def evaluate(root, split: str, trackers: list[str]) -> dict:
    """TrackEval's HOTA, MOTA and IDF1 of each tracker over a split's sequences (all combined).

    Returns
    -------
    dict
        tracker -> {"HOTA", "MOTA", "IDF1"}, in [0, 1] (MOTA may be negative).

    Raises
    ------
    UsdcrowdError
        Without TrackEval (``pip install 'usdcrowd[dataset]'``).
    """
    try:
        import trackeval
    except ImportError:
        from ..core.errors import UsdcrowdError

        raise UsdcrowdError("evaluating needs TrackEval: pip install 'usdcrowd[dataset]'") from None
    root = Path(root)
    evaluator = trackeval.Evaluator({"USE_PARALLEL": False, "PRINT_RESULTS": False, "PRINT_ONLY_COMBINED": True,
                                     "PRINT_CONFIG": False, "TIME_PROGRESS": False, "DISPLAY_LESS_PROGRESS": True,
                                     "OUTPUT_SUMMARY": False, "OUTPUT_DETAILED": False, "PLOT_CURVES": False,
                                     "OUTPUT_EMPTY_CLASSES": False})
    dataset = trackeval.datasets.MotChallenge2DBox({
        "GT_FOLDER": os.fspath(root / "mot"), "TRACKERS_FOLDER": os.fspath(root / "trackers"),
        "OUTPUT_FOLDER": os.fspath(root / "trackers" / "eval"), "TRACKERS_TO_EVAL": list(trackers),
        "BENCHMARK": BENCHMARK, "SPLIT_TO_EVAL": split, "SEQMAP_FOLDER": os.fspath(root / "mot" / "seqmaps"),
        "PRINT_CONFIG": False, "DO_PREPROC": True})
    metrics = [trackeval.metrics.HOTA(), trackeval.metrics.CLEAR({"PRINT_CONFIG": False}),
               trackeval.metrics.Identity({"PRINT_CONFIG": False})]
    import contextlib
    import io

    with contextlib.redirect_stdout(io.StringIO()):       # TrackEval prints as it goes
        results, _ = evaluator.evaluate([dataset], metrics)
    out = {}
    for name in trackers:
        combined = results["MotChallenge2DBox"][name]["COMBINED_SEQ"]["pedestrian"]
        out[name] = {"HOTA": float(np.mean(combined["HOTA"]["HOTA"])), "MOTA": float(combined["CLEAR"]["MOTA"]),
                     "IDF1": float(combined["Identity"]["IDF1"])}
    return out
