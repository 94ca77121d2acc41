"""usdcrowd benchmarks: each section prints sizes, rates and ratios.

    python tools/bench.py                 # every section
    python tools/bench.py author          # authoring 10,000 agents x 300 frames, against plain Sdf
    python tools/bench.py author --agents 2000 --frames 300
    python tools/bench.py sim             # crowd simulation steps/s (and JuPedSim)
    python tools/bench.py preview         # OpenGL preview fps, 1,000 and 10,000 characters
    python tools/bench.py render          # Mitsuba s/frame and ground-truth overhead
    python tools/bench.py cameras         # camera agents + event detection steps/s: 1-100 cameras x 100, 10,000 characters (Fig. 16)
    python tools/bench.py moe             # learned camera behaviors: predictions/s in numpy (target 2,000)
    python tools/bench.py dataset         # usdcrowd dataset: 640x360 ground-truth frames/hour, 1 -> 2 Ray workers
    python tools/bench.py memory          # simulate's peak memory, 300 agents x 750 and 6,000 frames
    python tools/bench.py memory --long   # and 10,000 agents x 10,000 frames (about 30 min)
    python tools/bench.py realism         # corridors and bottlenecks against Weidmann and the Jülich flows, and JuPedSim

Each measured run happens in a child process so that its peak memory is its own.
Every section prints the machine's core count and load before and after it
(recorded with ``--record`` as ``machine_load``). The sections measured
against JuPedSim (sim, realism, and cameras, which time its 10,000-agent
step beside the 100-camera case to show the load) stop in one line when it is not installed
(``make bench`` installs it); ``--allow-missing-peers`` measures usdcrowd alone.
Targets (2-core machine): author 10,000 x 300 in <= 20 s and <= 4 GiB; 100
camera agents with 10,000 characters (event detection included) >= 30 steps/s;
simulate's peak memory at 6,000 frames within 10 % of 750, and 10,000 agents x
10,000 frames within 4 GiB.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tools")]      # the tests package (its helpers) and the tools

def load() -> str:
    """The machine's load averages over 1, 5 and 15 minutes ("n/a" where the system does not say)."""
    try:
        return "/".join(f"{x:.2f}" for x in os.getloadavg())
    except (AttributeError, OSError):
        return "n/a"


def _installed(module: str) -> bool:
    import importlib.util

    return importlib.util.find_spec(module) is not None


def bench_section(name: str, **kw):
    """Run tools/bench_<name>.py's run(), which prints its own table; returns what it measured."""
    import importlib

    try:
        module = importlib.import_module(f"bench_{name}")
    except ImportError as exc:
        print(f"== {name}: not available ({exc})")
        return None
    print(f"== {name}")
    return module.run(**kw)


def _min_max(values) -> dict:
    values = list(values)
    return {"min": min(values), "max": max(values)}


def figures_of(section: str, found) -> tuple[dict, dict | None, list | None]:
    """What a section measured, as docs/data keeps it: (figures with string keys and plain numbers,
    tables, images written into docs/)."""
    if section == "render":
        return render_figures(found)
    if section == "cameras":
        import bench_cameras

        image = bench_cameras.sweep_plot(found, ROOT / "docs" / "images" / "cameras_sweep.png")
        return (_section_figures(section, found), {"sweep": bench_cameras.sweep_table(found)},
                [os.path.relpath(image, ROOT)])
    if section == "realism":
        import bench_realism

        return found, None, [os.path.relpath(bench_realism.IMAGE, ROOT)]
    return _section_figures(section, found), None, None


def _section_figures(section: str, found) -> dict:
    if section == "sim":
        try:
            from importlib.metadata import version
            jps = version("jupedsim")
        except Exception:
            jps = None
        return {"usdcrowd": {str(r["agents"]): r["steps_per_s"] for r in found},
                "jupedsim": {str(r["agents"]): r["jupedsim_steps_per_s"] for r in found},
                "ratio": {str(r["agents"]): r["ratio"] for r in found}, "jupedsim_version": jps,
                "ratio_low": {str(r["agents"]): r["ratio_range"][0] for r in found if "ratio_range" in r},
                "ratio_high": {str(r["agents"]): r["ratio_range"][1] for r in found if "ratio_range" in r},
                "one_thread": {str(r["agents"]): r["one_thread_steps_per_s"] for r in found},
                "one_thread_ratio": {str(r["agents"]): r["one_thread_ratio"] for r in found},
                "threads": found[0]["threads"] if found else None,
                **{"over_a_run": r["over_a_run"] for r in found if "over_a_run" in r},
                **{"few_agents": r["few_agents"] for r in found if "few_agents" in r},
                **{"cold_start": r["cold_start"] for r in found if "cold_start" in r}}
    if section == "cameras":
        return {f"{r['cameras']}x{r['characters']}": r for r in found}
    if section == "preview":
        out: dict = {}
        for (template, n, _camera, label), fps in found.items():
            out.setdefault(f"{template}_{n}", {}).setdefault(label.replace(", ", "_").replace(" ", "_"), []).append(fps)
        figures = {scene: {label: _min_max(v) for label, v in labels.items()} for scene, labels in out.items()}
        from bench_preview import SMALL, crowd_ms, over_empty, size_label

        for template, n in {(template, n) for template, n, _, _ in found}:
            small = f"lod, {size_label(SMALL)}"
            cameras = {c for tp, m, c, label in found if (tp, m) == (template, n) and label == small}
            if cameras:
                figures[f"{template}_{n}"]["crowd_ms"] = {c.rsplit("/", 1)[-1]: crowd_ms(found, template, n, c)
                                                         for c in cameras}
            figures[f"{template}_{n}"]["over_empty"] = over_empty(found, template, n)
            # Each camera's frame (level of detail, shadows) over the same frame empty.
            figures[f"{template}_{n}"]["over_empty_by_camera"] = {
                camera.rsplit("/", 1)[-1]: found[(tp, m, camera, "empty")] / fps
                for (tp, m, camera, label), fps in found.items() if (tp, m) == (template, n) and label == "lod"}
        return figures
    return found


def _slug(text: str) -> str:
    import re

    return re.sub(r"[^a-z0-9]+", "_", text.lower()).strip("_")


def _sampler_table(ours: dict) -> dict:
    """Relative MSE and time per sample count (rows) and sampler (columns)."""
    names = ("independent", "multijitter", "multijitter + OIDN")
    counts = sorted({spp for name, spp in ours if name in names})
    rows = [[spp] + [f"{ours[(n, spp)][0][1]:.5f}, {ours[(n, spp)][1]:.2f} s" if (n, spp) in ours else ""
                     for n in names] for spp in counts]
    return {"columns": ["spp", *names], "rows": rows}


def _people_table(ours: dict) -> dict:
    """The rows with more samples on the people: spp + the people's, relative MSE, time."""
    import re

    found = []
    for (name, spp), ((_, err), sec) in ours.items():
        m = re.match(r"mj \+ (\d+) people \+ OIDN", name)
        if m:
            found.append((spp, int(m[1]), err, sec))
    rows = [[f"{spp} + {people}", f"{err:.5f}", f"{sec:.2f} s"] for spp, people, err, sec in sorted(found)]
    return {"columns": ["spp + people's spp, OIDN", "relative MSE", "time"], "rows": rows}


def render_figures(found: dict) -> tuple[dict, dict, list]:
    """bench_render's results as (figures, tables, images): per-frame times, the noise-against-time rows,
    Cycles' rows, the comparison in turns, and the two figures copied into docs/images."""
    import shutil

    import bench_render
    import numpy as np

    figures = {key: {**r, "gt_pct": 100 * r["ground_truth"] / r["beauty"]} for key, r in found.items()
               if key in ("llvm", "cuda")}
    q = found["quality"]
    ours = {f"{_slug(name)}_{spp}": {"error": err, "measured": measured, "seconds": sec}
            for (name, spp), ((measured, err), sec) in q["ours"].items()}
    figures["ours"] = ours
    tables = {"samplers": _sampler_table(q["ours"]), "people": _people_table(q["ours"])}
    if ("independent", 64) in q["ours"] and ("multijitter", 64) in q["ours"]:
        (_, ind), ind_s = q["ours"][("independent", 64)]
        (_, mj), mj_s = q["ours"][("multijitter", 64)]
        figures["multijitter_64"] = {"less_error": ind / mj, "more_time_pct": 100 * (mj_s / ind_s - 1)}
    images = []
    for src, name in ((q.get("people_figure"), "museum_people_samples.png"), (q.get("figure"), "museum_vs_cycles.png")):
        if src:
            shutil.copyfile(src, ROOT / "docs" / "images" / name)
            images.append(f"docs/images/{name}")
    if isinstance(q.get("cycles"), dict):
        figures["cycles"] = {_slug(label): {"error": err, "measured": measured, "seconds": sec}
                             for label, ((measured, err), sec) in q["cycles"].items()}
        tables["cycles"] = {"columns": ["Cycles CPU, 64 spp", "relative MSE", "time"],
                            "rows": [[label, f"{err:.5f}", f"{sec:.2f} s"]
                                     for label, ((_, err), sec) in q["cycles"].items()]}
        figures["cycles_common"] = {_slug(label): {"error": err, "measured": measured, "seconds": sec}
                                    for label, ((measured, err), sec) in q["cycles_common"].items()}
        figures["references"] = q["references"]
        figures["threads"] = bench_render.THREADS
        tables["cycles"]["rows"] = [[label, f"{err:.5f}", f"{q['cycles_common'][label][0][1]:.5f}", f"{sec:.2f} s"]
                                    for label, ((_, err), sec) in q["cycles"].items()]
        tables["cycles"]["columns"] = ["Cycles CPU, 64 spp", "relative MSE, own reference",
                                       "relative MSE, common reference", "time"]
        figures["in_turns"] = {}
        turns = []
        for label, it in q.get("in_turns", {}).items():
            ours_s, cycles_s = float(np.median(it["ours"])), float(np.median(it["cycles"]))
            mine, theirs = float(np.mean(it["ours_common_error"])), float(np.mean(it["cycles_common_error"]))
            setting = f"{it['key'][0]} at {it['key'][1]} spp"
            figures["in_turns"][_slug(label)] = {"ours_setting": setting, "ours_s": ours_s, "cycles_s": cycles_s,
                                                 "ours_error": mine, "cycles_error": theirs,
                                                 "ours_own_error": float(np.mean(it["ours_error"])),
                                                 "cycles_own_error": float(np.mean(it["cycles_error"])),
                                                 "speedup": cycles_s / ours_s}
            turns.append([label, f"{theirs:.6f} in {cycles_s:.2f} s", f"{setting}: {mine:.6f} in {ours_s:.2f} s",
                          f"**{cycles_s / ours_s:.2f}x**"])
        tables["in_turns"] = {"columns": ["Cycles frame", "Cycles (common reference)", "usdcrowd (common reference)",
                                          "faster"], "rows": turns}
    return figures, tables, images


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("section", nargs="?", default="all", choices=["all", "author", "sim", "cameras", "moe", "preview", "render",
                                                                 "dataset", "memory", "realism"])
    p.add_argument("--agents", type=int, default=10_000)
    p.add_argument("--frames", type=int, default=300)
    p.add_argument("--sizes", default="1000,10000,100000", help="agent counts of the sim section")
    p.add_argument("--long", action="store_true", help="memory: also 10,000 agents x 10,000 frames")
    p.add_argument("--allow-missing-peers", action="store_true",
                   help="sim and realism: measure usdcrowd alone when JuPedSim is not installed (default: an error)")
    p.add_argument("--record", action="store_true",
                   help="write what each section measured to docs/data/bench_<section>.json and fill the pages")
    args = p.parse_args(argv)
    print(f"machine: {os.cpu_count()} cores, load {load()}, python {sys.version.split()[0]}")
    peers = not args.allow_missing_peers or _installed("jupedsim")
    found, loads = {}, {}

    def measure(section, run, *a, **kw):
        before = load()
        found[section] = run(*a, **kw)
        loads[section] = {"cores": os.cpu_count(), "load_before": before, "load_after": load()}
        print(f"   ({section}: load {before} before, {loads[section]['load_after']} after, {os.cpu_count()} cores)")

    if args.section in ("all", "author"):
        measure("author", bench_section, "author", agents=args.agents, frames=args.frames)
    if args.section in ("all", "sim"):
        measure("sim", bench_section, "sim", sizes=tuple(int(s) for s in args.sizes.split(",")), jupedsim=peers,
                cold=True)
    for name in ("cameras", "moe", "preview", "render", "dataset", "realism"):
        if args.section in ("all", name):
            measure(name, bench_section, name, **({"jupedsim": peers} if name in ("realism", "cameras") else {}))
    if args.section in ("all", "memory"):
        measure("memory", bench_section, "memory", long=args.long)
    if args.record:
        from docfigures import record

        for section, result in found.items():
            if result:
                source = f"tools/bench_{section}.py"
                figures, tables, images = figures_of(section, result)
                figures = {**figures, "machine_load": loads[section]}
                record(f"bench_{section}", source, figures=figures, tables=tables, images=images,
                       command=f"python tools/bench.py {section}" + (" --long" if args.long and section == "memory" else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
