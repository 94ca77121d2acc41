"""The documentation's pictures and camera figures, made with the command line as a user would make them.

    python tools/make_doc_figures.py [demo] [harbour] [museum] [dataset] [cut]    # default: all five

- ``demo``: ``usdcrowd demo`` (the museum): the trajectory map, the preview
  sheet, the render contact sheet and the camera gallery.
- ``harbour``: ``usdcrowd demo --template harbour`` then ``usdcrowd metrics
  --counts 4,8`` on its shot: seed 000's comparison of autonomous and static
  cameras (the table, the activity and viewed plots, the gallery, the events).
- ``museum``: the README tour's museum (40 visitors, seed 7), ``metrics --counts 4``.
- ``dataset``: ``usdcrowd dataset docs/dataset_example.toml``, timed, its card,
  and its ground truth scored with TrackEval (against itself and the IoU baseline).
- ``cut``: the whole harbour simulated, then ``usdcrowd edit``: the director's
  shots, what the rules refused, and the sheet of the cut.

Each part writes its pictures into docs/images and its figures into
docs/data (tools/docfigures.py), with the date, commit and machine.
"""

from __future__ import annotations

import argparse
import csv
import json
import re
import shutil
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WORK = ROOT / "build" / "docs"
IMAGES = ROOT / "docs" / "images"
sys.path.insert(0, str(ROOT / "tools"))

from docfigures import record  # noqa: E402


def usdcrowd(*args: str) -> str:
    """Run one command as a user would; its standard output."""
    done = subprocess.run([sys.executable, "-m", "usdcrowd", *map(str, args)], capture_output=True, text=True,
                          cwd=ROOT)
    if done.returncode != 0:
        raise SystemExit(f"usdcrowd {' '.join(map(str, args))} failed:\n{done.stderr}")
    return done.stdout


def fresh(name: str) -> Path:
    folder = WORK / name
    shutil.rmtree(folder, ignore_errors=True)
    folder.parent.mkdir(parents=True, exist_ok=True)
    return folder


def copy_images(pairs) -> list[str]:
    """Copy (source, name in docs/images) pairs; the repository paths written."""
    written = []
    for src, name in pairs:
        shutil.copyfile(src, IMAGES / name)
        written.append(f"docs/images/{name}")
    return written


def events_of(shot: Path) -> dict:
    """How many events the shot holds, by kind (from ``usdcrowd inspect --json``)."""
    summary = json.loads(usdcrowd("inspect", shot, "--json"))
    kinds = Counter(e["kind"] for e in summary["events"])
    time = summary["time"]
    return {"events": sum(kinds.values()), **kinds, "agents": summary["agents"]["count"],
            "visible": summary["agents"]["visible"], "frames": int(time["end"] - time["start"] + 1)}


def metrics_table(folder: Path) -> tuple[dict, dict]:
    """summary.csv of ``usdcrowd metrics`` as figures and a table; tracking_N.csv pooled per N as
    figures ``tracking_N`` and a table of every camera agent."""
    with open(folder / "summary.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    figures = {f"{r['kind']}_{r['cameras']}": {k: float(v) for k, v in r.items() if k not in ("kind", "cameras")}
               for r in rows}
    table = {"columns": ["cameras", "active / (active + idle) score", "active / idle score", "active people viewed"],
             "rows": [[f"{r['cameras']} {r['kind']}", f"{float(r['mean_active_share']):.2f}",
                       f"{float(r['mean_active_idle_ratio']):.2f}", f"{100 * float(r['mean_viewed_share']):.0f} %"]
                      for r in rows]}
    tracking_rows = []
    for n in sorted({int(r["cameras"]) for r in rows}):
        with open(folder / f"tracking_{n}.csv", newline="") as fh:
            cams = list(csv.DictReader(fh))
        settled = [int(c["settled_frames"]) for c in cams]
        total = max(sum(settled), 1)
        figures[f"tracking_{n}"] = {
            "settled_frames": sum(settled),
            "framed": sum(float(c["framed"]) * k for c, k in zip(cams, settled) if k) / total,
            "blank": sum(float(c["blank"]) * k for c, k in zip(cams, settled) if k) / total,
            "worst_framed": min(float(c["framed"]) for c, k in zip(cams, settled) if k),
            "worst_blank": max(float(c["blank"]) for c, k in zip(cams, settled) if k),
            "walled": sum(float(c["walled"]) * k for c, k in zip(cams, settled) if k) / total,
            "worst_walled": max(float(c["walled"]) for c, k in zip(cams, settled) if k),
            "takes": sum(int(c["takes"]) for c in cams)}
        tracking_rows += [[f"{n} autonomous", c["camera"].rsplit("/", 1)[-1], c["settled_frames"],
                           f"{100 * float(c['framed']):.1f} %" if int(c["settled_frames"]) else "-",
                           f"{100 * float(c['blank']):.1f} %" if int(c["settled_frames"]) else "-",
                           f"{100 * float(c['walled']):.1f} %" if int(c["settled_frames"]) else "-",
                           f"{100 * float(c['median_size']):.0f} %" if c["median_size"] != "nan" else "-",
                           f"{float(c['median_seconds_to_frame']):.2f}" if c["median_seconds_to_frame"] != "nan"
                           else "-"] for c in cams]
    tracking = {"columns": ["cameras", "camera", "tracking frames 2 s after taking the event",
                            "half its people or more visible", "none visible", "only scenery or ground", "their height on screen (median)",
                            "seconds to frame it (median)"], "rows": tracking_rows}
    return figures, {"metrics": table, "tracking": tracking}


def demo() -> None:
    out = fresh("museum_demo")
    usdcrowd("demo", "-o", out, "--no-progress")
    images = copy_images([(out / "shot" / "trajectories.png", "museum_trajectories.png"),
                          (out / "preview" / "preview_sheet.png", "museum_preview_sheet.png"),
                          (out / "render" / "contact_sheet.png", "museum_render_sheet.png"),
                          (out / "preview" / "gallery.png", "museum_camera_gallery.png")])
    record("demo_images", "tools/make_doc_figures.py", figures={"shot": events_of(out / "shot" / "shot.usda")},
           images=images, command="python tools/make_doc_figures.py demo")


def harbour() -> None:
    out = fresh("harbour")
    usdcrowd("demo", "--template", "harbour", "-o", out, "--no-progress")
    shot = out / "shot" / "shot.usda"
    usdcrowd("metrics", shot, "-o", out / "metrics", "--counts", "4,8", "--no-progress")
    figures, tables = metrics_table(out / "metrics")
    images = copy_images([(out / "metrics" / "activity_4.png", "harbour_activity_4.png"),
                          (out / "metrics" / "viewed_4.png", "harbour_viewed_4.png"),
                          (out / "metrics" / "tracking_gallery.png", "harbour_tracking_gallery.png"),
                          (out / "preview" / "gallery.png", "harbour_camera_gallery.png")])
    record("harbour_cameras", "tools/make_doc_figures.py", figures={**figures, "shot": events_of(shot)},
           tables=tables, images=images, command="python tools/make_doc_figures.py harbour")


def museum() -> None:
    out = fresh("museum_tour")
    usdcrowd("new", "museum", "-o", out / "museum.usda", "--agents", "40", "--seed", "7")
    usdcrowd("simulate", out / "museum.usda", "-o", out / "shot", "--no-progress")
    usdcrowd("metrics", out / "shot" / "shot.usda", "-o", out / "metrics", "--counts", "4", "--no-progress")
    figures, tables = metrics_table(out / "metrics")
    record("museum_cameras", "tools/make_doc_figures.py",
           figures={**figures, "shot": events_of(out / "shot" / "shot.usda")}, tables=tables,
           command="python tools/make_doc_figures.py museum")


def dataset() -> None:
    out = fresh("dataset_example")
    t0 = time.perf_counter()
    said = usdcrowd("dataset", ROOT / "docs" / "dataset_example.toml", "-o", out, "--no-progress")
    seconds = time.perf_counter() - t0
    counts = re.search(r"(\d+) sequences, (\d+) videos, (\d+) frames", said)
    scores = subprocess.run([sys.executable, str(ROOT / "tools" / "eval_dataset.py"), str(out)], capture_output=True,
                            text=True, check=True, cwd=ROOT).stdout.splitlines()
    tracking = {}
    for line in scores[1:]:
        split, tracker, hota, mota, idf1 = line.split()
        tracking.setdefault(split, {})[tracker] = {"HOTA": float(hota), "MOTA": float(mota), "IDF1": float(idf1)}
    figures = {"seconds": seconds, "minutes": seconds / 60, "tracking": tracking,
               **dict(zip(("sequences", "videos", "frames"), map(int, counts.groups())))}
    images = copy_images([(out / "card.png", "dataset_card.png")])
    record("dataset_example", "tools/make_doc_figures.py", figures=figures, images=images,
           command="python tools/make_doc_figures.py dataset")


def cut() -> None:
    out = fresh("harbour_cut")
    out.mkdir(parents=True)
    shutil.copy(ROOT / "stages" / "harbour.usda", out / "harbour.usda")
    shutil.copytree(ROOT / "stages" / "maps", out / "maps")
    usdcrowd("simulate", out / "harbour.usda", "-o", out / "shot", "--no-progress")
    t0 = time.perf_counter()
    said = usdcrowd("edit", out / "shot" / "shot.usda", "-o", out / "cut", "--no-progress")
    seconds = time.perf_counter() - t0
    with open(out / "cut" / "onair.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    shots: dict[int, list] = {}
    for r in rows:
        shots.setdefault(int(r["shot"]), []).append(r)
    lengths = sorted(len(v) / 24.0 for v in shots.values())
    refused = dict((rule, int(n)) for n, rule in re.findall(r"(\d+) by the ([\w-]+ rule)", said))
    figures = {"shots": len(shots), "frames": len(rows), "seconds_edit": seconds,
               "cameras_used": len({r["camera"] for r in rows}),
               "cameras": int(re.search(r"of (\d+) cameras", said).group(1)),
               "shortest_s": lengths[0], "longest_s": lengths[-1],
               "on_event": sum(bool(r["event"]) for r in rows) / len(rows),
               "events_on_air": len({r["event"] for r in rows if r["event"]}),
               "refused_30": refused.get("30-degree rule", 0), "refused_180": refused.get("180-degree rule", 0),
               "shot": events_of(out / "shot" / "shot.usda")}
    table = {"columns": ["shot", "frames", "camera", "why it is on air"],
             "rows": [[str(k), f"{v[0]['time_code']}-{v[-1]['time_code']}", v[0]["camera"].rsplit("/", 1)[-1],
                       v[0]["reason"]] for k, v in sorted(shots.items())]}
    images = copy_images([(out / "cut" / "cut_sheet.png", "harbour_cut_sheet.png")])
    record("harbour_cut", "tools/make_doc_figures.py", figures=figures, tables={"shots": table}, images=images,
           command="python tools/make_doc_figures.py cut")


PARTS = {"demo": demo, "harbour": harbour, "museum": museum, "dataset": dataset, "cut": cut}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("parts", nargs="*", metavar="PART", help=f"any of {', '.join(PARTS)} (default: all)")
    args = p.parse_args(argv)
    unknown = set(args.parts) - set(PARTS)
    if unknown:
        p.error(f"unknown part(s) {', '.join(sorted(unknown))}")
    for name in args.parts or PARTS:
        t0 = time.perf_counter()
        PARTS[name]()
        print(f"{name}: {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
