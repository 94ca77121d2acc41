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


def _tree_memory(proc) -> tuple[int, int]:
    """(resident, private) bytes of a process and all its descendants.

    Private leaves out file pages mapped in (``shared``): a reader's pages of
    the usdc files it has read, which the system takes back when it needs them.
    """
    import psutil

    rss = private = 0
    try:
        procs = [proc] + proc.children(recursive=True)
    except psutil.Error:
        return 0, 0
    for p in procs:
        try:
            m = p.memory_info()
        except psutil.Error:
            continue
        rss += m.rss
        private += m.rss - m.shared
    return rss, private


def peak_of(cmd: list[str], cwd: str) -> tuple[float, float, float]:
    """Run ``cmd``; (seconds, peak resident MiB, peak private MiB) of its process tree."""
    import psutil

    t0 = time.perf_counter()
    child = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    proc = psutil.Process(child.pid)
    peak = peak_private = 0
    while child.poll() is None:
        rss, private = _tree_memory(proc)
        peak, peak_private = max(peak, rss), max(peak_private, private)
        time.sleep(0.05)
    err = child.stderr.read().strip().splitlines()
    if child.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {err[-1] if err else child.returncode}")
    return time.perf_counter() - t0, peak / 2**20, peak_private / 2**20


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
        # Re-filming reads the whole shot back: its private memory is what must stay flat.
        refilm_s, refilm_rss, refilm_private = peak_of(
            exe + ["cameras", str(shot / "shot.usda"), "--count", "4", "--no-progress"], str(ROOT))
    return {"agents": agents, "frames": frames, "seconds": round(seconds, 1), "peak_mib": round(peak),
            "files": len(files), "size_mib": round(size / 2**20, 1), "refilm_s": round(refilm_s, 1),
            "refilm_rss_mib": round(refilm_rss), "refilm_private_mib": round(refilm_private)}


def _line(r: dict) -> str:
    return (f"   {r['agents']:,} agents x {r['frames']:,} frames: simulate {r['seconds']:.1f} s, peak {r['peak_mib']:,} "
            f"MiB, {r['files']} files, {r['size_mib']:,} MiB; cameras (4 agents) {r['refilm_s']:.1f} s, peak "
            f"{r['refilm_private_mib']:,} MiB private ({r['refilm_rss_mib']:,} MiB with the shot's mapped files)")


def run(long: bool = False) -> dict:
    """Print and return simulate's and re-filming's peaks at 750 and 6,000 frames (and the long run)."""
    try:
        import psutil  # noqa: F401
    except ImportError:
        print("   psutil is not installed (pip install -e '.[bench]'): skipped")
        return {}
    print("   usdcrowd simulate (events and camera agents on), peak resident memory of the command and its workers")
    short = simulate_peak(300, SHORT)
    print(_line(short))
    longer = simulate_peak(300, LONG)
    print(_line(longer))
    growth = longer["peak_mib"] / short["peak_mib"] - 1
    found = {"short": short, "long": longer, "growth_pct": 100 * growth}
    print(f"   simulate: {LONG // SHORT}x the frames, peak {growth:+.1%} (target within {GROWTH_TARGET:.0%}: "
          f"{'met' if abs(growth) <= GROWTH_TARGET else 'missed'})")
    growth = longer["refilm_private_mib"] / short["refilm_private_mib"] - 1
    # A 750-frame shot is read in one full window and a short one; longer shots reach the
    # full per-window peak (a window plus the look-back to unblended poses) and stay there.
    print(f"   cameras: {LONG // SHORT}x the frames, private peak {growth:+.1%} (a window of frames and its look-back)")
    found["refilm_growth_pct"] = 100 * growth
    if long:
        big = simulate_peak(10_000, 10_000)
        print(_line(big))
        print(f"   target <= {BIG_TARGET_GIB:.0f} GiB: {big['peak_mib'] / 1024 / BIG_TARGET_GIB:.2f}x of budget")
        found["big"] = big
    return found


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--long", action="store_true", help="also 10,000 agents x 10,000 frames")
    args = p.parse_args(argv)
    run(long=args.long)
    return 0


if __name__ == "__main__":
    sys.exit(main())
