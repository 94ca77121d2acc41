"""usdcrowd benchmarks: each section prints sizes, rates and ratios.

    python tools/bench.py                 # every section
    python tools/bench.py author          # authoring 10,000 agents x 300 frames
    python tools/bench.py author --agents 2000 --frames 300
    python tools/bench.py sim             # crowd simulation steps/s (and JuPedSim)
    python tools/bench.py preview         # OpenGL preview fps, 1,000 and 10,000 characters
    python tools/bench.py render          # Mitsuba s/frame and ground-truth overhead
    python tools/bench.py cameras         # camera agents + event detection steps/s (30 x 100, 100 x 10,000)
    python tools/bench.py moe             # learned camera behaviors: predictions/s in numpy (target 2,000)
    python tools/bench.py dataset         # usdcrowd dataset: 640x360 ground-truth frames/hour, 1 -> 2 Ray workers
    python tools/bench.py memory          # simulate's peak memory, 300 agents x 750 and 6,000 frames
    python tools/bench.py memory --long   # and 10,000 agents x 10,000 frames (about 30 min)

Each measured run happens in a child process so that its peak memory is its own.
Targets (2-core machine): author 10,000 x 300 in <= 20 s and <= 4 GiB; 100
camera agents with 10,000 characters (event detection included) >= 30 steps/s;
simulate's peak memory at 6,000 frames within 10 % of 750, and 10,000 agents x
10,000 frames within 4 GiB.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tests"), str(ROOT / "tools")]

AUTHOR_TARGET_S = 20.0
AUTHOR_TARGET_GIB = 4.0


def _peak_mib() -> float:
    """Peak resident memory of this process plus the largest of its finished children."""
    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    children = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return (own + children) / 1024.0


def author_once(agents: int, frames: int, events: bool = False) -> dict:
    """Author ``agents`` x ``frames`` of walking crowd as a shot; returns timings."""
    import usdcrowd  # noqa: F401
    from frames_factory import straight_walk

    from usdcrowd.core import model
    from usdcrowd.jobs.pipeline import author_shot
    from usdcrowd.jobs.templates import new_scenario

    with tempfile.TemporaryDirectory() as tmp:
        scenario = Path(tmp) / "scenario.usda"
        new_scenario("museum", scenario, agents=agents, seed=1)
        chunk = 50

        def source(sc: model.Scenario):
            whole = straight_walk(sc.agents, sc.time)
            for s in range(0, len(whole.times), chunk):
                sl = slice(s, s + chunk)
                yield model.CrowdFrames(whole.times[sl], whole.position[sl], whole.heading[sl], whole.velocity[sl],
                                        whole.behavior[sl], whole.anim_class[sl], whole.anim_phase[sl],
                                        whole.health[sl], whole.look_at[sl], whole.path_method)

        t0 = time.perf_counter()
        result = author_shot(scenario, Path(tmp) / "shot", source, frames=(1, frames), progress=False,
                             events=events)
        seconds = time.perf_counter() - t0
        size = sum(f.stat().st_size for f in (Path(tmp) / "shot").iterdir())
        samples = 2 * result.n_agents * result.n_frames
        return {"agents": result.n_agents, "frames": result.n_frames, "seconds": round(seconds, 2),
                "samples_per_s": round(samples / seconds), "agent_frames_per_s": round(result.n_agents * result.n_frames / seconds),
                "size_mib": round(size / 2**20, 1), "peak_mib": round(_peak_mib())}


def _child(section: str, **kw) -> dict:
    """Run one measurement in a fresh interpreter and return its JSON line."""
    code = (f"import sys, json; sys.path.insert(0, {str(ROOT / 'tools')!r}); import bench; "
            f"print(json.dumps(bench.{section}_once(**{kw!r})))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    if out.returncode != 0:
        raise RuntimeError(out.stderr[-2000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def bench_author(agents: int, frames: int) -> None:
    print(f"== author: {agents} agents x {frames} frames (two UsdSkel samples per agent and frame)")
    r = _child("author", agents=agents, frames=frames)
    print(f"   {r['seconds']:.2f} s, {r['samples_per_s']:,} samples/s, {r['agent_frames_per_s']:,} agent-frames/s, "
          f"files {r['size_mib']} MiB, peak {r['peak_mib']:,} MiB")
    if agents == 10_000 and frames == 300:
        print(f"   target <= {AUTHOR_TARGET_S:.0f} s: {r['seconds'] / AUTHOR_TARGET_S:.2f}x of budget; "
              f"<= {AUTHOR_TARGET_GIB:.0f} GiB: {r['peak_mib'] / 1024 / AUTHOR_TARGET_GIB:.2f}x of budget")
    e = _child("author", agents=agents, frames=frames, events=True)
    print(f"   with event detection (simulate's default): {e['seconds']:.2f} s "
          f"({e['seconds'] / r['seconds']:.2f}x), peak {e['peak_mib']:,} MiB")


def bench_section(name: str, **kw) -> None:
    """Run tools/bench_<name>.py's run(); each prints its own table."""
    import importlib

    try:
        module = importlib.import_module(f"bench_{name}")
    except ImportError as exc:
        print(f"== {name}: not available ({exc})")
        return
    print(f"== {name}")
    module.run(**kw)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("section", nargs="?", default="all", choices=["all", "author", "sim", "cameras", "moe", "preview", "render",
                                                                 "dataset", "memory"])
    p.add_argument("--agents", type=int, default=10_000)
    p.add_argument("--frames", type=int, default=300)
    p.add_argument("--sizes", default="1000,10000,100000", help="agent counts of the sim section")
    p.add_argument("--long", action="store_true", help="memory: also 10,000 agents x 10,000 frames")
    args = p.parse_args(argv)
    print(f"machine: {os.cpu_count()} cores, python {sys.version.split()[0]}")
    if args.section in ("all", "author"):
        bench_author(args.agents, args.frames)
    if args.section in ("all", "sim"):
        bench_section("sim", sizes=tuple(int(s) for s in args.sizes.split(",")))
    for name in ("cameras", "moe", "preview", "render", "dataset"):
        if args.section in ("all", name):
            bench_section(name)
    if args.section in ("all", "memory"):
        bench_section("memory", long=args.long)
    return 0


if __name__ == "__main__":
    sys.exit(main())
