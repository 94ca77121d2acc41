"""Where the pose detector puts its joints on usdcrowd's characters: the estimator's body, measured.

    python tools/calibrate_pose_joints.py [--out build/pose_joints]

The cinematic feature estimator (usdcrowd.cameras.estimator) is trained on
the joints of its BODY projected by the controllers' cameras; on a clip it
reads what the detector (MediaPipe's BlazePose, the ``video`` extra) finds.
Where the two disagree, the estimator is fed a body it never learned. This
tool measures the detector's joints on rendered usdcrowd characters:

1. on the dialogue example, toric cameras (orbits in three shot sizes, which
   go all round the pair, and a relative track) film C and D, drawn by the
   GL preview every 4th frame;
2. the detector runs on each frame (in the video venv: $USDCROWD_VIDEO_VENV,
   or one made in the temporary folder with usdcrowd[video]); each person
   found goes to the character whose projected head is nearest;
3. for each joint, the point in the character's own frame (x forward, y to
   its left, z up, scaled to the canonical body) that best explains every
   detection facing the camera within 70 degrees is solved by linear least
   squares (each detection: two linear equations in the point, as in DLT).

It prints the body, in metres, beside the estimator's BODY and the
residual on screen, and how often the detector swaps a person's left and
right; BODY takes its values from here (the cameras that
test the estimator film A and B, not C and D).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tools"))

CAMERAS = [("orbit", "close-up"), ("orbit", "medium"), ("orbit", "long"), ("relative-track", "medium"),
           ("direct-track", "long")]
FRAMES, STRIDE, SIZE = 240, 4, (960, 540)
FACING = np.radians(70.0)


def video_python() -> str:
    """The venv with usdcrowd[video] ($USDCROWD_VIDEO_VENV, else made once in the temporary folder)."""
    from tool_venvs import tool_venv

    return tool_venv("video", "USDCROWD_VIDEO_VENV", ["-e", f"{ROOT}[video]"])


def _usdcrowd(*args) -> None:
    subprocess.run([sys.executable, "-m", "usdcrowd", *map(str, args)], check=True, capture_output=True)


def render(work: Path) -> tuple[Path, list[str]]:
    """The dialogue shot with the calibration's cameras on C and D, drawn every STRIDE-th frame."""
    from usdcrowd.core.resources import data_dir

    (work / "dialogue.usda").write_bytes((data_dir("stages") / "dialogue.usda").read_bytes())
    _usdcrowd("simulate", work / "dialogue.usda", "-o", work / "shot", "--frames", f"1:{FRAMES}", "--no-progress")
    shot = work / "shot" / "shot.usda"
    names = []
    for behavior, size in CAMERAS:
        name = f"Cal_{behavior}_{size}".replace("-", "_")
        _usdcrowd("frame", shot, "--behavior", behavior, "--targets", "C", "D", "--shot", size, "--name", name,
                  "--no-progress")
        _usdcrowd("preview", shot, "--camera", f"/World/Cameras/{name}", "--frames", f"1:{FRAMES}x{STRIDE}",
                  "--resolution", f"{SIZE[0]}x{SIZE[1]}", "-o", f"{work / name}/", "--no-progress")
        names.append(name)
    return shot, names


def detect_worker(folder: str, out: str) -> None:
    """In the video venv: every person found in each frame of a folder, (7, 2) pixels each."""
    from PIL import Image

    from usdcrowd.cameras.clip_poses import detect

    files = sorted(p for p in Path(folder).glob("frame.*.png"))
    people = detect([np.asarray(Image.open(f).convert("RGB")) for f in files])
    np.savez(out, frames=np.array([int(f.name.split(".")[1]) for f in files]),
             people=json.dumps([[p.tolist() for p in ps] for ps in people]))


def observations(shot: Path, name: str, found: dict):
    """Rows of (camera (4, 4), ground (3,), yaw, scale, joints (8, 2) NDC) for detections facing the camera."""
    from usdcrowd.cameras.clip_poses import to_ndc
    from usdcrowd.cameras.estimator import HEAD, body_points, project
    from usdcrowd.cameras.features import head_and_facing
    from usdcrowd.cameras.moe_data import ASPECT, FOV_X
    from usdcrowd.scenario.shot_scene import ShotScene

    scene = ShotScene(shot)
    rows_cd = [scene.agent_row("C"), scene.agent_row("D")]
    out = []
    for frame, people in zip(found["frames"], json.loads(str(found["people"]))):
        cam = scene.camera(f"/World/Cameras/{name}", float(frame)).cam_to_world
        heads, yaws = head_and_facing(scene.agents(float(frame), rows_cd).joints_world)
        truth = [project(cam[None], body_points(heads[c:c + 1], yaws[c:c + 1]), FOV_X, ASPECT)[0, 0] for c in (0, 1)]
        for p in people:
            ndc = to_ndc(np.array(p), SIZE[0], SIZE[1], 50.0, FOV_X, ASPECT)
            c = int(np.argmin([np.linalg.norm(ndc[0] - t) for t in truth]))
            if np.linalg.norm(ndc[0] - truth[c]) > 0.1:
                continue                                   # someone else, or a stray detection
            to_cam = cam[3, :2] - heads[c, :2]
            facing = np.array([np.cos(yaws[c]), np.sin(yaws[c])])
            if np.arccos(np.clip(facing @ to_cam / np.linalg.norm(to_cam), -1, 1)) > FACING:
                continue
            out.append((cam, np.array([*heads[c, :2], 0.0]), yaws[c], heads[c, 2] / HEAD, ndc))
    return out


def swapped_share(obs) -> float:
    """Share of the detections (facing the camera) whose shoulders are nearer the other side's: the
    detector's left and right swapped (BODY's shoulders projected as the truth)."""
    from usdcrowd.cameras.estimator import HEAD, body_points, project
    from usdcrowd.cameras.moe_data import ASPECT, FOV_X

    swaps = 0
    for cam, ground, yaw, scale, ndc in obs:
        truth = project(cam[None], body_points(np.array([[*ground[:2], scale * HEAD]]), np.array([yaw])),
                        FOV_X, ASPECT)[0]                  # (8, 2)
        kept = np.linalg.norm(ndc[2] - truth[2]) + np.linalg.norm(ndc[3] - truth[3])
        swaps += np.linalg.norm(ndc[2] - truth[3]) + np.linalg.norm(ndc[3] - truth[2]) < kept
    return swaps / max(len(obs), 1)


def solve(obs) -> tuple[np.ndarray, np.ndarray]:
    """(8, 3) body-frame joints (canonical scale) by linear least squares, and (8,) RMS residual (NDC)."""
    from usdcrowd.cameras.estimator import JOINTS
    from usdcrowd.cameras.moe_data import ASPECT, FOV_X

    t = np.tan(0.5 * FOV_X)
    body, resid = np.zeros((len(JOINTS), 3)), np.zeros(len(JOINTS))
    for j in range(len(JOINTS)):
        rows, rhs = [], []
        for cam, ground, yaw, scale, ndc in obs:
            axes = cam[:3, :3]                             # rows: the camera's x, y, z in the world
            rot = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
            a, b = axes @ (ground - cam[3, :3]), scale * axes @ rot    # camera coordinates: a + b @ p
            x, y = ndc[j]
            for k, v, f in ((0, x, 1.0), (1, y, ASPECT)):
                # v * (-c2) * t = f * c_k, linear in p
                rows.append(-v * t * b[2] - f * b[k])
                rhs.append(f * a[k] + v * t * a[2])
        A, r = np.array(rows), np.array(rhs)
        body[j] = np.linalg.lstsq(A, r, rcond=None)[0]
        resid[j] = np.sqrt(np.mean((A @ body[j] - r) ** 2))
    return body, resid


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=ROOT / "build" / "pose_joints")
    p.add_argument("--detect-worker", nargs=2, metavar=("FOLDER", "OUT"), help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if a.detect_worker:
        detect_worker(*a.detect_worker)
        return 0
    from usdcrowd.cameras.estimator import BODY, JOINTS

    a.out.mkdir(parents=True, exist_ok=True)
    python = video_python()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        shot, names = render(tmp)
        obs = []
        for name in names:
            subprocess.run([python, __file__, "--detect-worker", str(tmp / name), str(tmp / f"{name}.npz")], check=True)
            obs += observations(shot, name, np.load(tmp / f"{name}.npz"))
            print(f"{name}: {len(obs)} detections so far", flush=True)
        body, resid = solve(obs)
        swapped = swapped_share(obs)
    print(f"{'joint':<11} {'measured x, y, z (m)':>24}   {'BODY':>22}   rms (NDC, the unit's share of the scale)")
    for j, name in enumerate(JOINTS):
        print(f"{name:<11} {body[j, 0]:7.3f} {body[j, 1]:7.3f} {body[j, 2]:7.3f}   "
              f"{BODY[j, 0]:6.3f} {BODY[j, 1]:6.3f} {BODY[j, 2]:6.3f}   {resid[j]:.4f}")
    print(f"left and right swapped in {100 * swapped:.0f} % of the {len(obs)} detections facing the camera")
    (a.out / "body.json").write_text(json.dumps({"joints": JOINTS, "body": body.round(4).tolist(),
                                                 "rms": resid.round(5).tolist(), "detections": len(obs),
                                                 "swapped": round(swapped, 4)}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
