"""Train the cinematic feature estimator (seed 002, section 4) and measure it on held-out clips.

    python tools/train_feature_estimator.py [--epochs 30] [--per-behavior 200] [--seed 0]
                                            [--out build/feature_estimator] [--install] [--record]

1. makes a seeded synthetic dataset, as the paper does (section 4.3): the
   two-character motions of usdcrowd.cameras.moe_data filmed by the four
   controllers with drawn parameters, the joints of
   usdcrowd.cameras.estimator.BODY projected per frame, with the shoulders
   and hips turned by up to 10 degrees of slow noise (the paper's joint
   noise), each joint moved by a detector's noise on screen, and the body
   drawn as a detector may see it (shoulder and hip widths and the nose,
   which tools/calibrate_pose_joints.py measures on usdcrowd's characters;
   left and right swapped in profile, where a detector guesses them);
2. trains the network with PyTorch in its own venv
   (tools/feature_estimator_torch.py; $USDCROWD_TORCH_VENV or one made in the
   temporary folder);
3. measures it in numpy on held-out clips (the camera model's held-out seed):
   per component, the error against the truth (theta and phi of the camera's
   direction, degrees; the span and dAB as ratios; sA, sB, sAB, degrees), and
   what it does to the gating network: the expert weights of each clip read
   from estimated features against those read from the true ones;
4. with --install copies the weights to usdcrowd/cameras/feature_estimator.npz
   (what the package ships); with --record writes the figures to
   docs/data/feature_estimator.json (tools/docfigures.py).
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tools"))

STRIDE = 3              # frames between training windows of one clip
SCREEN_NOISE = 0.006    # NDC, per joint and frame: a pose detector's jitter (head, neck, nose)
LIMB_NOISE = 0.015      # and on the shoulders and hips, which it places less surely
JOINT_NOISE = np.radians(10.0)
PROFILE = 0.5           # a character whose shoulders show less than this share of their width is in profile,
SWAP = 0.5              # where a detector's left and right are a guess: swapped with this chance per clip
SHOULDER_OUT = (0.11, 0.2)   # how far out the detector puts the shoulders, drawn per clip and character (m)
HIP_OUT = (0.08, 0.12)       # and the hips
NOSE_FORWARD = (0.0, 0.105)  # and the nose in front of the head's centre


def _slow_noise(rng, frames: int, amplitude: float) -> np.ndarray:
    """(frames,) a slowly varying angle within +-amplitude (two sines of drawn frequency and phase)."""
    t = np.arange(frames) / 24.0
    a = rng.uniform(0.0, amplitude, 2) / 2
    return sum(a[k] * np.sin(2 * np.pi * rng.uniform(0.05, 0.5) * t + rng.uniform(0, 6.3)) for k in range(2))


def drawn_body(rng) -> np.ndarray:
    """(8, 3) a body as a detector may place its joints: widths and the nose drawn (see the constants)."""
    from usdcrowd.cameras.estimator import BODY

    body = BODY.copy()
    body[2:4, 1] = np.array([1.0, -1.0]) * rng.uniform(*SHOULDER_OUT)
    body[5:7, 1] = np.array([1.0, -1.0]) * rng.uniform(*HIP_OUT)
    body[7, 0] = rng.uniform(*NOSE_FORWARD)
    return body


def clip_joints(clip, rng, screen_noise: float = SCREEN_NOISE, limb_noise: float = LIMB_NOISE,
                swap: float = SWAP) -> np.ndarray:
    """(t, 2, 8, 2) NDC joints of a clip's two characters, filmed by the clip's own controller, as a
    detector would give them: noisy, of drawn widths, and with left and right swapped in profile now and then."""
    from usdcrowd.cameras.estimator import body_points, project
    from usdcrowd.cameras.moe_data import ASPECT, FOV_X, refilm_track

    cam = refilm_track(clip, clip.params).cam_to_world
    t = len(clip.yaw_a)
    out = []
    for heads, yaw in ((clip.heads_a, clip.yaw_a), (clip.heads_b, clip.yaw_b)):
        # Drawn per character: a detector places one person's joints unlike another's (measured on usdcrowd's).
        pts = body_points(heads, yaw + _slow_noise(rng, t, JOINT_NOISE), yaw + _slow_noise(rng, t, JOINT_NOISE),
                          drawn_body(rng))
        joints = project(cam, pts, FOV_X, ASPECT)
        if rng.random() < swap:
            shoulders = np.stack([-np.sin(yaw), np.cos(yaw)], -1)
            side = np.abs(np.einsum("ti,ti->t", cam[:, 0, :2], shoulders)) < PROFILE
            joints[side] = joints[side][:, [0, 1, 3, 2, 4, 6, 5, 7]]
        out.append(joints)
    joints = np.stack(out, 1)
    noise = np.where(np.isin(np.arange(8), [2, 3, 5, 6])[None, None, :, None], limb_noise, screen_noise)
    return joints + rng.normal(0.0, 1.0, joints.shape) * noise


def targets(clip) -> np.ndarray:
    """(t, 11) what the estimator estimates (usdcrowd.cameras.estimator.OUTPUTS), from the clip's truth."""
    return np.column_stack([clip.camera[:, 4:8], clip.character[:, 0:7]])


def make_dataset(path: Path, per_behavior: int, seed: int):
    from usdcrowd.cameras.estimator import frame_inputs, windows
    from usdcrowd.cameras.moe_data import held_out_clips, make_clips

    rng = np.random.default_rng(seed + 3000)
    train, test = make_clips(seed, per_behavior), held_out_clips(max(4, per_behavior // 4), seed)
    xs, ys, flags = [], [], []
    for flag, clips in ((0, train), (1, test)):
        for clip in clips:
            x, y = windows(frame_inputs(clip_joints(clip, rng))), targets(clip)
            xs.append(x[::STRIDE])
            ys.append(y[::STRIDE])
            flags.append(np.full(len(xs[-1]), flag))
    np.savez(path, x=np.concatenate(xs).astype(np.float32), y=np.concatenate(ys).astype(np.float32),
             test=np.concatenate(flags))
    return train, test


def _deg(a):
    return np.degrees(np.abs((a + np.pi) % (2 * np.pi) - np.pi))


def component_errors(est_char, est_cam, true_char, true_cam) -> dict:
    """(t,) errors per frame of estimated (t, 10) character and (t, 8) camera features against true ones."""
    from usdcrowd.cameras.moe import camera_angles

    theta, phi = camera_angles(est_cam)
    t_theta, t_phi = camera_angles(true_cam)
    ang = lambda f, k: np.arctan2(f[:, k], f[:, k + 1])  # noqa: E731
    return {"theta_deg": _deg(theta - t_theta), "phi_deg": _deg(phi - t_phi),
            "span_ratio": np.exp(est_cam[:, 7] - true_cam[:, 7]),
            "d_ab_ratio": est_char[:, 0] / true_char[:, 0],
            "s_a_deg": _deg(ang(est_char, 1) - ang(true_char, 1)),
            "s_b_deg": _deg(ang(est_char, 3) - ang(true_char, 3)),
            "s_ab_deg": _deg(ang(est_char, 5) - ang(true_char, 5))}


def evaluate(weights: Path, test, seed: int) -> dict:
    """Per component, medians and 95th percentiles over the held-out clips' frames; and the gate."""
    from usdcrowd.cameras.behaviors import BEHAVIORS
    from usdcrowd.cameras.estimator import FeatureEstimator
    from usdcrowd.cameras.moe import CLIP_WEIGHTS, PAIR_MOTION, CameraMoE

    est, model = FeatureEstimator(weights), CameraMoE(CLIP_WEIGHTS)     # the model that reads clips
    rng = np.random.default_rng(seed + 4000)
    per = {}
    gates = {b: [] for b in BEHAVIORS}
    for clip in test:
        char, cam = est.features(clip_joints(clip, rng), model.w["char_mean"])
        for k, v in component_errors(char, cam, clip.character, clip.camera).items():
            per.setdefault(k, []).append(v)
        unknown = clip.character.copy()
        unknown[:, PAIR_MOTION] = model.w["char_mean"][PAIR_MOTION]
        w_true, w_unknown, w_est = (model.gate(c, m) for c, m in ((clip.character, clip.camera),
                                                                   (unknown, clip.camera), (char, cam)))
        gates[BEHAVIORS[clip.behavior]].append((np.abs(w_est - w_true).sum(), np.abs(w_unknown - w_true).sum(),
                                                np.abs(w_est - w_unknown).sum()))
    out = {"components": {}, "gate": {}}
    for k, v in per.items():
        v = np.concatenate(v)
        ratio = k.endswith("ratio")
        err = np.abs(np.log(v)) if ratio else v
        out["components"][k] = {"median": float(np.exp(np.median(err)) if ratio else np.median(err)),
                                "p95": float(np.exp(np.percentile(err, 95)) if ratio else np.percentile(err, 95))}
    for b, rows in gates.items():
        r = np.array(rows)
        out["gate"][b] = {"l1_estimated": float(np.median(r[:, 0])), "l1_motion_unknown": float(np.median(r[:, 1])),
                          "l1_estimated_vs_unknown": float(np.median(r[:, 2])), "clips": len(rows)}
    return out


def report(results: dict) -> None:
    print("component      median    95th pct   (ratios: a multiple of the truth, either way)")
    for k, v in results["components"].items():
        print(f"{k:<13} {v['median']:8.3f}  {v['p95']:8.3f}")
    print("gate weights, L1 from the truth's (median over clips): estimated / truth without motion / between")
    for b, v in results["gate"].items():
        print(f"{b:<15} {v['l1_estimated']:.3f} / {v['l1_motion_unknown']:.3f} / {v['l1_estimated_vs_unknown']:.3f}"
              f"  ({v['clips']} clips)")


def table(results: dict) -> dict:
    names = {"theta_deg": "theta (deg)", "phi_deg": "phi (deg)", "span_ratio": "span (x truth)",
             "d_ab_ratio": "dAB (x truth)", "s_a_deg": "sA (deg)", "s_b_deg": "sB (deg)", "s_ab_deg": "sAB (deg)"}
    return {"columns": ["feature", "median error", "95th percentile"],
            "rows": [[names[k], f"{v['median']:.2f}", f"{v['p95']:.2f}"] for k, v in results["components"].items()]}


def gate_table(results: dict) -> dict:
    """Per behavior, how far the gate's expert weights move (L1, median over clips) from those the true
    features give: with the estimated features, and with the true ones less the motion a picture lacks."""
    return {"columns": ["reference's behavior", "estimated features", "true features, motion unknown",
                        "estimated against true with motion unknown"],
            "rows": [[b.replace("-", " "), f"{v['l1_estimated']:.2f}", f"{v['l1_motion_unknown']:.2f}",
                      f"{v['l1_estimated_vs_unknown']:.2f}"] for b, v in results["gate"].items()]}


def main(argv=None) -> int:
    from train_camera_moe import torch_python

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--epochs", type=int, default=30)
    p.add_argument("--per-behavior", type=int, default=200)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=ROOT / "build" / "feature_estimator")
    p.add_argument("--install", action="store_true", help="copy the weights into the package")
    p.add_argument("--evaluate-only", action="store_true", help="measure the weights in --out (or the shipped ones)")
    p.add_argument("--record", action="store_true", help="write the figures to docs/data/feature_estimator.json")
    a = p.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    weights = a.out / "feature_estimator.npz"
    if a.evaluate_only:
        from usdcrowd.cameras.estimator import WEIGHTS
        from usdcrowd.cameras.moe_data import held_out_clips

        weights = weights if weights.exists() else WEIGHTS
        test = held_out_clips(max(4, a.per_behavior // 4), a.seed)
    else:
        print(f"dataset: {a.per_behavior} clips per behavior", flush=True)
        _, test = make_dataset(a.out / "data.npz", a.per_behavior, a.seed)
        subprocess.run([torch_python(), str(ROOT / "tools" / "feature_estimator_torch.py"), "train",
                        str(a.out / "data.npz"), str(weights), "--epochs", str(a.epochs), "--seed", str(a.seed)],
                       check=True)
    results = evaluate(weights, test, a.seed)
    report(results)
    (a.out / "evaluation.json").write_text(json.dumps(results, indent=1))
    if a.install:
        from usdcrowd.cameras.estimator import WEIGHTS

        shutil.copy(weights, WEIGHTS)
        print(f"installed {WEIGHTS}")
    if a.record:
        from docfigures import record

        record("feature_estimator", "tools/train_feature_estimator.py", figures=results,
               tables={"components": table(results), "gate": gate_table(results)})
    return 0


if __name__ == "__main__":
    sys.exit(main())
