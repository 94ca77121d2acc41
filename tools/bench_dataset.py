"""Dataset throughput: 640x360 ground-truth frames per hour, and the scaling from 1 to 2 Ray workers.

The same small spec (four museum sequences of 40 to 60 people, a steering
and a static camera each, 12 frames per camera at 640x360, the groundtruth
preset at 16 spp) is made three times from scratch: inline (one process,
Mitsuba on every core), then on a Ray instance with 1 and with 2 workers.
Every run includes simulating, filming, rendering and merging. The
projection to a cluster multiplies the best per-machine rate by the
machines, which holds while the shared file system keeps up: the bytes
written per frame are printed to size it.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from pathlib import Path

SPEC = """
[dataset]
name = "bench"
seed = 1
sequences = 4
frames = 12
stride = 2

[scene]
templates = ["museum"]
agents = [40, 60]

[cameras]
steering = [1, 1]
static = 1

[render]
preset = "groundtruth"
resolution = [640, 360]
spp = 16
"""
MACHINES = 100


def _make(spec: Path, out: Path, executor: str, workers: int) -> dict:
    from usdcrowd.dataset.run import make_dataset

    t0 = time.perf_counter()
    r = make_dataset(spec, out, executor=executor, workers=workers, progress=False)
    seconds = time.perf_counter() - t0
    size = sum(p.stat().st_size for p in (out / "sequences").rglob("*") if p.is_file()
               and p.parent.name in ("exr", "png", "json"))
    per_frame = size / max(r.frames, 1)
    return {"seconds": seconds, "frames": r.frames, "per_hour": r.frames / seconds * 3600,
            "bytes_per_frame": per_frame, "bytes_per_frame_mb": per_frame / 1e6}


def run() -> dict:
    """Print and return each run's rate and size, the scaling and the projection."""
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        spec = tmp / "spec.toml"
        spec.write_text(SPEC)
        runs = {}
        for name, executor, workers in (("inline", "inline", 1), ("ray x1", "ray", 1), ("ray x2", "ray", 2)):
            try:
                runs[name] = _make(spec, tmp / name.replace(" ", "_"), executor, workers)
            except Exception as exc:            # no Ray here: the inline figure stands
                print(f"{name}: not run ({exc})")
                continue
            r = runs[name]
            print(f"{name:<7} {r['frames']} frames (4 sequences x 2 cameras x 12) in {r['seconds']:.1f} s: "
                  f"{r['per_hour']:,.0f} frames/hour, {r['bytes_per_frame_mb']:.2f} MB written per frame")
            shutil.rmtree(tmp / name.replace(" ", "_"), ignore_errors=True)
        if "ray x1" in runs and "ray x2" in runs:
            ratio = runs["ray x1"]["seconds"] / runs["ray x2"]["seconds"]
            print(f"scaling 1 -> 2 Ray workers on {os.cpu_count()} cores: {ratio:.2f}x")
        best = max(runs.values(), key=lambda r: r["per_hour"])
        print(f"projection: {MACHINES} machines like this one, {best['per_hour'] * MACHINES:,.0f} frames/hour "
              f"({best['per_hour'] * MACHINES * best['bytes_per_frame'] / 3600 / 1e6:.1f} MB/s to the shared "
              f"file system), if the file system keeps up and each machine runs its best configuration here")
    found = {name.replace(" ", "_"): r for name, r in runs.items()}
    found["scaling"] = runs["ray x1"]["seconds"] / runs["ray x2"]["seconds"] if "ray x2" in runs and "ray x1" in runs else None
    found["projection"] = {"machines": MACHINES, "per_hour": best["per_hour"] * MACHINES,
                           "mb_per_s": best["per_hour"] * MACHINES * best["bytes_per_frame"] / 3600 / 1e6}
    return found


if __name__ == "__main__":
    run()
