"""Benchmark of usdcrowd.sim against JuPedSim on the same scene.

Scene: a 200 m x 200 m square, agents spread over it on a
jittered lattice, half heading for a waypoint near the west edge and half
for one near the east edge (JuPedSim: a journey shuttling between the two).
usdcrowd runs with every force on: steering, time-to-impact avoidance of
agents and of the square's walls (four wall obstacles around the square),
personal-space separation, flocking and velocity matching (groups of 8 with
a leader each; members follow it with line-of-sight memory), containment,
overlap and wall constraints, heading turn limits, plus an explosion
behavior map (health and reactions) at the start. Fixed dt = 0.01 s for both.

Usage::

    python tools/bench_sim.py                 # 1k, 10k, 100k
    python tools/bench_sim.py 1000 10000      # chosen sizes
"""

from __future__ import annotations

import os
import sys
import time
import tracemalloc

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from usdcrowd.core.model import (BEHAVIORS, LAYER_GENERATORS, LAYER_MEANINGS, ROLES, AgentTable, BehaviorField,
                                 GroupTable, InterestTable, Obstacles, Scenario, TimeRange, code)
from usdcrowd.sim import SimSettings, Simulation  # noqa: E402

SIDE = 200.0  # m
DT = 0.01  # s
GROUP = 8  # agents per group (one leader)


def positions(n: int, seed: int = 0) -> np.ndarray:
    """(n, 2) jittered-lattice positions inside the square (no initial overlap)."""
    rng = np.random.default_rng(seed)
    m = int(np.ceil(np.sqrt(n)))
    step = (SIDE - 4.0) / m
    ij = np.stack(np.unravel_index(np.arange(n), (m, m)), axis=1).astype(float)
    jitter = rng.uniform(-0.25, 0.25, (n, 2)) * max(step - 0.55, 0.0)
    return -SIDE / 2 + 2.0 + (ij + 0.5) * step + jitter


def scene(n: int, seed: int = 0, maps: bool = True) -> Scenario:
    """The benchmark scenario for ``n`` agents (groups of 8, two waypoints)."""
    xy = positions(n, seed)
    g = int(np.ceil(n / GROUP))
    group = np.arange(n) // GROUP
    first = np.arange(g) * GROUP
    leader = np.where(np.arange(n) % GROUP == 0, -1, first[group]).astype(np.int32)
    role = np.where(leader < 0, code(ROLES, "leader"), code(ROLES, "member")).astype(np.int8)
    goals = np.zeros((g, 3))
    gx = np.zeros(g)
    # Each group heads for the waypoint on the opposite side of where it stands.
    gx = np.where(xy[first, 0] < 0, SIDE / 2 - 10.0, -SIDE / 2 + 10.0)
    goals[:, 0] = gx
    z8 = lambda v, dt=np.int8: np.full(n, v, dt)  # noqa: E731
    agents = AgentTable(
        path=[f"/a{i}" for i in range(n)], agent_id=np.arange(1, n + 1, dtype=np.int32),
        group=group.astype(np.int32), leader=leader, role=role, character_type=z8(0), personality=z8(0),
        behavior=z8(code(BEHAVIORS, "walk")), condition=z8(0), fear_response=z8(0), visit_profile=z8(0),
        speed=np.random.default_rng(seed + 1).uniform(1.1, 1.5, n), height=np.full(n, 1.75),
        max_slope=np.full(n, 1.0), map_influence=np.full(n, 1.0), color=np.full((n, 3), 0.5),
        start=np.concatenate([xy, np.zeros((n, 1))], axis=1), start_heading=np.zeros(n))
    groups = GroupTable([f"/g{i}" for i in range(g)], np.full(g, -1, np.int32), goals, np.full(g, 600.0),
                        first.astype(np.int32))
    h = SIDE / 2
    t = 0.5  # wall thickness, m
    walls = [np.array([[-h - t, -h - t], [h + t, -h - t], [h + t, -h], [-h - t, -h]]),
             np.array([[-h - t, h], [h + t, h], [h + t, h + t], [-h - t, h + t]]),
             np.array([[-h - t, -h], [-h, -h], [-h, h], [-h - t, h]]),
             np.array([[h, -h], [h + t, -h], [h + t, h], [h, h]])]
    fields = []
    if maps:
        fields.append(BehaviorField("/blast", code(LAYER_MEANINGS, "damage"), code(LAYER_GENERATORS, "explosion"),
                                    None, np.array([-h, -h]), np.array([h, h]), origin=np.array([-60.0, -60.0, 0]),
                                    radius=10.0, start_time=1.0))
    return Scenario("bench", TimeRange(1, 10, 1.0 / DT), seed, groups, agents, fields, InterestTable.empty(),
                    Obstacles([f"/w{i}" for i in range(4)], walls, np.full(4, 3.0)),
                    np.array([[-h - t, -h - t], [h + t, h + t]]))


def bench_usdcrowd(n: int, steps: int, warmup: int = 3, threads: int | None = None) -> dict:
    """Steps per second and peak traced memory (MiB) of usdcrowd.sim on the scene, its compiled loops on
    ``threads`` cores (default all)."""
    import numba

    sc = scene(n)
    t0 = time.perf_counter()
    sim = Simulation(sc, SimSettings(fps=1.0 / DT, substeps=1))
    setup = time.perf_counter() - t0
    for _ in range(warmup):
        sim.step()
    every = numba.get_num_threads()
    numba.set_num_threads(threads or every)
    try:
        t0 = time.perf_counter()
        for _ in range(steps):
            sim.step()
        el = time.perf_counter() - t0
    finally:
        numba.set_num_threads(every)
    if threads is not None:
        return {"agents": n, "steps_per_s": steps / el, "threads": threads}
    assert np.all(np.isfinite(sim.pos))
    # Peak memory in a separate pass: tracemalloc slows numpy's allocations.
    tracemalloc.start()
    sim = Simulation(sc, SimSettings(fps=1.0 / DT, substeps=1))
    for _ in range(warmup):
        sim.step()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return {"agents": n, "steps_per_s": steps / el, "setup_s": setup, "peak_mib": peak / 2 ** 20,
            "rebuilds": sim.nl.rebuilds, "threads": every}


def cold_start(n: int = 1000) -> dict:
    """Seconds to a first step in a fresh interpreter: with nothing compiled yet (an empty numba cache, as
    on a machine's first run) and with the cache filled by it. Returns ``compile_s`` and ``cached_s``."""
    import subprocess
    import tempfile

    code = ("import sys, time; sys.path[:0] = [{root!r}, {tools!r}]; t = time.perf_counter(); import bench_sim; "
            "from usdcrowd.sim import SimSettings, Simulation; "
            "Simulation(bench_sim.scene({n}), SimSettings(fps=100.0, substeps=1)).step(); "
            "print(time.perf_counter() - t)")
    here = os.path.dirname(os.path.abspath(__file__))
    code = code.format(root=os.path.dirname(here), tools=here, n=n)
    out = {}
    with tempfile.TemporaryDirectory() as cache:
        for key in ("compile_s", "cached_s"):
            done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                                  env={**os.environ, "NUMBA_CACHE_DIR": cache})
            out[key] = float(done.stdout.split()[-1])
    return out


def over_a_run(n: int = 1000, steps: int = 900, block: int = 100, jupedsim: bool = True) -> dict:
    """Steps per second of each ``block`` of a ``steps``-long run of both simulators: a cost that grows
    as a run goes on shows here. The two take turns block by block, so each pair of blocks meets the
    machine in the same state and their ratio shows growth that the machine's drift would hide.
    Returns ``usdcrowd`` and ``jupedsim`` lists, one rate per block, and ``ratio`` (usdcrowd's over
    JuPedSim's, block by block)."""
    def timed(step):
        t0 = time.perf_counter()
        for _ in range(block):
            step()
        return block / (time.perf_counter() - t0)

    sim = Simulation(scene(n), SimSettings(fps=1.0 / DT, substeps=1))
    steppers = {"usdcrowd": sim.step}
    if jupedsim:
        peer = _jupedsim_simulation(n)
        steppers["jupedsim"] = peer.iterate
    for step in steppers.values():
        for _ in range(3):              # warm-up, as the rate rows have
            step()
    out = {"agents": n, "steps": steps, "block": block, **{name: [] for name in steppers}}
    for _ in range(steps // block):
        for name, step in steppers.items():
            out[name].append(timed(step))
    if jupedsim:
        out["ratio"] = [a / b for a, b in zip(out["usdcrowd"], out["jupedsim"])]
        # One block is noisy (a neighbour's burst on a shared machine): growth is read off the medians
        # of the first and the last third of the run.
        third = max(1, len(out["ratio"]) // 3)
        out["ratio_first_third"] = float(np.median(out["ratio"][:third]))
        out["ratio_last_third"] = float(np.median(out["ratio"][-third:]))
    return out


def require_jupedsim(section: str) -> None:
    """Stop with one line naming the missing peer and how to install it (a benchmark that compares with
    JuPedSim and prints n/a in its place says nothing)."""
    try:
        import jupedsim  # noqa: F401
        import shapely  # noqa: F401
    except ImportError as exc:
        raise SystemExit(f"tools/bench.py {section}: JuPedSim, the peer it is measured against, is missing ({exc}): "
                         "pip install -e '.[bench]' (or make bench), or --allow-missing-peers to measure "
                         "usdcrowd alone") from None


def _jupedsim_simulation(n: int):
    """JuPedSim's CollisionFreeSpeedModel set up on the scene (a journey shuttling between the waypoints)."""
    import jupedsim as jps
    import shapely

    h = SIDE / 2
    sim = jps.Simulation(model=jps.CollisionFreeSpeedModel(),
                         geometry=shapely.Polygon([(-h, -h), (h, -h), (h, h), (-h, h)]), dt=DT)
    west = sim.add_waypoint_stage((-h + 10.0, 0.0), 5.0)
    east = sim.add_waypoint_stage((h - 10.0, 0.0), 5.0)
    journey = jps.JourneyDescription([west, east])
    journey.set_transition_for_stage(west, jps.Transition.create_fixed_transition(east))
    journey.set_transition_for_stage(east, jps.Transition.create_fixed_transition(west))
    jid = sim.add_journey(journey)
    xy = positions(n)
    speed = np.random.default_rng(1).uniform(1.1, 1.5, n)
    for i in range(n):  # JuPedSim's API adds agents one by one
        stage = east if xy[i, 0] < 0 else west
        sim.add_agent(jps.CollisionFreeSpeedModelAgentParameters(
            journey_id=jid, stage_id=stage, position=(float(xy[i, 0]), float(xy[i, 1])), desired_speed=float(speed[i]),
            radius=0.25))
    return sim


def bench_jupedsim(n: int, steps: int, warmup: int = 3) -> float | None:
    """Steps per second of JuPedSim's CollisionFreeSpeedModel on the same scene, or None."""
    try:
        sim = _jupedsim_simulation(n)
    except ImportError:
        return None
    for _ in range(warmup):
        sim.iterate()
    t0 = time.perf_counter()
    for _ in range(steps):
        sim.iterate()
    return steps / (time.perf_counter() - t0)


FEW = 50  # agents: a crowd this small times what a step costs whatever its size


def run(sizes=(1000, 10000, 100000), steps=None, jupedsim: bool = True, rounds: int = 5,
        cold: bool = False) -> list[dict]:
    """Benchmark usdcrowd.sim (and JuPedSim) at each size in interleaved rounds; print and return a table.

    Parameters
    ----------
    sizes : iterable of int
        Agent counts.
    steps : int or dict, optional
        Timed steps (default: 600 / 60 / 12 by size).
    jupedsim : bool
        Also time JuPedSim, the peer each row is measured against; missing, it is an error
        (:func:`require_jupedsim`), not a column of n/a.
    rounds : int
        usdcrowd then JuPedSim, this many times per size: the machine's speed drifts, so the
        rates are medians and the ratio is the median of each round's ratio. Each round times
        usdcrowd twice, on all cores and on one (JuPedSim runs on one).
    cold : bool
        Also time a first run's compilation of the step's loops (:func:`cold_start`).

    Returns
    -------
    list of dict
        Keys: agents, steps_per_s, one_thread_steps_per_s, threads, setup_s, peak_mib, rebuilds,
        jupedsim_steps_per_s, ratio, one_thread_ratio, rounds (each round's usdcrowd, JuPedSim and
        one-thread rates); the first row also cold_start.
    """
    if jupedsim:
        require_jupedsim("sim")
    import numba

    rows = []
    print(f"usdcrowd's compiled loops on {numba.get_num_threads()} threads (and on 1), JuPedSim on its one")
    print(f"{'agents':>8} {'steps/s':>9} {'1 thread':>9} {'setup s':>8} {'peak MiB':>9} {'JuPedSim/s':>11} "
          f"{'ratio':>7} {'1 thread':>9}  (medians of {rounds} interleaved rounds)")
    for n in sizes:
        k = steps if isinstance(steps, int) else (steps or {}).get(n, 600 if n <= 2000 else 60 if n <= 20000 else 12)
        seen = []
        for _ in range(rounds):
            r = bench_usdcrowd(n, k)
            one = bench_usdcrowd(n, k, threads=1)["steps_per_s"]
            j = bench_jupedsim(n, max(3, k // 2 if n > 20000 else k)) if jupedsim else None
            seen.append((r, j, one))
        r = dict(seen[-1][0])
        r["steps_per_s"] = float(np.median([a["steps_per_s"] for a, _, _ in seen]))
        r["one_thread_steps_per_s"] = float(np.median([o for _, _, o in seen]))
        r["rounds"] = [[a["steps_per_s"], b, o] for a, b, o in seen]
        j = float(np.median([b for _, b, _ in seen])) if jupedsim else None
        r["jupedsim_steps_per_s"] = j
        r["ratio"] = float(np.median([a["steps_per_s"] / b for a, b, _ in seen])) if jupedsim else None
        r["one_thread_ratio"] = float(np.median([o / b for _, b, o in seen])) if jupedsim else None
        if jupedsim:
            each = [a["steps_per_s"] / b for a, b, _ in seen]
            r["ratio_range"] = [float(min(each)), float(max(each))]
        rows.append(r)
        js = f"{j:11.1f}" if j else f"{'n/a':>11}"
        rt = f"{r['ratio']:7.2f} {r['one_thread_ratio']:9.2f}" if j else f"{'n/a':>7} {'n/a':>9}"
        spread = f"  (ratio {r['ratio_range'][0]:.2f}-{r['ratio_range'][1]:.2f} over the rounds)" if j else ""
        print(f"{n:8d} {r['steps_per_s']:9.1f} {r['one_thread_steps_per_s']:9.1f} {r['setup_s']:8.2f} "
              f"{r['peak_mib']:9.1f} {js} {rt}{spread}", flush=True)
    if 1000 in sizes:
        _beside_the_1000_row(rows[list(sizes).index(1000)], jupedsim, rounds)
    if cold:
        c = cold_start()
        rows[0]["cold_start"] = c
        print(f"   a first run on a machine: {c['compile_s']:.1f} s to the first step, compiling the step's loops "
              f"(cached after: {c['cached_s']:.2f} s)")
    return rows


def _beside_the_1000_row(row: dict, jupedsim: bool, rounds: int) -> None:
    """Add to the 1,000-agent row, and print, the run-long rates (:func:`over_a_run`) and what a step
    costs whatever the crowd (``FEW`` agents, ``rounds`` medians): ``over_a_run`` and ``few_agents``."""
    long = over_a_run(1000, jupedsim=jupedsim)
    row["over_a_run"] = long
    for name in ("usdcrowd", "jupedsim"):
        if name in long:
            rates = long[name]
            print(f"   {name}, 1,000 agents over {long['steps']} steps, steps/s per {long['block']}: "
                  f"{' '.join(f'{x:.0f}' for x in rates)} (last / first {rates[-1] / rates[0]:.2f})")
    if "ratio" in long:
        print(f"   usdcrowd / JuPedSim block by block (taking turns): {' '.join(f'{x:.2f}' for x in long['ratio'])} "
              f"(median {long['ratio_first_third']:.2f} in the first third, {long['ratio_last_third']:.2f} in the last)")
    few = float(np.median([bench_usdcrowd(FEW, 600)["steps_per_s"] for _ in range(rounds)]))
    row["few_agents"] = {"agents": FEW, "step_us": 1e6 / few, "share_at_1000": row["steps_per_s"] / few}
    print(f"   a step of {FEW} agents (what every step costs whatever the crowd: the step's Python and its "
          f"loops' calls): {1e6 / few:.0f} us, {row['steps_per_s'] / few:.0%} of a 1,000-agent step")


if __name__ == "__main__":
    args = [int(a) for a in sys.argv[1:]]
    run(tuple(args) if args else (1000, 10000, 100000))
