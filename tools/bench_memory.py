"""Peak memory of ``usdcrowd simulate`` as the shot gets longer: it must not grow with the frames.

Each run is the real command line on a museum scenario with N agents (events
and the scenario's camera agents on), in a child process; its resident memory
and that of its part writers are summed every 50 ms (psutil) and the peak is
reported. Usage::

    python tools/bench_memory.py                    # 300 agents x 750 and 6,000 frames
    python tools/bench_memory.py --long             # and 10,000 agents x 10,000 frames (about 30 min)
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHORT, LONG = 750, 6000
GROWTH_TARGET = 0.10            # peak at 6,000 frames within 10 % of the peak at 750
BIG_TARGET_GIB = 4.0


def _tree_rss(proc) -> int:
    """Resident bytes of a process and all its descendants."""
    import psutil

    total = 0
    try:
        procs = [proc] + proc.children(recursive=True)
    except psutil.Error:
        return 0
    for p in procs:
        try:
            total += p.memory_info().rss
        except psutil.Error:
            pass
    return total


def peak_of(cmd: list[str], cwd: str) -> tuple[float, float, str]:
    """Run ``cmd``; (seconds, peak MiB of its process tree, last stderr line)."""
    import psutil

    t0 = time.perf_counter()
    child = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    proc = psutil.Process(child.pid)
    peak = 0
    while child.poll() is None:
        peak = max(peak, _tree_rss(proc))
        time.sleep(0.05)
    err = child.stderr.read().strip().splitlines()
    if child.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {err[-1] if err else child.returncode}")
    return time.perf_counter() - t0, peak / 2**20, err[-1] if err else ""


def simulate_peak(agents: int, frames: int) -> dict:
    exe = [sys.executable, "-m", "usdcrowd"]
    with tempfile.TemporaryDirectory(dir=os.environ.get("BENCH_TMP")) as tmp:
        scenario = os.path.join(tmp, "scenario.usda")
        subprocess.run(exe + ["new", "museum", "-o", scenario, "--agents", str(agents), "--seed", "1"],
                       check=True, capture_output=True, cwd=ROOT)
        seconds, peak, _ = peak_of(exe + ["simulate", scenario, "-o", os.path.join(tmp, "shot"),
                                          "--frames", f"1:{frames}", "--no-progress"], str(ROOT))
        shot = Path(tmp) / "shot"
        files = [p for p in shot.rglob("*") if p.is_file()]
        size = sum(p.stat().st_size for p in files)
    return {"agents": agents, "frames": frames, "seconds": round(seconds, 1), "peak_mib": round(peak),
            "files": len(files), "size_mib": round(size / 2**20, 1)}


def _line(r: dict) -> str:
    return (f"   {r['agents']:,} agents x {r['frames']:,} frames: {r['seconds']:.1f} s, peak {r['peak_mib']:,} MiB, "
            f"{r['files']} files, {r['size_mib']:,} MiB")


def run(long: bool = False) -> None:
    try:
        import psutil  # noqa: F401
    except ImportError:
        print("   psutil is not installed (pip install -e '.[bench]'): skipped")
        return
    print("   usdcrowd simulate (events and camera agents on), peak resident memory of the command and its workers")
    short = simulate_peak(300, SHORT)
    print(_line(short))
    longer = simulate_peak(300, LONG)
    print(_line(longer))
    growth = longer["peak_mib"] / short["peak_mib"] - 1
    print(f"   {LONG // SHORT}x the frames: peak {growth:+.1%} (target within {GROWTH_TARGET:.0%}: "
          f"{'met' if abs(growth) <= GROWTH_TARGET else 'missed'})")
    if long:
        big = simulate_peak(10_000, 10_000)
        print(_line(big))
        print(f"   target <= {BIG_TARGET_GIB:.0f} GiB: {big['peak_mib'] / 1024 / BIG_TARGET_GIB:.2f}x of budget")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--long", action="store_true", help="also 10,000 agents x 10,000 frames")
    args = p.parse_args(argv)
    run(long=args.long)
    return 0


if __name__ == "__main__":
    sys.exit(main())
