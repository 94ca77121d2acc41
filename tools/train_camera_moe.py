"""Train the learned camera behaviors (seed 002, section 5) and evaluate them as the paper does.

    python tools/train_camera_moe.py [--epochs 25] [--per-behavior 400] [--seed 0] [--out build/camera_moe]
                                     [--install] [--config JSON] [--evaluate-only]

1. makes a seeded dataset with usdcrowd: two-character motions filmed by the
   four controllers with drawn parameters (usdcrowd.cameras.moe_data), and
   for each clip the same behavior filming another pair (the gate's
   references, :func:`paired_references`);
2. trains the mixture of experts and the shared-bottom baseline with PyTorch
   in its own venv (tools/camera_moe_torch.py; torch==2.13.0, numpy,
   scikit-learn; $USDCROWD_TORCH_VENV or one made in the temporary folder);
3. evaluates in numpy: prediction error per behavior against the shared
   bottom (Figure 9), the silhouette coefficient of the gating outputs over
   training (Figure 10), and retargeting: each test clip's behavior, read by
   the gating network from that clip, rolled out on another clip's
   characters from a blind start as `usdcrowd frame --like` does (and, as
   "_warm", from the true first framing) and compared with the controller
   filming them itself (theta and phi errors; for orbits also how far and
   which way they turn);
4. writes CSV and plots to --out, and with --install copies the weights to
   usdcrowd/cameras/camera_moe.npz (what the package ships).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

TORCH_PACKAGES = ["torch==2.13.0", "numpy", "scikit-learn"]
CONFIG = {"step": 2, "past": 4, "char_past": 12, "char_future": 12, "out": 6, "gate_step": 4, "gate_len": 60,
          "experts": 9, "hidden": 128, "gate_hidden": 32, "noise": 0.3, "blind": 0.2, "residual": True,
          "pair": 0.8, "gate_lr": 10.0}


def torch_python() -> str:
    """The venv with PyTorch ($USDCROWD_TORCH_VENV, else made once in the temporary folder)."""
    venv = Path(os.environ.get("USDCROWD_TORCH_VENV", Path(tempfile.gettempdir()) / "usdcrowd-torch-venv"))
    python = venv / "bin" / "python"
    if not python.exists():
        print(f"making the PyTorch venv in {venv} ({' '.join(TORCH_PACKAGES)})", flush=True)
        subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
        subprocess.run([str(python), "-m", "pip", "install", "-q", *TORCH_PACKAGES], check=True)
    return str(python)


def make_dataset(path: Path, per_behavior: int, seed: int, frames: int = 480):
    from usdcrowd.cameras.moe_data import make_clips

    train = make_clips(seed, per_behavior, frames)
    test = make_clips(seed + 1000, max(4, per_behavior // 4), frames)
    clips = train + test
    rng = np.random.default_rng(seed + 2000)
    ref_char, ref_cam = (sum(pair, []) for pair in zip(paired_references(train, rng), paired_references(test, rng)))
    f32 = lambda a: np.asarray(a, dtype=np.float32)  # noqa: E731
    np.savez(path, config=json.dumps(CONFIG), character=f32([c.character for c in clips]),
             camera=f32([c.camera for c in clips]), ref_character=f32(ref_char), ref_camera=f32(ref_cam),
             behavior=np.array([c.behavior for c in clips]), test=np.array([0] * len(train) + [1] * len(test)))
    return train, test


def paired_references(clips, rng):
    """For each clip, the same behavior (same drawn parameters) filming another clip's characters doing
    another kind of motion: a reference that shares the clip's style and nothing else, so a gate fed it
    must carry the style (config "pair", the share of training samples gated from it). The other clip
    is drawn from ``clips`` only: train and test are paired apart."""
    from usdcrowd.cameras.moe_data import refilm

    unlike = {m: [c for c in clips if c.motion != m] for m in {c.motion for c in clips}}
    chars, cams = [], []
    for clip in clips:
        others = unlike[clip.motion]
        other = others[int(rng.integers(len(others)))]
        chars.append(other.character)
        cams.append(refilm(other, clip.params))
    return chars, cams


def around(cam: np.ndarray) -> float:
    """Degrees the camera turns round A in the ground plane of the pair's frame (signed: its direction)."""
    azimuth = np.unwrap(np.arctan2(cam[:, 4], cam[:, 3]))
    return float(np.degrees(azimuth[-1] - azimuth[0]))


def retarget_errors(weights: Path, test) -> list[dict]:
    """Each test clip's behavior, gated from the clip, rolled out: on its own characters (from its first
    framing), and blind (settled over SETTLE_FRAMES, as `usdcrowd frame --like`) on another clip's
    characters doing the same kind of motion and on a clip of another kind of motion, the last also from
    the true first framing ("other_motion_warm"); each compared with the controller (same parameters)
    filming those characters itself."""
    from usdcrowd.cameras.behaviors import BEHAVIORS
    from usdcrowd.cameras.moe import CameraMoE, camera_angles, turned
    from usdcrowd.cameras.moe_data import refilm
    from usdcrowd.jobs.toric_filming import SETTLE_FRAMES

    model = CameraMoE(weights)
    orbit = BEHAVIORS.index("orbit")
    rows = []
    for k, ref in enumerate(test):
        w = model.gate(ref.character, ref.camera)
        same = next(c for c in test[k + 1:] + test[:k] if c.motion == ref.motion)
        other = next(c for c in test[k + 1:] + test[:k] if c.motion != ref.motion)
        row = {"behavior": ref.behavior, "shot": ref.shot, "motion": ref.motion,
               "gate": " ".join(f"{v:.3f}" for v in w)}
        for name, target, warm in (("own_clip", ref, False), ("same_motion", same, False),
                                   ("other_motion", other, False), ("other_motion_warm", other, True)):
            truth = ref.camera if target is ref else refilm(target, ref.params)
            # On another pair, blind as `usdcrowd frame --like` starts (the new pair's framing is what the model
            # must find); "_warm" from the truth's first framing, for comparison.
            cold = target is not ref and not warm
            pred = model.rollout(w, target.character, None if cold else truth[0], settle=SETTLE_FRAMES if cold else 0)
            (theta_p, phi_p), (theta_t, phi_t) = camera_angles(pred), camera_angles(truth)
            row[f"{name}_features"] = float(np.abs(pred - truth).mean())
            row[f"{name}_theta_deg"] = float(np.degrees(np.abs(theta_p - theta_t)).mean())
            row[f"{name}_phi_deg"] = float(np.degrees(np.abs(np.angle(np.exp(1j * (phi_p - phi_t))))).mean())
            # An orbit's phase drifts over 20 s whatever its speed; how far and which way it turns is its style.
            row[f"{name}_turn_ratio"] = float(turned(pred) / turned(truth)) if ref.behavior == orbit else float("nan")
            row[f"{name}_same_way"] = float(np.sign(around(pred)) == np.sign(around(truth))) \
                if ref.behavior == orbit else float("nan")
        rows.append(row)
    return rows


def plots(out: Path, errors_csv: Path, history_csv: Path) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from usdcrowd.cameras.behaviors import BEHAVIORS

    err = list(csv.DictReader(open(errors_csv)))
    hist = list(csv.DictReader(open(history_csv)))
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    data, labels = [], []
    for b, name in enumerate(BEHAVIORS):
        for model in ("moe", "shared_bottom"):
            v = [float(r["err_direction_deg"]) for r in err if r["model"] == model and int(r["behavior"]) == b]
            data.append(v)
            labels.append(f"{name.replace('-track', '')}\n{'MoE' if model == 'moe' else 'shared'}")
    bp = ax[0].boxplot(data, showfliers=False, patch_artist=True)
    for k, box in enumerate(bp["boxes"]):
        box.set_facecolor("#4c72b0" if k % 2 == 0 else "#dd8452")
    ax[0].set_xticks(range(1, len(labels) + 1), labels, fontsize=8)
    ax[0].set_ylabel("direction error, 6 samples (deg)")
    ax[0].set_title("Prediction error per behavior (cf. seed 002, Fig. 9)")
    moe = [r for r in hist if r["model"] == "moe"]
    ax[1].plot([int(r["epoch"]) for r in moe], [float(r["silhouette"]) for r in moe], "o-")
    ax[1].set_xlabel("epoch")
    ax[1].set_ylabel("silhouette of gating outputs")
    ax[1].set_title("Silhouette of the gating outputs by behavior (cf. Fig. 10)")
    fig.tight_layout()
    path = out / "camera_moe_evaluation.png"
    fig.savefig(path, dpi=110)
    return [str(path)]


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--epochs", type=int, default=25)
    p.add_argument("--per-behavior", type=int, default=400, help="training clips per behavior (20 s each)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="build/camera_moe")
    p.add_argument("--install", action="store_true", help="copy the weights into the package")
    p.add_argument("--config", default="{}",
                   help='JSON overriding the model and training config, e.g. \'{"noise": 0.1}\'')
    p.add_argument("--record", action="store_true",
                   help="copy summary.csv, history.csv and the plot into docs/ and record the figures the camera "
                        "researcher's guide quotes (docs/data/camera_moe.json)")
    p.add_argument("--evaluate-only", action="store_true",
                   help="evaluate the weights, CSV and history already in --out (no training)")
    a = p.parse_args()
    CONFIG.update(json.loads(a.config))
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    train, test = make_dataset(out / "dataset.npz", a.per_behavior, a.seed)
    print(f"dataset: {len(train)} training and {len(test)} test clips in {time.perf_counter() - t0:.1f} s", flush=True)
    if not a.evaluate_only:
        python = torch_python()
        t1 = time.perf_counter()
        subprocess.run([python, str(ROOT / "tools" / "camera_moe_torch.py"), "train", str(out / "dataset.npz"),
                        str(out), "--epochs", str(a.epochs), "--seed", str(a.seed)], check=True)
        print(f"trained in {time.perf_counter() - t1:.0f} s", flush=True)
    rows = retarget_errors(out / "camera_moe.npz", test)
    with open(out / "retarget.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    from usdcrowd.cameras.behaviors import BEHAVIORS

    err = list(csv.DictReader(open(out / "errors.csv")))
    summary = []
    for b, name in enumerate(BEHAVIORS):
        line = {"behavior": name}
        for model in ("moe", "shared_bottom"):
            sel = np.array([[float(r[f"err_{k}"]) for k in range(6)] + [float(r["err_direction_deg"])] for r in err
                            if r["model"] == model and int(r["behavior"]) == b])
            line[f"{model}_direction_deg"] = float(sel[:, 6].mean())
            line[f"{model}_screen"] = float(sel[:, :3].mean())
        ret = [r for r in rows if r["behavior"] == b]
        for name in ("own_clip", "same_motion", "other_motion", "other_motion_warm"):
            for what in ("features", "theta_deg", "phi_deg"):
                line[f"rollout_{name}_{what}"] = float(np.mean([r[f"{name}_{what}"] for r in ret]))
            line[f"rollout_{name}_theta_median_deg"] = float(np.median([r[f"{name}_theta_deg"] for r in ret]))
            for what in ("turn_ratio", "same_way"):      # orbits only (NaN for the tracks)
                v = [r[f"{name}_{what}"] for r in ret]
                line[f"rollout_{name}_{what}"] = float(np.median(v) if what == "turn_ratio" else np.mean(v))
        summary.append(line)
    with open(out / "summary.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(summary[0]))
        w.writeheader()
        w.writerows(summary)
    for line in summary:
        print("  ".join(f"{k}={v:.3f}" if isinstance(v, float) else f"{k}={v}" for k, v in line.items()))
    hist = list(csv.DictReader(open(out / "history.csv")))
    sil = [float(r["silhouette"]) for r in hist if r["model"] == "moe"]
    print(f"silhouette of the gating outputs: first epoch {sil[0]:.3f}, last {sil[-1]:.3f}")
    print("plots:", *plots(out, out / "errors.csv", out / "history.csv"))
    if a.record:
        record_figures(out, summary, sil, rows)
    if a.install:
        dest = ROOT / "usdcrowd" / "cameras" / "camera_moe.npz"
        shutil.copy(out / "camera_moe.npz", dest)
        print(f"installed {dest} ({dest.stat().st_size / 1e6:.2f} MB)")
    return 0


def record_figures(out: Path, summary: list[dict], silhouette: list[float], rows: list[dict]) -> None:
    """The guide's figures: the summary per behavior, the silhouette's rise, the spread of single orbits."""
    sys.path.insert(0, str(ROOT / "tools"))
    from docfigures import record

    docs = ROOT / "docs"
    shutil.copyfile(out / "summary.csv", docs / "camera_moe_summary.csv")
    shutil.copyfile(out / "history.csv", docs / "camera_moe_history.csv")
    shutil.copyfile(out / "camera_moe_evaluation.png", docs / "images" / "camera_moe_evaluation.png")
    hist = list(csv.DictReader(open(out / "history.csv")))
    orbit_turns = [r[f"{name}_turn_ratio"] for r in rows for name in ("own_clip", "same_motion", "other_motion")
                   if np.isfinite(r[f"{name}_turn_ratio"])]
    figures = {line["behavior"].replace("-", "_"): {k: v for k, v in line.items() if k != "behavior"}
               for line in summary}
    figures["silhouette"] = {"first": silhouette[0], "last": silhouette[-1]}
    figures["training_s"] = sum(float(r["seconds"]) for r in hist)
    figures["training_min"] = figures["training_s"] / 60
    if orbit_turns:
        figures["orbit_turn_ratio"] = {"min": float(np.min(orbit_turns)), "max": float(np.max(orbit_turns))}
    figures["ranges"] = _ranges(summary)
    record("camera_moe", "tools/train_camera_moe.py", figures=figures, tables={"summary": _summary_table(summary)},
           images=["docs/images/camera_moe_evaluation.png"])


ROLLOUTS = ("own_clip", "same_motion", "other_motion", "other_motion_warm")


def _summary_table(summary: list[dict]) -> dict:
    """The guide's table: one prediction's direction error, then theta error mean / median per roll-out."""
    def pair(a, b):
        return " / ".join(f"{v:.1f}" if abs(v) < 50 else f"{v:.0f}" for v in (a, b))

    rows = [[line["behavior"].replace("-", " "), pair(line["moe_direction_deg"], line["shared_bottom_direction_deg"]),
             *(pair(line[f"rollout_{r}_theta_deg"], line[f"rollout_{r}_theta_median_deg"]) for r in ROLLOUTS)]
            for line in summary]
    return {"columns": ["behavior", "direction error, MoE / shared bottom (one prediction, deg)",
                        "roll-out on its own clip", "on another pair, same kind of motion",
                        "on another kind of motion", "the same, started from the true framing"], "rows": rows}


def _ranges(summary: list[dict]) -> dict:
    """Ranges the guide's prose quotes: the tracks' medians by roll-out, the one-prediction errors."""
    by = {line["behavior"]: line for line in summary}
    tracks = [b for b in by if b.endswith("track")]
    steady = [by[b] for b in ("direct-track", "side-track") if b in by]

    def span(lines, key):
        values = [line[key] for line in lines]
        return {"min": float(min(values)), "max": float(max(values))}

    def over(lines, rollouts):
        values = [line[f"rollout_{r}_theta_median_deg"] for line in lines for r in rollouts]
        return {"min": float(min(values)), "max": float(max(values))}

    return {"steady_same_kind": over(steady, ("own_clip", "same_motion")),
            "steady_other_kind": over(steady, ("other_motion",)),
            "relative": over([by["relative-track"]], ROLLOUTS),
            "tracks_moe": span([by[b] for b in tracks], "moe_direction_deg"),
            "tracks_shared_bottom": span([by[b] for b in tracks], "shared_bottom_direction_deg")}


if __name__ == "__main__":
    raise SystemExit(main())
