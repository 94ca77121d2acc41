"""How fast a replayed walker's feet move while they bear weight: the figure behind "the feet slide".

    python tools/measure_feet.py [--speed 1.34] [--record]

Replays one person walking a straight line at ``--speed`` m/s (a file in the ETH/UCY layout, read by
``usdcrowd replay`` as a user's would be), poses the shot's skeleton at every frame as the preview and
the ground truth do (:class:`usdcrowd.scenario.shot_scene.ShotScene`), and follows the corners of each
sole (the body's shoe vertices on the ground, carried by the legs joint). A foot bears weight on the
frames its lowest corner is within :data:`STANCE_BAND` of the lowest it ever gets; its speed there is
that corner's ground speed from one frame to the next. A planted foot moves at 0; the field's bar for
"feet do not slide" is under 0.1 m/s.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

STANCE_BAND = 0.01  # m above a sole's lowest: the foot is on the ground
FPS = 25.0
SECONDS = 8.0


def soles(body) -> tuple[np.ndarray, np.ndarray]:
    """(k, 3) bind-pose points of the left (+Y) and the right (-Y) sole: shoe vertices at the ground."""
    from usdcrowd.character.body import REGIONS

    shoe = body.regions == REGIONS.index("shoes")
    low = shoe & (body.points[:, 2] <= body.points[shoe, 2].min() + 1e-4)
    p = body.points[low].astype(np.float64)
    return p[p[:, 1] > 0], p[p[:, 1] < 0]


def stance_speeds(corners: np.ndarray, fps: float, band: float = STANCE_BAND) -> np.ndarray:
    """Ground speeds (m/s) of a foot over the frames it bears weight.

    Parameters
    ----------
    corners : (t, k, 3) float
        World positions of one sole's corners, frame by frame (Z up).
    fps : float
    band : float
        Metres above the sole's lowest point over all frames that still count as on the ground.

    Returns
    -------
    (s,) float
        For each frame (but the last) whose lowest corner is within ``band`` of the lowest ever, that
        corner's horizontal speed to the next frame.
    """
    corners = np.asarray(corners, dtype=np.float64)
    low = corners[..., 2].argmin(axis=1)
    rows = np.arange(len(corners) - 1)
    z = corners[rows, low[:-1], 2]
    step = corners[rows + 1, low[:-1], :2] - corners[rows, low[:-1], :2]
    speed = np.linalg.norm(step, axis=1) * fps
    return speed[z <= corners[..., 2].min() + band]


def walker_file(path: Path, speed: float, seconds: float = SECONDS, fps: float = FPS) -> Path:
    """An ETH/UCY-layout file (frame id x y) of one person walking +X at ``speed``."""
    frames = np.arange(int(round(seconds * fps)) + 1)
    path.write_text("".join(f"{k} 1 {k / fps * speed:.6f} 0.0\n" for k in frames))
    return path


def measure(speed: float = 1.34, workdir: Path | None = None) -> dict:
    """Replay a walker at ``speed`` and measure each foot's speed while it bears weight (figures)."""
    from usdcrowd.character.body import build_body
    from usdcrowd.cli import main
    from usdcrowd.scenario.shot_scene import ShotScene

    with tempfile.TemporaryDirectory() as tmp:
        work = Path(workdir or tmp)
        walk = walker_file(work / "walk.txt", speed)
        shot = work / "shot"
        assert main(["replay", str(walk), "-o", str(shot), "--fps", f"{FPS:g}", "--cameras", "0", "--no-events",
                     "--no-progress"]) == 0
        scene = ShotScene(shot / "shot.usda")
        left, right = soles(build_body())
        feet = {"left": [], "right": []}
        hips = []
        for t in scene.time_codes:
            posed = scene.agents(t)
            m = posed.skinning[0, 0]                      # the legs joint: bind pose to world
            feet["left"].append(left @ m[:3, :3] + m[3, :3])
            feet["right"].append(right @ m[:3, :3] + m[3, :3])
            hips.append(posed.joints_world[0, 0, 3, :2])
    walked = np.median(np.linalg.norm(np.diff(np.array(hips), axis=0), axis=1)) * FPS
    out = {"speed": speed, "hips_speed": float(walked), "stance_band": STANCE_BAND, "fps": FPS}
    for side, corners in feet.items():
        s = stance_speeds(np.array(corners), FPS)
        out[side] = {"stance_median": float(np.median(s)), "stance_max": float(s.max()), "stance_frames": int(len(s)),
                     "frames": len(corners)}
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--speed", type=float, default=1.34, help="walking speed of the replayed person, m/s")
    p.add_argument("--record", action="store_true", help="write docs/data/feet.json and fill the pages")
    a = p.parse_args(argv)
    figures = measure(a.speed)
    print(f"a walker replayed at {figures['speed']:g} m/s (hips at {figures['hips_speed']:.2f} m/s):")
    for side in ("left", "right"):
        f = figures[side]
        print(f"  {side} foot, on {f['stance_frames']} of {f['frames']} frames within {STANCE_BAND * 100:g} cm of "
              f"its lowest: {f['stance_median']:.2f} m/s (median), {f['stance_max']:.2f} at most (planted: 0; "
              f"the field's bar 0.1)")
    if a.record:
        sys.path.insert(0, str(ROOT / "tools"))
        from docfigures import record

        record("feet", "tools/measure_feet.py", figures=figures)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
