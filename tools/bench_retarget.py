"""Retargeting as a user runs it: `usdcrowd frame --like` against the controller it imitates (seed 002, section 5).

    python tools/bench_retarget.py [--record]

On the dialogue example (two pairs talking and walking), for each of the
four behaviors and three shot sizes: a reference camera films C and D with
the controller, `frame --like` films A and B the way the reference does
(a blind start, as the command runs), and the controller with the
reference's parameters films A and B too. Per frame, with plain usd-core
reading the cameras and usdcrowd's reader the heads:

- roll: the angle of the camera's right axis out of the horizontal, degrees;
- distance ratio: the learned camera's distance to the pair's midpoint over
  the controller's;
- theta and phi errors: the differences of the two cameras' toric angles
  about A and B, degrees;
- screen error: how far both heads are from where the controller puts
  them on screen, NDC;
- for orbits, the turn: how far round the pair each camera goes over the
  shot, and whether the learned one goes the same way.

Each per-frame figure is :func:`usdcrowd.cameras.retarget.compare`, the
same that scores held-out clips in tools/train_camera_moe.py.

Prints medians and worst cases per behavior and size; ``--record`` writes
them to docs/data/bench_retarget.json (tools/docfigures.py) and draws the
gallery (reference, learned and controller frames per behavior, the GL
preview) to docs/images/retarget_gallery.png.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
BEHAVIORS = ("direct-track", "relative-track", "side-track", "orbit")
SIZES = ("close-up", "medium", "long")
FRAMES = 240
GALLERY = ROOT / "docs" / "images" / "retarget_gallery.png"


def _usdcrowd(*args) -> None:
    subprocess.run([sys.executable, "-m", "usdcrowd", *map(str, args)], check=True, capture_output=True, cwd=ROOT)


def _poses(shot: Path, camera: str) -> np.ndarray:
    """(FRAMES, 4, 4) local-to-world of a camera, read with plain usd-core."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(shot))
    stage.Reload()                                   # the file changed since an earlier open
    xform = UsdGeom.Xformable(stage.GetPrimAtPath(camera))
    return np.array([np.array(xform.ComputeLocalToWorldTransform(t)) for t in range(1, FRAMES + 1)])


def _heads(shot: Path) -> tuple[np.ndarray, np.ndarray]:
    """(FRAMES, 3) heads of A and B (usdcrowd's reader: the rig's head point); the stage must be Z up."""
    from pxr import UsdGeom

    from usdcrowd.cameras.features import head_and_facing
    from usdcrowd.scenario.shot_scene import ShotScene

    scene = ShotScene(shot)
    assert UsdGeom.GetStageUpAxis(scene.stage) == "Z"
    rows = [scene.agent_row("A"), scene.agent_row("B")]
    heads = np.array([head_and_facing(scene.agents(t, rows).joints_world)[0] for t in range(1, FRAMES + 1)])
    return heads[:, 0], heads[:, 1]


def measure(shot: Path, behavior: str, size: str) -> dict:
    """One behavior and size: reference on C-D, learned and controller on A-B; the per-shot figures."""
    from usdcrowd.cameras.retarget import compare
    from usdcrowd.jobs.toric_filming import APERTURE, FOCAL_LENGTH

    key = f"{behavior}_{size}".replace("-", "_")
    ref, learned, ctl = f"Ref_{key}", f"Learned_{key}", f"Ctl_{key}"
    _usdcrowd("frame", shot, "--behavior", behavior, "--targets", "C", "D", "--shot", size, "--name", ref,
              "--no-progress")
    _usdcrowd("frame", shot, "--like", shot, "--camera", f"/World/Cameras/{ref}", "--targets", "A", "B",
              "--name", learned, "--no-progress")
    _usdcrowd("frame", shot, "--behavior", behavior, "--targets", "A", "B", "--shot", size, "--name", ctl,
              "--no-progress")
    m, c = _poses(shot, f"/World/Cameras/{learned}"), _poses(shot, f"/World/Cameras/{ctl}")
    heads_a, heads_b = _heads(shot)
    d = compare(m, c, heads_a, heads_b, 2.0 * np.arctan(0.5 * APERTURE / FOCAL_LENGTH), 16 / 9)
    ratio = d["distance_ratio"]
    out = {"roll_median": float(np.median(d["roll_deg"])), "roll_max": float(d["roll_deg"].max()),
           "distance_ratio_median": float(np.median(ratio)), "distance_ratio_mean": float(ratio.mean()),
           "distance_ratio_max": float(ratio.max()), "distance_ratio_min": float(ratio.min()),
           "theta_error_median": float(np.median(d["theta_deg"])), "theta_error_mean": float(d["theta_deg"].mean()),
           "theta_error_max": float(d["theta_deg"].max()), "phi_error_median": float(np.median(d["phi_deg"])),
           "screen_error_median": float(np.median(d["screen"])), "screen_error_max": float(d["screen"].max())}
    if behavior == "orbit":
        mine, theirs = d["turn_deg"], d["truth_turn_deg"]
        out.update({"turn_deg": mine, "controller_turn_deg": theirs, "same_way": bool(np.sign(mine) == np.sign(theirs)),
                    "turn_ratio": abs(mine) / max(abs(theirs), 1e-9)})
    return out


def gallery(shot: Path, path: Path, size: str = "medium", frames=(80, 200)) -> None:
    """A contact sheet: per behavior, the reference camera on C and D, then the learned camera and the
    controller on A and B, at two frames (the GL preview)."""
    from PIL import Image, ImageDraw

    w, h = 384, 216
    names = ("reference (C, D)", "learned (A, B)", "controller (A, B)")
    label_w, head_h = 120, 22
    sheet = Image.new("RGB", (label_w + 3 * len(frames) * w, head_h + len(BEHAVIORS) * h), "white")
    draw = ImageDraw.Draw(sheet)
    for k, name in enumerate(names):
        draw.text((label_w + k * len(frames) * w + 6, 4), f"{name}, frames {frames[0]} and {frames[1]}", fill="black")
    with tempfile.TemporaryDirectory() as tmp:
        for r, behavior in enumerate(BEHAVIORS):
            key = f"{behavior}_{size}".replace("-", "_")
            draw.text((6, head_h + r * h + h // 2), behavior, fill="black")
            for k, cam in enumerate((f"Ref_{key}", f"Learned_{key}", f"Ctl_{key}")):
                out = Path(tmp) / cam
                _usdcrowd("preview", shot, "--camera", f"/World/Cameras/{cam}", "--frames",
                          f"{frames[0]}:{frames[1]}x{frames[1] - frames[0]}", "--resolution", f"{w}x{h}",
                          "-o", f"{out}/", "--no-progress")
                pngs = sorted(p for p in out.glob("*.png") if p.name != "contact_sheet.png")
                assert len(pngs) == len(frames), pngs
                for f, png in enumerate(pngs):
                    sheet.paste(Image.open(png).convert("RGB").resize((w, h)),
                                (label_w + (k * len(frames) + f) * w, head_h + r * h))
    sheet.save(path)


def run(gallery_png: Path | None = None) -> dict:
    from usdcrowd.core.resources import data_dir

    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        shutil.copy(data_dir("stages") / "dialogue.usda", tmp / "dialogue.usda")
        _usdcrowd("simulate", tmp / "dialogue.usda", "-o", tmp / "shot", "--frames", f"1:{FRAMES}", "--no-progress")
        shot = tmp / "shot" / "shot.usda"
        print(f"{'behavior':<15} {'shot':<9} {'roll med/max':>13} {'distance x med/max':>19} {'theta err med/max':>18}")
        for behavior in BEHAVIORS:
            for size in SIZES:
                r = measure(shot, behavior, size)
                results.setdefault(behavior.replace("-", "_"), {})[size.replace("-", "_")] = r
                turn = (f"  turn {r['turn_deg']:+.0f} vs {r['controller_turn_deg']:+.0f} deg"
                        if behavior == "orbit" else "")
                print(f"{behavior:<15} {size:<9} {r['roll_median']:6.1f}/{r['roll_max']:<6.1f} "
                      f"{r['distance_ratio_median']:9.2f}/{r['distance_ratio_max']:<9.2f} "
                      f"{r['theta_error_median']:8.1f}/{r['theta_error_max']:<8.1f}{turn}", flush=True)
        if gallery_png is not None:
            gallery(shot, gallery_png)
            print(f"gallery: {gallery_png}")
    return results


def table(results: dict) -> dict:
    """The guide's table: per behavior and size, distance ratio, theta and screen errors, roll, orbits' turn."""
    rows = []
    for behavior in BEHAVIORS:
        for size in SIZES:
            r = results[behavior.replace("-", "_")][size.replace("-", "_")]
            turn = (f"{r['turn_deg']:+.0f} vs {r['controller_turn_deg']:+.0f}" if "turn_deg" in r else "")
            rows.append([behavior.replace("-", " "), size, f"{r['distance_ratio_median']:.2f} / "
                         f"{r['distance_ratio_min']:.2f}-{r['distance_ratio_max']:.2f}",
                         f"{r['theta_error_median']:.1f}", f"{r['screen_error_median']:.3f}",
                         f"{r['roll_max']:.1f}", turn])
    return {"columns": ["behavior", "shot", "distance ratio, median / range", "theta error, median (deg)",
                        "screen error, median (NDC)", "roll, worst (deg)", "orbit: learned vs controller turn (deg)"],
            "rows": rows}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--record", action="store_true", help="write the figures to docs/data/bench_retarget.json")
    p.add_argument("--gallery", type=Path, help="write the gallery of reference, learned and controller frames here "
                   f"(with --record: {GALLERY.relative_to(ROOT)})")
    args = p.parse_args(argv)
    results = run(GALLERY if args.record else args.gallery)
    if args.record:
        sys.path.insert(0, str(ROOT / "tools"))
        from docfigures import record

        record("bench_retarget", "tools/bench_retarget.py", figures=results, tables={"summary": table(results)},
               images=[str(GALLERY.relative_to(ROOT))])
    return 0


if __name__ == "__main__":
    sys.exit(main())
