"""Benchmark of the steering camera agents with event detection (seed 000).

Scene: characters on a square (2.5 m^2 each, at least 20 m wide), a third of
them marching in platoons of 20 across it, the rest wandering slowly, pairs
stopping face to face. Each frame runs the event detector on that frame
(streaming, as ``usdcrowd simulate`` does) and steps every camera agent
(two substeps of Algorithms 1 and 2). A step here is one frame of the shot.

    python tools/bench_cameras.py                    # seed 000's Figure 16: 1 to 100 cameras, 100 and 10,000 characters
    python tools/bench_cameras.py 50:1000            # cameras:characters

Seed 000 reports 30 cameras with 100 characters at 15 fps in Unity on a
Core i7 (crowd simulation included); the target here is >= 30 steps/s for
100 cameras with 10,000 characters on 2 cores.
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from usdcrowd.core import model
from usdcrowd.cameras.placement import crowd_extent, generated_agents  # noqa: E402
from usdcrowd.cameras.steering import CameraAgents  # noqa: E402
from usdcrowd.events import EventDetector  # noqa: E402

FPS = 24.0
TARGET_STEPS = 30.0
PAPER = (30, 100, 15.0)          # cameras, characters, fps (Unity 4, Core i7 at 2.4 GHz)


def crowd(n: int, frames: int, seed: int = 0):
    """Synthetic crowd frames: (positions (t, n, 3), headings (t, n), velocities (t, n, 2))."""
    rng = np.random.default_rng(seed)
    side = max(20.0, np.sqrt(2.5 * n))
    start = rng.uniform(-side / 2, side / 2, (n, 2))
    vel = np.zeros((n, 2))
    n_march = (n // 3) // 20 * 20
    for g in range(0, n_march, 20):
        ang = rng.uniform(0, 2 * np.pi)
        centre = rng.uniform(-side / 3, side / 3, 2)
        grid = np.stack(np.meshgrid(np.arange(5.0), np.arange(4.0), indexing="ij"), -1).reshape(-1, 2) * 1.1
        start[g:g + 20] = centre + grid
        vel[g:g + 20] = 1.3 * np.array([np.cos(ang), np.sin(ang)])
    wander = np.arange(n_march, n)
    pairs = wander[: (len(wander) // 10) * 2].reshape(-1, 2)
    start[pairs[:, 1]] = start[pairs[:, 0]] + [1.2, 0.0]
    t = np.arange(frames)[:, None, None] / FPS
    pos = np.zeros((frames, n, 3), np.float32)
    walk = rng.normal(0, 0.3, (frames, n, 2)).cumsum(0) / FPS
    walk[:, pairs.ravel()] = 0.0
    walk[:, :n_march] = 0.0
    pos[..., :2] = start + vel * t + walk
    v = np.gradient(pos[..., :2], axis=0) * FPS
    heading = np.arctan2(v[..., 1], v[..., 0])
    heading[:, pairs[:, 0]] = 0.0
    heading[:, pairs[:, 1]] = np.pi
    return pos, heading.astype(np.float32), v.astype(np.float32)


def run_case(cameras: int, n: int, frames: int = 96) -> dict:
    pos, heading, vel = crowd(n, frames)
    times = np.arange(1, frames + 1, dtype=np.float64)
    visible = np.ones(n, bool)
    det = EventDetector(np.zeros(n, np.int8), visible, FPS)
    zeros_i8 = np.zeros((1, n), np.int8)
    t_events = t_cams = 0.0
    # Pass 1: the streaming detector, one frame at a time, timed per frame.
    for k in range(frames):
        chunk = model.CrowdFrames(times[k:k + 1], pos[k:k + 1], heading[k:k + 1], vel[k:k + 1], zeros_i8, zeros_i8,
                                  np.zeros((1, n), np.float32), zeros_i8, np.full((1, n, 3), np.nan, np.float32),
                                  np.zeros(n, np.int8))
        t0 = time.perf_counter()
        det.feed(chunk)
        t_events += time.perf_counter() - t0
    t0 = time.perf_counter()
    events = det.finish()
    t_events += time.perf_counter() - t0
    # Pass 2: the cameras, with the events found.
    centre, radius = crowd_extent(pos[0])
    table = generated_agents(cameras, centre, radius)
    agents = CameraAgents(table, events, model.Obstacles.empty(), visible=visible, fps=FPS)
    substeps = agents.params.substeps
    for k in range(frames):
        t1 = time.perf_counter()
        p = pos[k].astype(np.float64)
        c, r = crowd_extent(p)
        agents.update_modes(times[k], p)
        for _ in range(substeps):
            agents.step(times[k], p, c, r, 1.0 / (FPS * substeps))
        t_cams += time.perf_counter() - t1
    tracking = float(np.mean(agents.tracked >= 0))
    return {"cameras": cameras, "characters": n, "frames": frames, "steps_per_s": frames / (t_events + t_cams),
            "events_ms": 1e3 * t_events / frames, "cameras_ms": 1e3 * t_cams / frames,
            "tracking_at_end": tracking, "events": len(events)}


# Seed 000's Figure 16 (frame rate against the number of camera agents), with 100 and 10,000 characters.
SWEEP = tuple((c, n) for n in (100, 10_000) for c in (1, 3, 10, 30, 100))


def sweep_table(rows: list[dict]) -> dict:
    """Steps per second by cameras (rows) and characters (columns), for docs/data."""
    crowds = sorted({r["characters"] for r in rows})
    counts = sorted({r["cameras"] for r in rows})
    at = {(r["cameras"], r["characters"]): r["steps_per_s"] for r in rows}
    return {"columns": ["cameras"] + [f"steps/s with {n:,} characters" for n in crowds],
            "rows": [[str(c)] + [f"{at[(c, n)]:.1f}" if (c, n) in at else "" for n in crowds] for c in counts]}


def sweep_plot(rows: list[dict], path) -> str:
    """Figure 16's curve: steps per second against camera agents, one line per crowd size."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.5), constrained_layout=True)
    for n in sorted({r["characters"] for r in rows}):
        mine = sorted((r["cameras"], r["steps_per_s"]) for r in rows if r["characters"] == n)
        ax.plot(*zip(*mine), marker="o", label=f"{n:,} characters")
    ax.axhline(PAPER[2], color="0.6", ls="--", lw=1, label=f"seed 000: {PAPER[0]} cameras, {PAPER[1]} characters")
    ax.set_xscale("log")
    ax.set_xlabel("camera agents")
    ax.set_ylabel("steps per second (events + cameras)")
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return str(path)


# JuPedSim's 10,000-agent step (tools/bench_sim.py's scene), timed beside the 100 x 10,000 case, shows how
# loaded the machine was: the same figure the crowd-step rows are measured against.
PEER_STEPS = 30


def _peer_rate() -> float:
    from bench_sim import bench_jupedsim

    return bench_jupedsim(10_000, PEER_STEPS)


def run(cases=SWEEP, jupedsim: bool = True) -> list[dict]:
    """Print and return one row per (cameras, characters) case; with ``jupedsim`` (an error when it is
    missing), JuPedSim's 10,000-agent steps per second just before and after the 100 x 10,000 case."""
    if jupedsim:
        from bench_sim import require_jupedsim

        require_jupedsim("cameras")
    rows = []
    print(f"   {'cameras':>7} {'characters':>10} {'steps/s':>8} {'events ms':>9} {'cameras ms':>10} "
          f"{'tracking':>8} {'events':>6}")
    for cams, n in cases:
        peer = jupedsim and (cams, n) == (100, 10_000)
        before = _peer_rate() if peer else None
        r = run_case(cams, n)
        if peer:
            r["jupedsim_10k_before"], r["jupedsim_10k_after"] = before, _peer_rate()
        rows.append(r)
        print(f"   {r['cameras']:>7} {r['characters']:>10,} {r['steps_per_s']:>8.1f} {r['events_ms']:>9.2f} "
              f"{r['cameras_ms']:>10.2f} {r['tracking_at_end']:>8.0%} {r['events']:>6}")
        if (cams, n) == PAPER[:2]:
            print(f"   seed 000: {PAPER[0]} cameras x {PAPER[1]} characters at {PAPER[2]:.0f} fps (Unity, crowd "
                  f"included): {r['steps_per_s'] / PAPER[2]:.1f}x")
        if (cams, n) == (100, 10_000):
            print(f"   target >= {TARGET_STEPS:.0f} steps/s: {r['steps_per_s'] / TARGET_STEPS:.2f}x of target")
            if peer:
                print(f"   the machine's load: JuPedSim's 10,000-agent crowd step at "
                      f"{r['jupedsim_10k_before']:.1f} steps/s just before, "
                      f"{r['jupedsim_10k_after']:.1f} just after (tools/bench_sim.py's scene)")
    return rows


if __name__ == "__main__":
    args = sys.argv[1:]
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))      # bench_sim, the peer's timing
    if args:
        run(tuple(tuple(int(x) for x in a.split(":")) for a in args))
    else:
        run()
