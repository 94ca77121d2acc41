"""A film clip as the reference (seed 002, section 4), measured where the truth is known.

    python tools/bench_clip_reference.py [--record]

On the dialogue example, for each of the four behaviors in each shot size, the
controller films A and B and the GL preview draws that camera to an MP4
(960 x 540): a clip whose true features are the stage's. The clip is read
as `usdcrowd frame --like clip.mp4` reads it (in the video venv:
$USDCROWD_VIDEO_VENV, or one made in the temporary folder with
usdcrowd[video]), and compared with the stage:

- per component, the median error over the clip's frames: the heads'
  screen positions (NDC), theta and phi (degrees), the span and dAB (a
  multiple of the truth, either way), sA, sB and sAB (degrees);
- the gating network's expert weights from the clip against those from
  the stage (L1 distance; the pair's motion, which no picture shows, set
  to unknown in both), and against the stage's other behaviors;
- what a user gets: each reading's style rolled out on C and D as `frame
  --like` does (usdcrowd.cameras.retarget.retarget_poses), the clip's camera
  against the stage's (distance ratio, theta error, and for the orbit the
  turn of each).

Prints a table; ``--record`` writes it to docs/data/clip_reference.json
(tools/docfigures.py) and draws the detections over a frame of each clip
to docs/images/clip_reference_gallery.png.
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

BEHAVIORS = ("direct-track", "relative-track", "side-track", "orbit")
SIZES = ("close-up", "medium", "long")
CASES = [(b, size) for size in SIZES for b in BEHAVIORS]


def _key(behavior: str, size: str) -> str:
    return f"{behavior}_{size}".replace("-", "_")
FRAMES, SIZE = 240, (960, 540)
GALLERY = ROOT / "docs" / "images" / "clip_reference_gallery.png"
GALLERY_FRAME = 120


def _usdcrowd(*args) -> None:
    subprocess.run([sys.executable, "-m", "usdcrowd", *map(str, args)], check=True, capture_output=True)


def worker(out: str, clips: list[str]) -> None:
    """In the video venv: each clip's features as `frame --like` reads them, and its filled joints."""
    from usdcrowd.cameras import clip_poses
    from usdcrowd.cameras.moe_data import ASPECT, FOV_X
    from usdcrowd.jobs.toric_filming import read_clip_reference

    from usdcrowd.core.errors import UsdcrowdError

    result = {}
    for path in clips:
        try:
            ref = read_clip_reference(path)
        except UsdcrowdError as exc:              # refused, as `frame --like` refuses it: part of the result
            result[path] = {"refused": str(exc).split(": ", 1)[-1]}
            continue
        frames, _ = clip_poses.read_frames(path)
        people = clip_poses.detect([frames[GALLERY_FRAME]])[0]
        result[path] = {"character": ref.character.tolist(), "camera": ref.camera_features.tolist(),
                        "size": ref.shot_size,
                        "gallery": [clip_poses.to_ndc(p, SIZE[0], SIZE[1], 50.0, FOV_X, ASPECT).tolist()
                                    for p in people]}
    Path(out).write_text(json.dumps(result))


def compare_features(est_char, est_cam, truth) -> dict:
    """Median errors per component of a clip's features against the stage's (the reference's truth): the
    heads on screen (NDC), and tools/train_feature_estimator.py's components (ratios either way)."""
    from train_feature_estimator import component_errors

    n = min(len(est_cam), len(truth.camera_features))
    errors = component_errors(est_char[:n], est_cam[:n], truth.character[:n], truth.camera_features[:n])
    out = {"screen": float(np.median(np.linalg.norm(est_cam[:n, :4] - truth.camera_features[:n, :4], axis=1)))}
    for k, v in errors.items():
        out[k] = float(np.exp(np.median(np.abs(np.log(v)))) if k.endswith("ratio") else np.median(v))
    return out


def truth_of(shot: Path, name: str, clip_camera: np.ndarray):
    """The stage's reading of the camera a clip was drawn from, its A the one the clip calls A: the
    character whose head is where the clip's A's is (over the first second)."""
    from usdcrowd.jobs.toric_filming import read_reference

    ref = read_reference(shot, f"/World/Cameras/{name}")
    n = min(24, len(clip_camera), len(ref.camera_features))
    kept = np.linalg.norm(clip_camera[:n, 0:2] - ref.camera_features[:n, 0:2], axis=1).mean()
    swapped = np.linalg.norm(clip_camera[:n, 0:2] - ref.camera_features[:n, 2:4], axis=1).mean()
    return read_reference(shot, f"/World/Cameras/{name}", ("B", "A")) if swapped < kept else ref


def run(gallery_png: Path | None = None) -> dict:
    from calibrate_pose_joints import video_python
    from usdcrowd.cameras.features import head_and_facing
    from usdcrowd.cameras.moe import CLIP_WEIGHTS, PAIR_MOTION, CameraMoE, character_features
    from usdcrowd.cameras.moe_data import ASPECT, FOV_X
    from usdcrowd.cameras.retarget import compare, retarget_poses
    from usdcrowd.core.resources import data_dir
    from usdcrowd.scenario.shot_scene import ShotScene

    model = CameraMoE(CLIP_WEIGHTS)      # the model `frame --like` reads a clip with, for clip and stage alike
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / "dialogue.usda").write_bytes((data_dir("stages") / "dialogue.usda").read_bytes())
        _usdcrowd("simulate", tmp / "dialogue.usda", "-o", tmp / "shot", "--frames", f"1:{FRAMES}", "--no-progress")
        shot = tmp / "shot" / "shot.usda"
        clips = {}
        for behavior, size in CASES:
            name = f"Ref_{_key(behavior, size)}"
            _usdcrowd("frame", shot, "--behavior", behavior, "--targets", "A", "B", "--shot", size, "--name", name,
                      "--no-progress")
            _usdcrowd("preview", shot, "--camera", f"/World/Cameras/{name}", "--resolution", f"{SIZE[0]}x{SIZE[1]}",
                      "-o", tmp / f"{name}.mp4", "--no-progress")
            clips[behavior, size] = tmp / f"{name}.mp4"
        subprocess.run([video_python(), __file__, "--worker", str(tmp / "clips.json"), *map(str, clips.values())],
                       check=True)
        read = json.loads((tmp / "clips.json").read_text())
        scene = ShotScene(shot)
        rows = [scene.agent_row("C"), scene.agent_row("D")]
        heads, yaws = zip(*(head_and_facing(scene.agents(t, rows).joints_world) for t in range(1, FRAMES + 1)))
        heads, yaws = np.array(heads), np.array(yaws)
        char_cd = character_features(heads[:, 0], heads[:, 1], yaws[:, 0], yaws[:, 1], scene.fps)
        truths, gates = {}, {}
        for case in CASES:
            est = read[str(clips[case])]
            if "refused" in est:
                continue
            truths[case] = truth_of(shot, f"Ref_{_key(*case)}", np.array(est["camera"]))
            unknown = truths[case].character.copy()
            unknown[:, PAIR_MOTION] = model.w["char_mean"][PAIR_MOTION]
            gates[case] = (model.gate(np.array(est["character"]), np.array(est["camera"])),
                           model.gate(unknown, truths[case].camera_features))
        for behavior, size in CASES:
            est = read[str(clips[behavior, size])]
            if "refused" in est:
                results[_key(behavior, size)] = {"refused": est["refused"]}
                print(f"{behavior:<15} {size:<9} refused: {est['refused']}", flush=True)
                continue
            r = compare_features(np.array(est["character"]), np.array(est["camera"]), truths[behavior, size])
            g_clip, g_stage = gates[behavior, size]
            r["gate_l1"] = float(np.abs(g_clip - g_stage).sum())
            r["gate_l1_other_nearest"] = float(min(np.abs(g_clip - gates[b, size][1]).sum()
                                                   for b in BEHAVIORS if b != behavior and (b, size) in gates))
            r["size"] = est["size"]
            poses = {}
            for k, w in (("clip", g_clip), ("stage", g_stage)):
                poses[k], _ = retarget_poses(model, w, char_cd, heads[:, 0], heads[:, 1], FOV_X, ASPECT)
            d = compare(poses["clip"], poses["stage"], heads[:, 0], heads[:, 1], FOV_X, ASPECT)
            r.update({"camera_distance_ratio": float(np.median(d["distance_ratio"])),
                      "camera_theta_deg": float(np.median(d["theta_deg"])),
                      "turn_deg": float(d["turn_deg"]), "stage_turn_deg": float(d["truth_turn_deg"])})
            results[_key(behavior, size)] = r
            print(f"{behavior:<15} {size:<9} screen {r['screen']:.3f}  theta {r['theta_deg']:5.1f}  phi {r['phi_deg']:4.1f}  "
                  f"span x{r['span_ratio']:.2f}  dAB x{r['d_ab_ratio']:.2f}  sA {r['s_a_deg']:5.1f}  "
                  f"sB {r['s_b_deg']:5.1f}  sAB {r['s_ab_deg']:5.1f}  | gate L1 {r['gate_l1']:.2f} "
                  f"(other behaviors >= {r['gate_l1_other_nearest']:.2f})  | camera x{r['camera_distance_ratio']:.2f}, "
                  f"theta {r['camera_theta_deg']:.0f}, turn {r['turn_deg']:+.0f} vs {r['stage_turn_deg']:+.0f}",
                  flush=True)
        if gallery_png is not None:
            gallery(tmp, clips, read, gallery_png)
            print(f"gallery: {gallery_png}")
    return results


def gallery(tmp: Path, clips: dict, read: dict, path: Path) -> None:
    """One frame of each clip with the detected joints drawn (A's and B's skeletons)."""
    import imageio.v2 as imageio
    from PIL import Image, ImageDraw

    w, h = SIZE[0] // 2, SIZE[1] // 2
    sheet = Image.new("RGB", (2 * w, 2 * h + 40), "white")
    draw = ImageDraw.Draw(sheet)
    bones = [(0, 1), (1, 2), (1, 3), (1, 4), (4, 5), (4, 6), (0, 7)]
    for k, behavior in enumerate(BEHAVIORS):
        reader = imageio.get_reader(str(clips[behavior, "medium"]), format="FFMPEG")
        frame = Image.fromarray(reader.get_data(GALLERY_FRAME)).resize((w, h))
        reader.close()
        d = ImageDraw.Draw(frame)
        for person, colour in zip(read[str(clips[behavior, "medium"])]["gallery"], ((255, 60, 60), (60, 160, 255))):
            px = [((x + 1) * w / 2, (1 - y) * h / 2) for x, y in person]
            for i, j in bones:
                d.line([px[i], px[j]], fill=colour, width=2)
            for x, y in px:
                d.ellipse([x - 2, y - 2, x + 2, y + 2], fill=colour)
        sheet.paste(frame, ((k % 2) * w, 20 + (k // 2) * (h + 20)))
        draw.text(((k % 2) * w + 6, 4 + (k // 2) * (h + 20)), f"{behavior}, medium, frame {GALLERY_FRAME + 1}",
                  fill="black")
    sheet.save(path)


def table(results: dict) -> dict:
    rows = []
    for behavior, size in CASES:
        r = results[_key(behavior, size)]
        if "refused" in r:
            rows.append([behavior.replace("-", " "), size, f"refused: {r['refused']}"] + [""] * 7)
            continue
        rows.append([behavior.replace("-", " "), size, f"{r['screen']:.3f}", f"{r['theta_deg']:.0f}", f"{r['phi_deg']:.1f}",
                     f"{r['span_ratio']:.2f}", f"{r['d_ab_ratio']:.2f}",
                     f"{r['s_a_deg']:.0f} / {r['s_b_deg']:.0f} / {r['s_ab_deg']:.0f}",
                     f"{r['gate_l1']:.2f} ({r['gate_l1_other_nearest']:.2f})",
                     f"{r['camera_distance_ratio']:.2f} / {r['camera_theta_deg']:.0f}"])
    return {"columns": ["reference clip", "shot", "heads on screen (NDC)", "theta (deg)", "phi (deg)", "span (x)", "dAB (x)",
                        "sA / sB / sAB (deg)", "gate L1 to the stage's (to the nearest other behavior's)",
                        "camera on C, D: distance x / theta (deg)"],
            "rows": rows}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--record", action="store_true", help="write the figures to docs/data/clip_reference.json")
    p.add_argument("--worker", nargs="+", help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if a.worker:
        worker(a.worker[0], a.worker[1:])
        return 0
    results = run(GALLERY if a.record else None)
    if a.record:
        from docfigures import record

        worst = {k: max(r[k] for r in results.values() if "refused" not in r) for k in ("screen", "theta_deg", "phi_deg", "span_ratio",
                                                                   "d_ab_ratio")}
        record("clip_reference", "tools/bench_clip_reference.py", figures={**results, "worst": worst},
               tables={"summary": table(results)},
               images=[str(GALLERY.relative_to(ROOT))])
    return 0


if __name__ == "__main__":
    sys.exit(main())
