"""Score a dataset's ground truth with TrackEval: against itself (must be 1) and the shipped IoU-tracker baseline.

    python tools/eval_dataset.py out/dataset [--split train] [--drop 0.1] [--jitter 0.05]

Writes the trackers' files under DATASET/trackers/ (TrackEval's layout) and prints HOTA, MOTA and IDF1.
"""

from __future__ import annotations

import argparse
import sys


def main(argv=None) -> int:
    from usdcrowd.dataset import baseline

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("dataset")
    p.add_argument("--split", default=None, help="one split (default: every split the dataset has)")
    p.add_argument("--drop", type=float, default=0.1, help="share of detections the baseline misses")
    p.add_argument("--jitter", type=float, default=0.05, help="box noise of the baseline, share of its size")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    from pathlib import Path

    splits = [args.split] if args.split else [s for s in ("train", "val", "test")
                                              if (Path(args.dataset) / "mot" / f"USDCROWD-{s}").is_dir()]
    print(f"{'split':<6} {'tracker':<8} {'HOTA':>6} {'MOTA':>6} {'IDF1':>6}")
    for split in splits:
        baseline.ground_truth_as_tracker(args.dataset, split)
        baseline.run_baseline(args.dataset, split, seed=args.seed, drop=args.drop, jitter=args.jitter)
        for name, m in baseline.evaluate(args.dataset, split, ["gt", "iou"]).items():
            print(f"{split:<6} {name:<8} {m['HOTA']:6.3f} {m['MOTA']:6.3f} {m['IDF1']:6.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
