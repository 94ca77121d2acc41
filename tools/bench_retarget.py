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
- theta error: the difference of the two cameras' toric theta, degrees;
- for orbits, the turn: how far round the pair each camera goes over the
  shot, and whether the learned one goes the same way.

Prints medians and worst cases per behavior and size; ``--record`` writes
them to docs/data/bench_retarget.json (tools/docfigures.py).
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


def _usdcrowd(*args) -> None:
    subprocess.run([sys.executable, "-m", "usdcrowd", *map(str, args)], check=True, capture_output=True, cwd=ROOT)


def _poses(shot: Path, camera: str) -> np.ndarray:
    """(FRAMES, 4, 4) local-to-world of a camera, read with plain usd-core."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(shot))
    stage.Reload()                                   # the file changed since an earlier open
    xform = UsdGeom.Xformable(stage.GetPrimAtPath(camera))
    return np.array([np.array(xform.ComputeLocalToWorldTransform(t)) for t in range(1, FRAMES + 1)])


def _toric_theta(shot: Path, camera: str) -> np.ndarray:
    from pxr import Usd

    stage = Usd.Stage.Open(str(shot))
    attr = stage.GetPrimAtPath(camera).GetAttribute("crowd:toric:theta")
    return np.array([attr.Get(t) for t in range(1, FRAMES + 1)], dtype=np.float64)


def _heads_midpoint(shot: Path) -> tuple[np.ndarray, np.ndarray]:
    """(FRAMES, 3) midpoint of A's and B's heads and the stage's up axis, (3,) float."""
    from pxr import UsdGeom

    from usdcrowd.scenario.shot_scene import ShotScene

    scene = ShotScene(shot)
    rows = [scene.agent_row("A"), scene.agent_row("B")]
    mid = np.array([scene.agents(t, rows).keypoints()[:, 3].mean(0) for t in range(1, FRAMES + 1)])
    up = np.eye(3)[{"Y": 1, "Z": 2}[UsdGeom.GetStageUpAxis(scene.stage)]]
    return mid, up


def _turn(poses: np.ndarray, mid: np.ndarray, up: np.ndarray) -> float:
    """Signed degrees the camera goes round the pair's midpoint, about the up axis, over the shot."""
    rel = poses[:, 3, :3] - mid
    rel -= np.outer(rel @ up, up)
    side = np.cross(up, rel[0]) / max(np.linalg.norm(rel[0]), 1e-9)
    ang = np.unwrap(np.arctan2(rel @ side, rel @ rel[0] / max(np.linalg.norm(rel[0]), 1e-9)))
    return float(np.degrees(ang[-1] - ang[0]))


def measure(shot: Path, behavior: str, size: str) -> dict:
    """One behavior and size: reference on C-D, learned and controller on A-B; the per-shot figures."""
    key = f"{behavior}_{size}".replace("-", "_")
    ref, learned, ctl = f"Ref_{key}", f"Learned_{key}", f"Ctl_{key}"
    _usdcrowd("frame", shot, "--behavior", behavior, "--targets", "C", "D", "--shot", size, "--name", ref,
              "--no-progress")
    _usdcrowd("frame", shot, "--like", shot, "--camera", f"/World/Cameras/{ref}", "--targets", "A", "B",
              "--name", learned, "--no-progress")
    _usdcrowd("frame", shot, "--behavior", behavior, "--targets", "A", "B", "--shot", size, "--name", ctl,
              "--no-progress")
    m, c = _poses(shot, f"/World/Cameras/{learned}"), _poses(shot, f"/World/Cameras/{ctl}")
    mid, up = _heads_midpoint(shot)
    right = m[:, 0, :3]
    roll = np.degrees(np.arcsin(np.abs(right @ up) / np.linalg.norm(right, axis=1)))
    ratio = np.linalg.norm(m[:, 3, :3] - mid, axis=1) / np.linalg.norm(c[:, 3, :3] - mid, axis=1)
    theta = np.abs(_toric_theta(shot, f"/World/Cameras/{learned}") - _toric_theta(shot, f"/World/Cameras/{ctl}"))
    out = {"roll_median": float(np.median(roll)), "roll_max": float(roll.max()),
           "distance_ratio_median": float(np.median(ratio)), "distance_ratio_max": float(ratio.max()),
           "theta_error_median": float(np.nanmedian(theta)), "theta_error_max": float(np.nanmax(theta))}
    if behavior == "orbit":
        mine, theirs = _turn(m, mid, up), _turn(c, mid, up)
        out.update({"turn_deg": mine, "controller_turn_deg": theirs, "same_way": bool(np.sign(mine) == np.sign(theirs)),
                    "turn_ratio": abs(mine) / max(abs(theirs), 1e-9)})
    return out


def run() -> dict:
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
    return results


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--record", action="store_true", help="write the figures to docs/data/bench_retarget.json")
    args = p.parse_args(argv)
    results = run()
    if args.record:
        sys.path.insert(0, str(ROOT / "tools"))
        from docfigures import record

        record("bench_retarget", "tools/bench_retarget.py", figures=results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
