"""Benchmark of the final renderer: seconds per frame, ground-truth overhead, CUDA speed-up.

Scene: ``usdcrowd new museum --agents 200`` simulated for 24 frames (the
museum's walls, partition, plinths; sun, sky and a lamp), rendered through
the stage's Overview camera at 640x360, 64 spp, max depth 6, on the LLVM
variant (and on CUDA where a GPU exists).

Measured per frame, after one warm-up frame (JIT compilation and the scene
build are reported separately, as they are paid once per sequence):

- beauty: the path-traced frame;
- ground truth: the exact per-pixel passes (ids, depth, normals, position,
  albedo) and the peeling for the visibility fraction;
- update: posing 200 skinned characters and the camera, BVH rebuild.

Targets: <= 3 s/frame on the llvm variant on 2 cores; ground truth <= 15 %
of beauty.

Usage::

    .venv/bin/python tools/bench_render.py [FRAMES]
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

AGENTS = 200
RESOLUTION = (640, 360)
SPP = 64
MAX_DEPTH = 6


def make_shot(out_dir: Path) -> str:
    """A 200-agent museum shot (24 frames), made with the command line like a user would."""
    exe = [sys.executable, "-m", "usdcrowd"]
    scenario = out_dir / "museum200.usda"
    subprocess.run(exe + ["new", "museum", "--agents", str(AGENTS), "-o", str(scenario)], check=True,
                   capture_output=True)
    subprocess.run(exe + ["simulate", str(scenario), "-o", str(out_dir / "shot"), "--frames", "1:24",
                          "--no-progress"], check=True, capture_output=True)
    return str(out_dir / "shot" / "shot.usda")


def bench_variant(shot: str, variant: str, frames: int) -> dict:
    from usdcrowd.render.final.frame import FrameRenderer
    from usdcrowd.render.scene import ShotScene

    scene = ShotScene(shot)
    t0 = time.perf_counter()
    r = FrameRenderer(scene, "/World/Cameras/Overview", RESOLUTION, SPP, MAX_DEPTH, variant=variant)
    build = time.perf_counter() - t0
    t0 = time.perf_counter()
    r.render(1)                                               # warm-up: kernels compile here
    warm = time.perf_counter() - t0
    rows = []
    for t in np.linspace(2, 24, frames).round():
        t0 = time.perf_counter()
        res = r.render(float(t))
        rows.append(dict(res.seconds, total=time.perf_counter() - t0))
    mean = {k: float(np.mean([row[k] for row in rows])) for k in rows[0]}
    return {"variant": variant, "agents": len(scene.agent_paths), "build": build, "warmup": warm, **mean}


def run(frames: int = 5) -> dict:
    """Run the benchmark and print the results; returns them."""
    from usdcrowd.render.final.variant import choose_variant, describe, probe

    with tempfile.TemporaryDirectory() as tmp:
        shot = make_shot(Path(tmp))
        results = {}
        llvm = "llvm_ad_rgb" if probe("llvm_ad_rgb") else choose_variant()
        results["llvm"] = bench_variant(shot, llvm, frames)
        if probe("cuda_ad_rgb"):
            results["cuda"] = bench_variant(shot, "cuda_ad_rgb", frames)
    print(f"render benchmark: museum, {results['llvm']['agents']} agents, {RESOLUTION[0]}x{RESOLUTION[1]}, "
          f"{SPP} spp, max depth {MAX_DEPTH}, {os.cpu_count()} cores, {frames} frames")
    for key, r in results.items():
        gt_pct = 100 * r["ground_truth"] / r["beauty"]
        print(f"  {describe(r['variant'])}")
        print(f"    scene build {r['build']:.2f} s (once), first frame {r['warmup']:.2f} s (JIT)")
        print(f"    {r['total']:.2f} s/frame: beauty {r['beauty']:.2f} s, ground truth {r['ground_truth']:.3f} s "
              f"({gt_pct:.1f} % of beauty), update {r['update']:.3f} s"
              f"   [targets: <= 3 s/frame on llvm, ground truth <= 15 %]")
    if "cuda" in results:
        print(f"  cuda speed-up over llvm: {results['llvm']['total'] / results['cuda']['total']:.1f}x")
    else:
        print("  cuda: no GPU here, not measured")
    return results


if __name__ == "__main__":
    run(int(sys.argv[1]) if len(sys.argv) > 1 else 5)
