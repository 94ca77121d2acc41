"""Write the reference renders of tests/render/final/test_render_final.py into tests/baselines/.

Run after a deliberate change to how frames look::

    .venv/bin/python tools/make_baselines.py

and, after a deliberate change to what the demo's ground truth holds, ``--demo``:
the sha256 of the demo's MOT and COCO files, which tests/cli/test_cli.py
holds every later demo run to (the same command gives the same bytes).

Each baseline is a small beauty EXR plus a JSON of how it was made (shot
recipe, camera, frame, size, spp, seed) and the tolerances the test applies:
the mean and the 99th percentile of the per-pixel absolute difference,
relative to the image mean. The tolerances are set from two renders that
differ only by their sampler seed (pure Monte Carlo noise), times a margin.
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
BASELINES = ROOT / "tests" / "baselines"

# name -> how the reference is made (the shot is the museum with straight-walking agents, frames 1..12)
CASES = {"museum_overview_f6": {"camera": "/World/Cameras/Overview", "time": 6.0, "resolution": [96, 54],
                                "spp": 64, "max_depth": 4, "seed": 7}}
MARGIN = 3.0


def museum_test_shot(out_dir) -> str:
    """The shot the tests render: museum.usda with every agent walking straight (tests/helpers/frames.py)."""
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))           # the repository's tests package
    from tests.helpers.frames import straight_walk

    import usdcrowd.core.resources as res
    from usdcrowd.jobs.pipeline import author_shot

    r = author_shot(res.data_dir("stages") / "museum.usda", out_dir,
                    lambda sc: [straight_walk(sc.agents, sc.time)], frames=(1, 12), progress=False)
    return r.shot


def render_baseline(shot, meta: dict, seed: int | None = None):
    """Render one baseline case; returns the FrameResult."""
    from usdcrowd.render.final.frame import FrameRenderer

    r = FrameRenderer(shot, meta["camera"], tuple(meta["resolution"]), spp=meta["spp"], max_depth=meta["max_depth"],
                      seed=meta["seed"] if seed is None else seed, ground_truth=False)
    return r.render(meta["time"])


# The demo's outputs that must not change unless their content is meant to: the tracks byte for byte;
# the COCO file value for value, its floats to COCO_ATOL pixels (numpy's float32 loops round differently
# on CPUs with and without AVX-512: the eighth decimal of a box moves).
DEMO_FILES = ("render/mot/gt/gt.txt",)
DEMO_COCO = "render/coco.json"
COCO_ATOL = 1e-3


def demo_digests(folder) -> dict:
    """sha256 of :data:`DEMO_FILES` under a demo's output folder."""
    import hashlib

    return {name: hashlib.sha256((Path(folder) / name).read_bytes()).hexdigest() for name in DEMO_FILES}


def coco_differences(got, expected, atol: float = COCO_ATOL, where: str = "") -> list[str]:
    """Where two COCO documents (parsed JSON) differ: every value equal, floats within ``atol``."""
    if isinstance(expected, dict):
        if not isinstance(got, dict) or got.keys() != expected.keys():
            return [f"{where}: keys {sorted(got) if isinstance(got, dict) else got!r} != {sorted(expected)}"]
        return [d for k in expected for d in coco_differences(got[k], expected[k], atol, f"{where}.{k}")]
    if isinstance(expected, list):
        if not isinstance(got, list) or len(got) != len(expected):
            return [f"{where}: {len(got) if isinstance(got, list) else got!r} items != {len(expected)}"]
        return [d for k, (g, e) in enumerate(zip(got, expected)) for d in coco_differences(g, e, atol, f"{where}[{k}]")]
    if isinstance(expected, float) or isinstance(got, float):
        ok = isinstance(got, (int, float)) and not isinstance(got, bool) and abs(got - expected) <= atol
        return [] if ok else [f"{where}: {got!r} != {expected!r}"]
    return [] if got == expected else [f"{where}: {got!r} != {expected!r}"]


def record_demo() -> int:
    """Run ``usdcrowd demo``; write its tracks' digest to tests/baselines/demo_ground_truth.json and its COCO
    file to tests/baselines/demo_coco.json."""
    import shutil
    import subprocess

    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run([sys.executable, "-m", "usdcrowd", "demo", "-o", f"{tmp}/demo", "--no-progress"], check=True,
                       capture_output=True)
        digests = demo_digests(f"{tmp}/demo")
        shutil.copyfile(f"{tmp}/demo/{DEMO_COCO}", BASELINES / "demo_coco.json")
    (BASELINES / "demo_ground_truth.json").write_text(json.dumps(digests, indent=2) + "\n")
    print(f"wrote {BASELINES / 'demo_ground_truth.json'} and {BASELINES / 'demo_coco.json'}")
    return 0


def main() -> int:
    if "--demo" in sys.argv[1:]:
        return record_demo()
    from usdcrowd.render.final.exr import channels_of, write_frame_exr
    from usdcrowd.render.final.variant import choose_variant

    BASELINES.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        shot = museum_test_shot(tmp)
        for name, meta in CASES.items():
            ref = render_baseline(shot, meta).beauty
            other = render_baseline(shot, meta, seed=meta["seed"] + 1000).beauty
            diff = np.abs(other - ref).mean(-1)
            scale = float(ref.mean())
            meta = dict(meta, variant=choose_variant(), noise_mean_rel=float(diff.mean() / scale),
                        noise_p99_rel=float(np.percentile(diff, 99) / scale))
            meta["max_mean_rel"] = round(MARGIN * meta["noise_mean_rel"], 4)
            meta["max_p99_rel"] = round(MARGIN * meta["noise_p99_rel"], 4)
            write_frame_exr(BASELINES / f"{name}.exr", channels_of(ref))
            (BASELINES / f"{name}.json").write_text(json.dumps(meta, indent=2) + "\n")
            print(f"{name}: noise mean {meta['noise_mean_rel']:.4f}, p99 {meta['noise_p99_rel']:.4f} "
                  f"-> tolerances {meta['max_mean_rel']}, {meta['max_p99_rel']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
