"""Does usdcrowd's crowd move like people? Corridors and bottlenecks against the field's data and JuPedSim.

    python tools/bench_realism.py [--record] [--quick] [--tune]

The same scenes, the same start positions and free speeds, are simulated by
usdcrowd (every force on, as `usdcrowd simulate` runs) and, in the same
run, by JuPedSim's collision-free speed model; both trajectories go through
PedPy (the JuPedSim team's analysis library, in its own venv, as the field
measures experiments):

- a unidirectional and a bidirectional corridor (60 m x 4 m, people filling
  part of it walk through): Voronoi density (cells cut off at 1 m) and
  the mean speed of the people in a 8 m x 4 m measurement area, frame by
  frame (the Voronoi speed counts the part of the area no cut-off cell
  covers as standing still, and so reads low at low densities); the pairs against Weidmann's
  fundamental diagram (free speed 1.34 m/s, gamma 1.913, jam density
  5.4 per square metre), RMSE over densities 0.5-3 per square metre;
- a bottleneck of 0.8 to 2.4 m width (150 people leave a 10 m x 10 m room
  through a 4 m passage): the flow through a line across the passage's
  middle between the 10th and the 90th percent of passages, per metre of
  width, against the Jülich experiments' 1.6-2.0 persons per metre per
  second (Seyfried et al. 2009; Rupprecht et al. 2011);
- every agent's largest speed over any half second, against its own
  maximum speed.

Free speeds are drawn from Weidmann's N(1.34, 0.26) m/s, clipped to
0.8-2.0. Writes docs/images/realism.png and, with --record (or
`python tools/bench.py realism --record`), docs/data/bench_realism.json.
With --tune it runs usdcrowd alone and prints, beside the RMSE, the mean
residual against Weidmann per density bin: for tuning the crowd's parameters
(it draws and records nothing).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tools"))          # bench_sim, its sibling

FPS = 16.0                   # recorded frames per second (what PedPy analyses)
DT = 0.01                    # both simulators' step, s
WEIDMANN = {"v0": 1.34, "gamma": 1.913, "rho_max": 5.4}
JULICH_BAND = (1.6, 2.0)     # specific flow through bottlenecks, persons / m / s
WIDTHS = (0.8, 1.2, 1.6, 2.0, 2.4)
CORRIDOR = (60.0, 4.0)       # length, width (m)
IMAGE = ROOT / "docs" / "images" / "realism.png"


def weidmann(rho):
    """Weidmann's speed (m/s) at density ``rho`` (per square metre)."""
    w = WEIDMANN
    rho = np.asarray(rho, dtype=np.float64)
    return w["v0"] * (1.0 - np.exp(-w["gamma"] * (1.0 / np.maximum(rho, 1e-9) - 1.0 / w["rho_max"])))


# ---------------------------------------------------------------------------------------------- scenes
class Scene:
    """Walls (convex polygons), bounds, the walkable polygon, starts, goals, free speeds, where to measure."""

    def __init__(self, name, walls, bounds, start, goal, speed, area=None, line=None, width=None, exits=None):
        self.name, self.walls, self.bounds = name, walls, np.asarray(bounds, dtype=np.float64)
        self.start, self.goal, self.speed = start, goal, speed
        self.area, self.line, self.width, self.exits = area, line, width, exits

    def walkable(self):
        import shapely

        (x0, y0), (x1, y1) = self.bounds
        return shapely.box(x0, y0, x1, y1).difference(shapely.union_all([shapely.Polygon(w) for w in self.walls]))


def _box(x0, y0, x1, y1):
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float64)


def _fill(rng, n, x0, x1, y0, y1, radius=0.25):
    """(n, 2) starts on a jittered lattice over a rectangle, no two closer than two radii (JuPedSim refuses
    closer); too many for the rectangle is an error."""
    gap = 2.1 * radius
    rows = max(1, min(int(np.ceil((y1 - y0) / np.sqrt((x1 - x0) * (y1 - y0) / n))), int((y1 - y0) // gap)))
    cols = int(np.ceil(n / rows))
    if (x1 - x0) / cols < gap:
        raise ValueError(f"{n} people do not fit {x1 - x0:g} m x {y1 - y0:g} m")
    ij = np.stack(np.unravel_index(rng.permutation(cols * rows)[:n], (cols, rows)), axis=1).astype(np.float64)
    cell = np.array([(x1 - x0) / cols, (y1 - y0) / rows])
    jitter = rng.uniform(-0.5, 0.5, (n, 2)) * np.maximum(cell - gap, 0.0)
    return np.array([x0, y0]) + (ij + 0.5) * cell + jitter


def _speeds(rng, n):
    return np.clip(rng.normal(1.34, 0.26, n), 0.8, 2.0)


def corridor(n: int, both_ways: bool, seed: int = 0) -> Scene:
    """People spread over the corridor's first 30 m (both ways: the halves from either end) walking through."""
    length, width = CORRIDOR
    rng = np.random.default_rng(seed)
    walls = [_box(0.0, -0.5, length, 0.0), _box(0.0, width, length, width + 0.5)]
    if both_ways:
        a = _fill(rng, n // 2, 1.0, 27.0, 0.3, width - 0.3)
        b = _fill(rng, n - n // 2, length - 27.0, length - 1.0, 0.3, width - 0.3)
        start = np.concatenate([a, b])
        goal = np.where(np.arange(n)[:, None] < n // 2, [[length + 12.0, width / 2]], [[-12.0, width / 2]])
        area = _box(26.0, 0.0, 34.0, width)
    else:
        start = _fill(rng, n, 1.0, 30.0, 0.3, width - 0.3)
        goal = np.tile([[length + 12.0, width / 2]], (n, 1))
        area = _box(36.0, 0.0, 44.0, width)
    bounds = [[-15.0, -0.5], [length + 15.0, width + 0.5]]
    return Scene(f"corridor_{'bi' if both_ways else 'uni'}_{n}", walls, bounds, start, goal, _speeds(rng, n),
                 area=area)


def bottleneck(width: float, n: int = 150, seed: int = 0) -> Scene:
    """A 10 m x 10 m room, left of a 4 m passage ``width`` wide, into an open area; the line across its middle."""
    rng = np.random.default_rng(seed)
    h = width / 2.0
    walls = [_box(0.0, h, 4.0, 8.0), _box(0.0, -8.0, 4.0, -h), _box(-10.5, 5.0, 0.0, 8.0),
             _box(-10.5, -8.0, 0.0, -5.0), _box(-10.5, -5.0, -10.0, 5.0)]
    start = _fill(rng, n, -9.7, -0.6, -4.7, 4.7)
    goal = np.tile([[22.0, 0.0]], (n, 1))
    return Scene(f"bottleneck_{width:g}", walls, [[-10.5, -8.0], [25.0, 8.0]], start, goal, _speeds(rng, n),
                 line=[[2.0, -h], [2.0, h]], width=width)


# ------------------------------------------------------------------------------------------ simulators
def run_usdcrowd(scene: Scene, seconds: float) -> np.ndarray:
    """(k, n, 2) positions at FPS of usdcrowd's simulation of ``scene`` (every force on)."""
    from usdcrowd.core.model import (BEHAVIORS, CONDITIONS, ROLES, AgentTable, GroupTable, InterestTable, Obstacles,
                                     Scenario, TimeRange, code)
    from usdcrowd.sim import SimSettings, Simulation

    n = len(scene.start)
    z8 = lambda v: np.full(n, v, np.int8)  # noqa: E731
    agents = AgentTable(
        path=[f"/a{i}" for i in range(n)], agent_id=np.arange(1, n + 1, dtype=np.int32),
        group=np.arange(n, dtype=np.int32), leader=np.full(n, -1, np.int32), role=z8(code(ROLES, "leader")),
        character_type=z8(0), personality=z8(0), behavior=z8(code(BEHAVIORS, "walk")),
        condition=z8(code(CONDITIONS, "isolated")), fear_response=z8(0), visit_profile=z8(0),
        speed=scene.speed.astype(np.float64), height=np.full(n, 1.75), max_slope=np.full(n, 1.0),
        map_influence=np.full(n, 1.0), color=np.full((n, 3), 0.5),
        start=np.column_stack([scene.start, np.zeros(n)]),
        start_heading=np.arctan2(scene.goal[:, 1] - scene.start[:, 1], scene.goal[:, 0] - scene.start[:, 0]))
    groups = GroupTable([f"/g{i}" for i in range(n)], np.full(n, -1, np.int32),
                        np.column_stack([scene.goal, np.zeros(n)]), np.full(n, 600.0), np.arange(n, dtype=np.int32))
    frames = int(round(seconds * FPS))
    sc = Scenario(scene.name, TimeRange(1, frames, FPS), 0, groups, agents, [], InterestTable.empty(),
                  Obstacles([f"/w{i}" for i in range(len(scene.walls))], scene.walls, np.full(len(scene.walls), 2.5)),
                  scene.bounds)
    sim = Simulation(sc, SimSettings(fps=FPS, substeps=int(round(1.0 / (FPS * DT)))))
    return np.asarray(sim.frames(frames, 1.0).position[:, :, :2], dtype=np.float64)


def run_jupedsim(scene: Scene, seconds: float) -> np.ndarray | None:
    """(k, n, 2) positions at FPS of JuPedSim's collision-free speed model (NaN once an agent has left)."""
    try:
        import jupedsim as jps
    except ImportError:
        return None
    import shapely

    sim = jps.Simulation(model=jps.CollisionFreeSpeedModel(), geometry=scene.walkable(), dt=DT)
    exits = {}
    ids = []
    for i, (p, g, v) in enumerate(zip(scene.start, scene.goal, scene.speed)):
        key = (round(float(g[0]), 3), round(float(g[1]), 3))
        if key not in exits:
            poly = shapely.Point(key).buffer(1.5).intersection(scene.walkable())
            stage = sim.add_exit_stage(poly)
            exits[key] = (sim.add_journey(jps.JourneyDescription([stage])), stage)
        journey, stage = exits[key]
        ids.append(sim.add_agent(jps.CollisionFreeSpeedModelAgentParameters(
            journey_id=journey, stage_id=stage, position=(float(p[0]), float(p[1])), desired_speed=float(v),
            radius=0.25)))
    row = {a: k for k, a in enumerate(ids)}
    every = int(round(1.0 / (FPS * DT)))
    frames = int(round(seconds * FPS))
    out = np.full((frames, len(ids), 2), np.nan)
    for f in range(frames):
        for agent in sim.agents():
            out[f, row[agent.id]] = agent.position
        for _ in range(every):
            sim.iterate()
    return out


# ------------------------------------------------------------------------------------------- analysis
ANALYSIS = textwrap.dedent("""
    import json, sys
    import numpy as np, pandas as pd, shapely
    import pedpy
    d = np.load(sys.argv[1], allow_pickle=False)
    spec = json.loads(str(d["spec"]))
    xy = d["xy"]
    k, n, _ = xy.shape
    f, i = np.nonzero(np.isfinite(xy[..., 0]))
    traj = pedpy.TrajectoryData(pd.DataFrame({"id": i + 1, "frame": f, "x": xy[f, i, 0], "y": xy[f, i, 1]}),
                                frame_rate=spec["fps"])
    out = {}
    walkable = pedpy.WalkableArea(shapely.from_wkt(spec["walkable"]))
    if spec.get("area"):
        area = pedpy.MeasurementArea(spec["area"])
        polys = pedpy.compute_individual_voronoi_polygons(traj_data=traj, walkable_area=walkable,
                                                          cut_off=pedpy.Cutoff(radius=1.0, quad_segments=3))
        density, inter = pedpy.compute_voronoi_density(individual_voronoi_data=polys, measurement_area=area)
        speed = pedpy.compute_individual_speed(traj_data=traj, frame_step=int(spec["fps"] // 2),
                                               speed_calculation=pedpy.SpeedCalculation.BORDER_SINGLE_SIDED)
        vs = pedpy.compute_mean_speed_per_frame(traj_data=traj, individual_speed=speed, measurement_area=area)
        both = density.merge(vs, on="frame")
        both = both[both["density"] > 0.05]
        out["density"] = both["density"].tolist()
        out["speed"] = both["speed"].tolist()
    if spec.get("line"):
        nt, crossing = pedpy.compute_n_t(traj_data=traj, measurement_line=pedpy.MeasurementLine(spec["line"]))
        out["crossing_frames"] = sorted(crossing["frame"].tolist())
    print(json.dumps(out))
""")


def pedpy_python() -> str:
    """The PedPy venv ($USDCROWD_PEDPY_VENV, else made once in the temporary folder, as the tests make it)."""
    from tool_venvs import PEDPY, tool_venv

    return tool_venv("pedpy", "USDCROWD_PEDPY_VENV", PEDPY)


def analyse(scene: Scene, xy: np.ndarray, python: str) -> dict:
    """PedPy's Voronoi density, mean speed and line crossings of trajectories ``xy`` ((k, n, 2), NaN: absent)."""
    import shapely

    spec = {"fps": FPS, "walkable": shapely.to_wkt(scene.walkable()),
            "area": scene.area.tolist() if scene.area is not None else None, "line": scene.line}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "traj.npz"
        np.savez(path, xy=xy, spec=json.dumps(spec))
        r = subprocess.run([python, "-c", ANALYSIS, str(path)], capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"PedPy failed on {scene.name}: {r.stderr[-2000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def fundamental_rmse(density, speed, lo: float = 0.5, hi: float = 3.0) -> dict:
    """RMSE (m/s) of measured speeds against Weidmann's over densities ``lo``-``hi``, and the frames it counts."""
    density, speed = np.asarray(density), np.asarray(speed)
    sel = (density >= lo) & (density <= hi)
    if not sel.any():
        return {"rmse": None, "frames": 0}
    return {"rmse": float(np.sqrt(np.mean((speed[sel] - weidmann(density[sel])) ** 2))), "frames": int(sel.sum())}


def specific_flow(crossing_frames, width: float) -> float | None:
    """Persons per metre per second through the line between the 10th and 90th percent of its passages."""
    c = np.sort(np.asarray(crossing_frames, dtype=np.float64))
    if len(c) < 10:
        return None
    a, b = int(0.1 * len(c)), int(0.9 * len(c))
    seconds = (c[b] - c[a]) / FPS
    return float((b - a) / seconds / width) if seconds > 0 else None


def width_key(w: float) -> str:
    """A bottleneck's key in the record: ``w1_6`` for 1.6 m (the pages' figure paths split at dots)."""
    return "w" + f"{w:.1f}".replace(".", "_")


def overspeed(xy: np.ndarray, speed: np.ndarray) -> float:
    """The largest ratio of an agent's speed over half a second to its free speed."""
    half = int(FPS // 2)
    v = np.linalg.norm(xy[half:] - xy[:-half], axis=-1) / (half / FPS)
    return float(np.nanmax(v / speed[None]))


# ------------------------------------------------------------------------------------------------ main
def run(quick: bool = False, jupedsim: bool = True) -> dict:
    """Simulate, analyse and plot every scene (docs/images/realism.png); print and return the summary.
    With ``jupedsim`` (the default) JuPedSim, the peer, must be installed (else one line and exit)."""
    if jupedsim:
        from bench_sim import require_jupedsim

        require_jupedsim("realism")
    t0 = time.perf_counter()
    results = measure(quick)
    plot(results, IMAGE)
    summary = {
        "corridor_uni": {s: results["corridor_uni"][s]["rmse"] for s in ("usdcrowd", "jupedsim")},
        "corridor_bi": {s: results["corridor_bi"][s]["rmse"] for s in ("usdcrowd", "jupedsim")},
        "frames": {k: {s: results[k][s]["frames"] for s in ("usdcrowd", "jupedsim")}
                   for k in ("corridor_uni", "corridor_bi")},
        "bottleneck": results["bottleneck"], "julich_band": list(JULICH_BAND),
        "overspeed": results["overspeed"], "overspeed_max": max(results["overspeed"].values()),
        "seconds": time.perf_counter() - t0, "machine": f"{platform.machine()}, {os.cpu_count()} cores",
    }
    print(json.dumps(summary, indent=1))
    return summary


def measure(quick: bool = False, sims=("usdcrowd", "jupedsim")) -> dict:
    """Every scene by both simulators (or those named), through PedPy: density and speed pairs, flows,
    overspeeds."""
    python = pedpy_python()
    corridor_counts = (40, 160, 320) if quick else (40, 80, 160, 240, 320)
    widths = WIDTHS[::2] if quick else WIDTHS
    results = {"corridor_uni": {}, "corridor_bi": {}, "bottleneck": {}, "overspeed": {}}
    for both in (False, True):
        key = "corridor_bi" if both else "corridor_uni"
        for sim_name in sims:
            pairs = {"density": [], "speed": []}
            for n in corridor_counts:
                scene = corridor(n, both)
                t0 = time.perf_counter()
                xy = (run_usdcrowd if sim_name == "usdcrowd" else run_jupedsim)(scene, 45.0)
                if xy is None:
                    raise SystemExit("JuPedSim is missing: pip install 'usdcrowd[bench]'")
                got = analyse(scene, xy, python)
                pairs["density"] += got["density"]
                pairs["speed"] += got["speed"]
                if sim_name == "usdcrowd":
                    results["overspeed"][scene.name] = overspeed(xy, scene.speed)
                print(f"{key} {sim_name} n={n}: {len(got['density'])} frames, "
                      f"{time.perf_counter() - t0:.0f} s", flush=True)
            results[key][sim_name] = {**pairs, **fundamental_rmse(pairs["density"], pairs["speed"])}
            print(f"{key} {sim_name}: RMSE {results[key][sim_name]['rmse']}", flush=True)
    for w in widths:
        scene = bottleneck(w)
        row = {}
        for sim_name in sims:
            xy = (run_usdcrowd if sim_name == "usdcrowd" else run_jupedsim)(scene, 150.0)
            got = analyse(scene, xy, python)
            row[sim_name] = specific_flow(got["crossing_frames"], w)
            row[f"{sim_name}_passed"] = len(got["crossing_frames"])
            if sim_name == "usdcrowd":
                results["overspeed"][scene.name] = overspeed(xy, scene.speed)
        results["bottleneck"][width_key(w)] = {"width_m": w, **row}
        print(f"bottleneck {w:g} m: {row}", flush=True)
    return results


def residuals_by_density(density, speed, edges=(0.5, 1.0, 1.5, 2.0, 2.5, 3.0)) -> list:
    """(low, high, mean measured minus Weidmann's speed in m/s, frames) per density bin that has frames."""
    density, speed = np.asarray(density), np.asarray(speed)
    out = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = (density >= lo) & (density < hi)
        if sel.any():
            out.append((lo, hi, float(np.mean(speed[sel] - weidmann(density[sel]))), int(sel.sum())))
    return out


def tune(quick: bool = False) -> dict:
    """usdcrowd alone, for tuning its parameters: each corridor's RMSE and its mean residual per density
    bin, each bottleneck's flow, the overspeed. Nothing drawn or recorded (the peer is not run)."""
    results = measure(quick, sims=("usdcrowd",))
    for key in ("corridor_uni", "corridor_bi"):
        r = results[key]["usdcrowd"]
        bins = "  ".join(f"{lo:g}-{hi:g}: {d:+.2f} ({n})" for lo, hi, d, n in
                         residuals_by_density(r["density"], r["speed"]))
        print(f"{key}: RMSE {r['rmse']:.3f} m/s; mean residual per density bin (1/m2), frames: {bins}")
    flows = {row["width_m"]: row["usdcrowd"] for row in results["bottleneck"].values()}
    print("bottleneck specific flows:", ", ".join(f"{w:g} m {f:.2f}" for w, f in sorted(flows.items())),
          f"(band {JULICH_BAND[0]:g}-{JULICH_BAND[1]:g})")
    print(f"fastest agent / its free speed: {max(results['overspeed'].values()):.4f}")
    return results


def plot(results: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(15, 4.2))
    rho = np.linspace(0.3, 4.5, 100)
    for k, key in enumerate(("corridor_uni", "corridor_bi")):
        for sim_name, colour in (("usdcrowd", "#4c72b0"), ("jupedsim", "#dd8452")):
            r = results[key][sim_name]
            rmse = f"{r['rmse']:.2f}" if r["rmse"] is not None else "n/a"
            ax[k].scatter(r["density"], r["speed"], s=3, alpha=0.3, color=colour, label=f"{sim_name} (RMSE {rmse} m/s)")
        ax[k].plot(rho, weidmann(rho), "k-", label="Weidmann")
        ax[k].set_xlabel("Voronoi density (1/m²)")
        ax[k].set_ylabel("mean speed in the area (m/s)")
        ax[k].set_xlim(0, 4.5)
        ax[k].set_ylim(0, 2.0)
        ax[k].set_title(f"{'Uni' if k == 0 else 'Bi'}directional corridor")
        ax[k].legend(fontsize=8)
    rows = sorted(results["bottleneck"].values(), key=lambda r: r["width_m"])
    for sim_name, colour in (("usdcrowd", "#4c72b0"), ("jupedsim", "#dd8452")):
        ax[2].plot([r["width_m"] for r in rows], [r[sim_name] for r in rows], "o-", color=colour,
                   label=sim_name)
    ax[2].axhspan(*JULICH_BAND, color="0.85", label="Jülich experiments")
    ax[2].set_xlabel("bottleneck width (m)")
    ax[2].set_ylabel("specific flow (1/m/s)")
    ax[2].set_title("Bottleneck")
    ax[2].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--record", action="store_true", help="record the figures to docs/data/bench_realism.json")
    p.add_argument("--quick", action="store_true", help="three corridor fillings and three widths")
    p.add_argument("--tune", action="store_true",
                   help="usdcrowd alone, with the residuals per density bin (for tuning; draws and records nothing)")
    a = p.parse_args(argv)
    if a.tune:
        if a.record:
            p.error("--tune runs usdcrowd alone: nothing to record")
        tune(a.quick)
        return 0
    summary = run(a.quick)
    if a.record:
        sys.path.insert(0, str(ROOT / "tools"))
        from docfigures import record

        record("bench_realism", "tools/bench_realism.py", figures=summary, images=["docs/images/realism.png"],
               command="python tools/bench.py realism --record")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
