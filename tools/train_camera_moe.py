"""Train the learned camera behaviors (seed 002, section 5) and evaluate them as the paper does.

    python tools/train_camera_moe.py [--recipe base|stage] [--epochs 50] [--per-behavior 400] [--seed 0]
                                     [--retarget-clips 400]
                                     [--out build/camera_moe] [--install | --install-clip] [--config JSON]
                                     [--evaluate-only]

The shipped models: ``--recipe stage --install`` (stage references) and
``--install-clip`` (film clips, the base recipe), 50 epochs, seed 0 each.

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
   usdcrowd/cameras/camera_moe.npz (the model the package reads stage
   references with), with --install-clip to camera_moe_clip.npz (film clips).

Config keys beyond the sizes (usdcrowd.cameras.moe.Config): ``gate_style``
gives the gate the style features (usdcrowd.cameras.moe.style_features) and
``style`` weighs an auxiliary loss asking its logits for the controllers'
parameters (:func:`style_labels`). ``expert_style`` has the experts read
the style too; ``unseen_motion`` (a share) gates that many training windows
from a reference without its pair motion, as a film clip gives it
(:func:`unseen_motion_styles`). All four are off in the base recipe and on
in the stage recipe (:data:`STAGE_RECIPE`).
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tools"))

from tool_venvs import tool_venv  # noqa: E402  (tools/ is no package)

TORCH_PACKAGES = ["torch==2.13.0", "numpy", "scikit-learn"]
CONFIG = {"step": 2, "past": 4, "char_past": 12, "char_future": 12, "out": 6, "gate_step": 4, "gate_len": 60,
          "experts": 9, "hidden": 128, "gate_hidden": 32, "noise": 0.3, "blind": 0.2, "residual": True,
          "pair": 0.8, "gate_lr": 10.0}
# The model `frame --like` reads stage references with (camera_moe.npz): the base recipe above with experts
# that read the reference's style, taught on a quarter of the gate's windows what a film clip gives (no pair
# motion). The base recipe itself is the film clips' model (camera_moe_clip.npz).
STAGE_RECIPE = {"gate_style": True, "style": 0.3, "expert_style": True, "unseen_motion": 0.25}
# References per behavior the retargeting is measured on (held-out clips, 1,600 in all): a share near 95 %
# measured on 100 orbits is known to +-4 points, on 400 to +-2 (a clip costs the evaluation about 15 ms).
RETARGET_PER_BEHAVIOR = 400


# The paper's recipe (section 5.2, appendix A) at its own frame rate (60 fps, every frame): 60 past and 120
# character frames in, 30 out, hidden 512, a gating LSTM of 512 over 400 frames, 9 experts.
PAPER_SIZES = {"step": 1, "past": 60, "char_past": 60, "char_future": 60, "out": 30, "gate_step": 1,
               "gate_len": 400, "experts": 9, "hidden": 512, "gate_hidden": 512}


def torch_python() -> str:
    """The venv with PyTorch ($USDCROWD_TORCH_VENV, else made once in the temporary folder)."""
    return tool_venv("torch", "USDCROWD_TORCH_VENV", TORCH_PACKAGES)


def make_dataset(path: Path, per_behavior: int, seed: int, frames: int = 480):
    from usdcrowd.cameras.moe import U, style_features
    from usdcrowd.cameras.moe_data import held_out_clips, make_clips

    train = make_clips(seed, per_behavior, frames)
    test = held_out_clips(max(4, per_behavior // 4), seed, frames)
    clips = train + test
    rng = np.random.default_rng(seed + 2000)
    ref_char, ref_cam = (sum(pair, []) for pair in zip(paired_references(train, rng), paired_references(test, rng)))
    f32 = lambda a: np.asarray(a, dtype=np.float32)  # noqa: E731
    # The torch side reads where the direction's columns are (its error in degrees) from the data.
    np.savez(path, config=json.dumps({**CONFIG, "u": [U.start, U.stop]}),
             character=f32([c.character for c in clips]), camera=f32([c.camera for c in clips]), ref_character=f32(ref_char), ref_camera=f32(ref_cam),
             behavior=np.array([c.behavior for c in clips]), test=np.array([0] * len(train) + [1] * len(test)),
             style=f32([style_labels(c) for c in clips]),
             **({"gate_style": f32([style_features(c.character, c.camera) for c in clips]),
                 "ref_gate_style": f32([style_features(c, m) for c, m in zip(ref_char, ref_cam)])}
                if CONFIG.get("gate_style") else {}),
             **(unseen_motion_styles(clips, ref_char, ref_cam, len(train))
                if CONFIG.get("gate_style") and CONFIG.get("unseen_motion") else {}))
    return train, test


def unseen_motion_styles(clips, ref_char, ref_cam, n_train: int) -> dict:
    """The style features as a film clip's reference gives them (config "unseen_motion"): a picture
    shows no pair motion, so a clip's character columns 7-9 are the training mean
    (usdcrowd.cameras.estimator.FeatureEstimator.features), and its style's turn and velocity columns
    are made from that mean. Training gates some windows from these so the experts learn not to
    trust what a clip cannot give."""
    from usdcrowd.cameras.moe import PAIR_MOTION, style_features

    mean = np.concatenate([c.character for c in clips[:n_train]]).astype(np.float32).mean(0)[PAIR_MOTION]

    def still(char):
        return np.concatenate([char[:, :PAIR_MOTION.start], np.broadcast_to(mean, (len(char), len(mean)))], 1)

    f32 = lambda a: np.asarray(a, dtype=np.float32)  # noqa: E731
    return {"gate_style_still": f32([style_features(still(c.character), c.camera) for c in clips]),
            "ref_gate_style_still": f32([style_features(still(c), m) for c, m in zip(ref_char, ref_cam)])}


def style_labels(clip) -> list[float]:
    """What the controller that filmed ``clip`` was told: its behavior (one-hot), the relative track's offset
    (/ 60 deg), the orbit's speed (/ 25 deg/s), the side and the shot size (one-hot). Config "style" > 0 asks
    the gate's logits to predict these (an auxiliary loss): the gate is otherwise taught only through the
    camera it makes, which reads a style's kind and sign but barely its size (an offset's or orbit's)."""
    from usdcrowd.cameras.behaviors import BEHAVIORS, SHOT_SIZES

    p = clip.params
    kind = [float(clip.behavior == b) for b in range(len(BEHAVIORS))]
    return [*kind, p.offset / 60.0 * kind[1], p.orbit_speed / 25.0 * kind[3], p.side * (1.0 - kind[1]),
            *[float(p.shot == s) for s in SHOT_SIZES]]


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


def retarget_errors(weights: Path, test) -> list[dict]:
    """Retargeting as `usdcrowd frame --like` runs it, on held-out clips: each test clip is a reference,
    gated from itself; its style is rolled out blind on another test clip's characters doing another kind
    of motion (usdcrowd.cameras.retarget.retarget_poses) and compared, frame by frame, with the controller
    with the reference's parameters filming those characters (usdcrowd.cameras.retarget.compare). One row
    per reference: medians and worst cases over its frames."""
    from usdcrowd.cameras.behaviors import BEHAVIORS
    from usdcrowd.cameras.moe import CameraMoE
    from usdcrowd.cameras.moe_data import ASPECT, FOV_X, refilm_track
    from usdcrowd.cameras.retarget import compare, retarget_poses

    model = CameraMoE(weights)
    rows = []
    for k, ref in enumerate(test):
        w = model.gate(ref.character, ref.camera)
        target = next(c for c in test[k + 1:] + test[:k] if c.motion != ref.motion)
        poses, _ = retarget_poses(model, w, target.character, target.heads_a, target.heads_b, FOV_X, ASPECT)
        truth = refilm_track(target, ref.params).cam_to_world
        d = compare(poses, truth, target.heads_a, target.heads_b, FOV_X, ASPECT)
        ratio = d["distance_ratio"]
        rows.append({"behavior": BEHAVIORS[ref.behavior], "shot": ref.shot, "motion": ref.motion,
                     "target_motion": target.motion,
                     "distance_ratio_median": float(np.median(ratio)), "distance_ratio_max": float(ratio.max()),
                     "distance_ratio_min": float(ratio.min()),
                     "theta_deg_median": float(np.median(d["theta_deg"])), "theta_deg_max": float(d["theta_deg"].max()),
                     "phi_deg_median": float(np.median(d["phi_deg"])),
                     "screen_median": float(np.median(d["screen"])), "screen_max": float(d["screen"].max()),
                     "roll_deg_max": float(d["roll_deg"].max()),
                     "turn_deg": d["turn_deg"], "truth_turn_deg": d["truth_turn_deg"],
                     "gate": " ".join(f"{v:.3f}" for v in w)})
    return rows


def prediction_summary(errors_csv: Path) -> list[dict]:
    """Per behavior, one prediction's mean errors (Fig. 9): the direction (degrees) and the screen
    positions (NDC), mixture of experts and shared bottom."""
    from usdcrowd.cameras.behaviors import BEHAVIORS

    err = list(csv.DictReader(open(errors_csv)))
    summary = []
    for b, name in enumerate(BEHAVIORS):
        line = {"behavior": name}
        for model in ("moe", "shared_bottom"):
            sel = [r for r in err if r["model"] == model and int(r["behavior"]) == b]
            if not sel:                                     # trained --moe-only
                continue
            line[f"{model}_direction_deg"] = float(np.mean([float(r["err_direction_deg"]) for r in sel]))
            line[f"{model}_screen"] = float(np.mean([float(r[f"err_{k}"]) for r in sel for k in range(4)]))
        summary.append(line)
    return summary


def retarget_summary(rows: list[dict]) -> list[dict]:
    """Per behavior and shot size: medians over the references, means, and the worst case."""
    from usdcrowd.cameras.behaviors import BEHAVIORS, SHOT_SIZES

    out = []
    for b in BEHAVIORS:
        for shot in (*SHOT_SIZES, "all"):
            sel = [r for r in rows if r["behavior"] == b and (shot == "all" or r["shot"] == shot)]
            if not sel:
                continue
            col = lambda k: np.array([r[k] for r in sel])  # noqa: E731
            line = {"behavior": b, "shot": shot, "clips": len(sel),
                    "distance_ratio_median": float(np.median(col("distance_ratio_median"))),
                    "distance_ratio_mean": float(np.mean(col("distance_ratio_median"))),
                    "distance_ratio_worst": float(col("distance_ratio_max").max()),
                    "distance_ratio_least": float(col("distance_ratio_min").min()),
                    "theta_deg_median": float(np.median(col("theta_deg_median"))),
                    "theta_deg_mean": float(np.mean(col("theta_deg_median"))),
                    "theta_deg_worst": float(col("theta_deg_max").max()),
                    "phi_deg_median": float(np.median(col("phi_deg_median"))),
                    "screen_median": float(np.median(col("screen_median"))),
                    "screen_worst": float(col("screen_max").max()),
                    "roll_deg_worst": float(col("roll_deg_max").max())}
            if b == "orbit":
                turn, truth = col("turn_deg"), col("truth_turn_deg")
                speed = np.abs(turn) / np.maximum(np.abs(truth), 1e-9)
                same = np.sign(turn) == np.sign(truth)
                low, high = wilson_interval(int(same.sum()), len(same))
                line.update({"orbit_same_way": float(np.mean(same)), "orbit_same_way_low": low,
                             "orbit_same_way_high": high,
                             "orbit_speed_median": float(np.median(speed)),
                             "orbit_speed_least": float(speed.min()), "orbit_speed_most": float(speed.max())})
            out.append(line)
    return out


def wilson_interval(hits: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """The 95 % Wilson score interval of a share of ``hits`` in ``n`` (it stays inside 0-1 near the ends,
    where a share like the orbits' right-way turns lies)."""
    if n == 0:
        return 0.0, 1.0
    p = hits / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return float(centre - half), float(centre + half)


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
            if not v:                                       # trained --moe-only
                continue
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
    p.add_argument("--epochs", type=int, default=50)
    p.add_argument("--per-behavior", type=int, default=400, help="training clips per behavior (20 s each)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--retarget-clips", type=int, default=RETARGET_PER_BEHAVIOR,
                   help="held-out references per behavior retargeting is measured on")
    p.add_argument("--out", default="build/camera_moe")
    slot = p.add_mutually_exclusive_group()
    slot.add_argument("--install", action="store_true",
                      help="copy the weights into the package as the model for stage references (camera_moe.npz)")
    slot.add_argument("--install-clip", action="store_true",
                      help="copy them as the model for film clips (camera_moe_clip.npz)")
    p.add_argument("--recipe", choices=("base", "stage"), default="base",
                   help="base: the film clips' model; stage: the stage references' model (STAGE_RECIPE)")
    p.add_argument("--config", default="{}",
                   help='JSON overriding the model and training config, e.g. \'{"noise": 0.1}\'')
    p.add_argument("--record", action="store_true",
                   help="copy summary.csv, history.csv and the plot into docs/ and record the figures the camera "
                        "researcher's guide quotes (docs/data/camera_moe.json)")
    p.add_argument("--costs", action="store_true",
                   help="only measure what one training epoch costs with the paper's sizes and with this config "
                        "(PyTorch, this machine), print it and, with --record, record it (docs/data/camera_moe_costs.json)")
    p.add_argument("--moe-only", action="store_true",
                   help="train no shared-bottom baseline (its columns of summary.csv stay empty): for sweeps")
    p.add_argument("--evaluate-only", action="store_true",
                   help="evaluate the weights, CSV and history already in --out (no training)")
    a = p.parse_args()
    CONFIG.update(STAGE_RECIPE if a.recipe == "stage" else {})
    CONFIG.update(json.loads(a.config))
    if CONFIG.get("unseen_motion") and not CONFIG.get("gate_style"):
        p.error("unseen_motion needs gate_style (it replaces the style features the gate reads)")
    if a.costs:
        return costs(a.record)
    if a.record and a.retarget_clips != RETARGET_PER_BEHAVIOR:
        p.error(f"--record measures on the pages' {RETARGET_PER_BEHAVIOR} references per behavior: "
                "leave --retarget-clips out")
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    train, test = make_dataset(out / "dataset.npz", a.per_behavior, a.seed)
    print(f"dataset: {len(train)} training and {len(test)} test clips in {time.perf_counter() - t0:.1f} s", flush=True)
    if not a.evaluate_only:
        python = torch_python()
        t1 = time.perf_counter()
        subprocess.run([python, str(ROOT / "tools" / "camera_moe_torch.py"), "train", str(out / "dataset.npz"),
                        str(out), "--epochs", str(a.epochs), "--seed", str(a.seed),
                        *(["--moe-only"] if a.moe_only else [])], check=True)
        print(f"trained in {time.perf_counter() - t1:.0f} s", flush=True)
    from usdcrowd.cameras.moe_data import held_out_clips

    rows = retarget_errors(out / "camera_moe.npz", held_out_clips(a.retarget_clips, a.seed))
    with open(out / "retarget.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    summary = prediction_summary(out / "errors.csv")
    retarget = retarget_summary(rows)
    for name, lines in (("summary.csv", summary), ("retarget_summary.csv", retarget)):
        with open(out / name, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(dict.fromkeys(k for line in lines for k in line)))
            w.writeheader()
            w.writerows(lines)
    for line in summary + retarget:
        print("  ".join(f"{k}={v:.3f}" if isinstance(v, float) else f"{k}={v}" for k, v in line.items()))
    hist = list(csv.DictReader(open(out / "history.csv")))
    sil = [float(r["silhouette"]) for r in hist if r["model"] == "moe"]
    print(f"silhouette of the gating outputs: first epoch {sil[0]:.3f}, last {sil[-1]:.3f}")
    print("plots:", *plots(out, out / "errors.csv", out / "history.csv"))
    if a.record:
        record_figures(out, summary, retarget, sil)
    from usdcrowd.cameras.moe import CLIP_WEIGHTS, WEIGHTS

    for dest in [WEIGHTS] * a.install + [CLIP_WEIGHTS] * a.install_clip:
        # Stage references are read by experts that read the style; film clips cannot give it.
        reads_style = json.loads(str(np.load(out / "camera_moe.npz")["config"])).get("expert_style", False)
        if reads_style != (dest == WEIGHTS):
            print(f"not installed: {dest.name} takes a model whose experts read the style "
                  f"{'(--recipe stage)' if dest == WEIGHTS else 'not at all (--recipe base)'}", file=sys.stderr)
            return 2
        shutil.copy(out / "camera_moe.npz", dest)
        print(f"installed {dest} ({dest.stat().st_size / 1e6:.2f} MB)")
    return 0


def costs(record_them: bool) -> int:
    """Seconds per training epoch (185,600 samples, as the shipped model's) with the paper's sizes and with
    this config's, measured on this machine: the reason the shipped model is smaller, in numbers."""
    python = torch_python()
    out = {}
    for name, cfg in (("paper", PAPER_SIZES), ("shipped", CONFIG)):
        r = subprocess.run([python, str(ROOT / "tools" / "camera_moe_torch.py"), "time", json.dumps(cfg)],
                           check=True, capture_output=True, text=True)
        out[name] = json.loads(r.stdout.strip().splitlines()[-1])
        e = out[name]
        print(f"{name:8} {e['parameters']:>10,} parameters, {e['seconds_per_batch']:.3f} s per batch of 256, "
              f"{e['seconds_per_epoch'] / 60:.1f} min per epoch, {e['seconds_per_epoch'] * 100 / 3600:.1f} h for "
              f"the paper's 100 epochs", flush=True)
    out["ratio"] = out["paper"]["seconds_per_epoch"] / out["shipped"]["seconds_per_epoch"]
    out["paper"]["hours_100_epochs"] = out["paper"]["seconds_per_epoch"] * 100 / 3600
    out["paper"]["hours_25_epochs"] = out["paper"]["seconds_per_epoch"] * 25 / 3600
    if record_them:
        sys.path.insert(0, str(ROOT / "tools"))
        from docfigures import record

        record("camera_moe_costs", "tools/train_camera_moe.py", figures=out,
               command="python tools/train_camera_moe.py --costs --record")
    return 0


def record_figures(out: Path, summary: list[dict], retarget: list[dict], silhouette: list[float]) -> None:
    """The guide's figures: one prediction per behavior (Fig. 9), the silhouette's rise (Fig. 10), and
    retargeting on held-out clips per behavior and shot size, with the table the guide shows."""
    sys.path.insert(0, str(ROOT / "tools"))
    from docfigures import record

    docs = ROOT / "docs"
    for name in ("summary.csv", "retarget_summary.csv", "history.csv"):
        shutil.copyfile(out / name, docs / f"camera_moe_{name}")
    shutil.copyfile(out / "camera_moe_evaluation.png", docs / "images" / "camera_moe_evaluation.png")
    hist = list(csv.DictReader(open(out / "history.csv")))
    key = lambda text: text.replace("-", "_")  # noqa: E731
    figures = {key(line["behavior"]): {k: v for k, v in line.items() if k != "behavior"} for line in summary}
    figures["retarget"] = {f"{key(r['behavior'])}_{key(r['shot'])}": {k: v for k, v in r.items()
                                                                       if k not in ("behavior", "shot")}
                           for r in retarget}
    figures["silhouette"] = {"first": silhouette[0], "last": silhouette[-1]}
    figures["training_s"] = sum(float(r["seconds"]) for r in hist)
    figures["training_min"] = figures["training_s"] / 60
    figures["ranges"] = _ranges(summary, retarget)
    record("camera_moe", "tools/train_camera_moe.py", figures=figures,
           tables={"summary": _summary_table(summary), "retarget": _retarget_table(retarget)},
           images=["docs/images/camera_moe_evaluation.png"])


def _summary_table(summary: list[dict]) -> dict:
    """One prediction's errors per behavior, mixture of experts against the shared bottom (Fig. 9)."""
    rows = [[line["behavior"].replace("-", " "),
             f"{line['moe_direction_deg']:.1f} / {line['shared_bottom_direction_deg']:.1f}",
             f"{line['moe_screen']:.3f} / {line['shared_bottom_screen']:.3f}"] for line in summary]
    return {"columns": ["behavior", "direction error, MoE / shared bottom (deg)",
                        "screen error, MoE / shared bottom (NDC)"], "rows": rows}


def _retarget_table(retarget: list[dict]) -> dict:
    """Retargeting per behavior and shot size: distance ratio, theta, screen, roll, orbits' turn."""
    def orbit(r):
        if "orbit_same_way" not in r:
            return ""
        return (f"{r['orbit_same_way']:.0%} ({r['orbit_same_way_low']:.0%}-{r['orbit_same_way_high']:.0%}), "
                f"{r['orbit_speed_median']:.2f}x")

    rows = [[r["behavior"].replace("-", " "), r["shot"], str(r["clips"]),
             f"{r['distance_ratio_median']:.2f} / {r['distance_ratio_mean']:.2f} / {r['distance_ratio_worst']:.2f}",
             f"{r['theta_deg_median']:.1f} / {r['theta_deg_mean']:.1f} / {r['theta_deg_worst']:.0f}",
             f"{r['screen_median']:.3f}", f"{r['roll_deg_worst']:.1f}", orbit(r)]
            for r in retarget if r["shot"] != "all"]
    return {"columns": ["behavior", "shot", "clips", "distance ratio, median / mean / worst",
                        "theta error, median / mean / worst (deg)", "screen error (NDC, median)", "roll, worst (deg)",
                        "orbits: right way (95 % interval), speed (median)"], "rows": rows}


def _ranges(summary: list[dict], retarget: list[dict]) -> dict:
    """Ranges the guide's prose quotes."""
    by = {line["behavior"]: line for line in summary}
    tracks = [b for b in by if b.endswith("track")]
    sizes = [r for r in retarget if r["shot"] != "all"]

    def span(lines, key):
        values = [line[key] for line in lines]
        return {"min": float(min(values)), "max": float(max(values))}

    return {"tracks_moe": span([by[b] for b in tracks], "moe_direction_deg"),
            "tracks_shared_bottom": span([by[b] for b in tracks], "shared_bottom_direction_deg"),
            "distance_median": span(sizes, "distance_ratio_median"),
            "distance_worst": span(sizes, "distance_ratio_worst"),
            "track_theta_median": span([r for r in sizes if r["behavior"] != "orbit"], "theta_deg_median"),
            "roll_worst": span(sizes, "roll_deg_worst")}

if __name__ == "__main__":
    raise SystemExit(main())
