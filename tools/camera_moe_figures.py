"""Seed 002's Figures 10 and 11 for the shipped stage model, and the base recipe's experts swept (section 6).

    python tools/camera_moe_figures.py [gates] [generality] [experts] [recipes] [--record] [--epochs 10]

gates
    the gating network's outputs on the held-out clips (the evaluation's
    test seed), their silhouette coefficient by behavior and a 2D t-SNE
    embedding coloured by behavior (scikit-learn, in the PyTorch venv):
    Fig. 10, right.
generality
    retargeting on held-out clips changed as the paper changes them
    (Fig. 11): the distance between the two characters, the speed of the
    animation, and one character's height against the other's. Each
    changed clip is filmed by the controller with another clip's drawn
    parameters and by the shipped stage model gated from that clip, blind, as
    `frame --like` runs; the figure is the tracks' median theta error and
    the median distance ratio (and the share of orbits turning the right
    way, in the data).
recipes
    the base recipe (the film clips' model) against the paper's (its past window and Eq. 6
    loss over the same time spans), trained alike, on the same held-out
    clips.
main
    how often appendix B's main character M (the larger on screen over
    the clip) is the controller's A, the character its behavior is built
    round, on the held-out clips: why M orders the targets of a clip
    reference but is no input of the network.
experts
    the model trained with 4, 6, 9 and 12 experts (fewer epochs than the
    shipped models', the same seed and data otherwise), each evaluated on
    the held-out clips: one-prediction error and retargeting (Fig. 10,
    left: the paper sweeps the number of experts the same way).

Figures go to docs/images/, numbers to docs/data/camera_moe_figures.json
with --record.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tools"))

from train_camera_moe import STAGE_RECIPE  # noqa: E402  (the stage model's recipe, one of the recipes compared)

IMAGES = ROOT / "docs" / "images"
DISTANCES = (0.5, 1.0, 2.0, 3.0, 5.0, 7.0)           # metres between the characters
SPEEDS = (0.5, 1.0, 1.5, 2.0, 3.0)                   # animation played this many times as fast
SCALES = (0.6, 0.8, 1.0, 1.25, 1.5, 2.0)             # B's height over its own
EXPERTS = (4, 6, 9, 12)
# The experts sweep and the recipes, 25-epoch comparisons of each other, are scored on 100 held-out
# references per behavior (the shipped model's own table on train_camera_moe's 400).
SWEEP_RETARGET_CLIPS = 100


def _clips(per_behavior: int):
    from usdcrowd.cameras.moe_data import held_out_clips

    return held_out_clips(per_behavior)              # the evaluation's (train_camera_moe)


# ------------------------------------------------------------------------------------- Fig. 10
def gates(record: dict) -> str:
    """Gate outputs of held-out clips: silhouette by behavior and a t-SNE plot (PyTorch venv's scikit-learn)."""
    from train_camera_moe import torch_python

    from usdcrowd.cameras.behaviors import BEHAVIORS
    from usdcrowd.cameras.moe import CameraMoE

    model = CameraMoE()
    clips = _clips(50)
    w = np.array([model.mix_and_style(model.gate(c.character, c.camera))[0] for c in clips])   # the expert mix
    labels = np.array([c.behavior for c in clips])
    with tempfile.TemporaryDirectory() as tmp:
        np.savez(Path(tmp) / "gates.npz", gates=w, labels=labels)
        code = ("import numpy as np, json, sys; from sklearn.manifold import TSNE; "
                "from sklearn.metrics import silhouette_score; d = np.load(sys.argv[1]); "
                "e = TSNE(2, perplexity=30, random_state=0, init='pca').fit_transform(d['gates']); "
                "np.save(sys.argv[2], e); "
                "print(json.dumps({'silhouette': float(silhouette_score(d['gates'], d['labels'])), "
                "'silhouette_tsne': float(silhouette_score(e, d['labels']))}))")
        r = subprocess.run([torch_python(), "-c", code, str(Path(tmp) / "gates.npz"), str(Path(tmp) / "tsne.npy")],
                           check=True, capture_output=True, text=True)
        scores = json.loads(r.stdout.strip().splitlines()[-1])
        emb = np.load(Path(tmp) / "tsne.npy")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4.5))
    for b, name in enumerate(BEHAVIORS):
        sel = labels == b
        ax.scatter(emb[sel, 0], emb[sel, 1], s=10, label=name)
    ax.legend(fontsize=8)
    ax.set_title(f"Gate outputs of {len(clips)} held-out clips, t-SNE (cf. Fig. 10)\n"
                 f"silhouette by behavior {scores['silhouette']:.2f}", fontsize=9)
    ax.set_xticks([])
    ax.set_yticks([])
    path = IMAGES / "camera_moe_gates_tsne.png"
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    record["gates"] = {**scores, "clips": len(clips), "experts": model.config.experts}
    print(f"gates: silhouette {scores['silhouette']:.3f} ({len(clips)} clips); {path}")
    return str(path.relative_to(ROOT))


# ------------------------------------------------------------------------------------- Fig. 11
def _changed(clip, what: str, value: float):
    """(heads_a, heads_b, yaw_a, yaw_b) of a clip with one control variable changed (Fig. 11)."""

    ha, hb, ya, yb = clip.heads_a.copy(), clip.heads_b.copy(), clip.yaw_a.copy(), clip.yaw_b.copy()
    if what == "distance":
        ab = hb[:, :2] - ha[:, :2]
        hb[:, :2] = ha[:, :2] + ab * (value / np.maximum(np.linalg.norm(ab, axis=1, keepdims=True), 1e-9))
    elif what == "speed":
        t = np.arange(0, len(ha) - 1, value)
        idx = np.arange(len(ha))
        lerp = lambda v: np.column_stack([np.interp(t, idx, v[:, k]) for k in range(v.shape[1])])  # noqa: E731
        ha, hb = lerp(ha), lerp(hb)
        ya, yb = (np.interp(t, idx, np.unwrap(y)) for y in (ya, yb))
    else:                                             # relative scale: B's head height
        hb[:, 2] *= value
    return ha, hb, ya, yb


def generality(record: dict) -> str:
    from usdcrowd.cameras.behaviors import behavior_track
    from usdcrowd.cameras.moe import CameraMoE, character_features
    from usdcrowd.cameras.moe_data import ASPECT, FOV_X, FPS
    from usdcrowd.cameras.retarget import compare, retarget_poses

    model = CameraMoE()
    clips = _clips(12)
    out = {}
    for what, values in (("distance", DISTANCES), ("speed", SPEEDS), ("scale", SCALES)):
        rows = []
        for value in values:
            theta, ratio, same_way = [], [], []
            for k, ref in enumerate(clips):
                target = next(c for c in clips[k + 1:] + clips[:k] if c.motion != ref.motion)
                ha, hb, ya, yb = _changed(target, what, value)
                if len(ha) < 120:
                    continue
                char = character_features(ha, hb, ya, yb, FPS)
                poses, _ = retarget_poses(model, model.gate(ref.character, ref.camera), char, ha, hb, FOV_X, ASPECT)
                truth = behavior_track(ref.params, np.arange(1, len(ha) + 1.0), FPS, ha, hb, ya, yb, FOV_X,
                                       ASPECT).cam_to_world
                d = compare(poses, truth, ha, hb, FOV_X, ASPECT)
                if ref.params.name == "orbit":      # an orbit's theta is its phase: which way it turns counts
                    same_way.append(np.sign(d["turn_deg"]) == np.sign(d["truth_turn_deg"]))
                else:
                    theta.append(float(np.median(d["theta_deg"])))
                ratio.append(float(np.median(d["distance_ratio"])))
            worst = ratio[int(np.argmax(np.abs(np.log(ratio))))]
            rows.append({"value": value, "theta_deg_median": float(np.median(theta)),
                         "distance_ratio_median": float(np.median(ratio)), "distance_ratio_worst_clip": float(worst),
                         "orbit_same_way": float(np.mean(same_way))})
            print(f"{what:8} {value:5.2f}: tracks' theta {rows[-1]['theta_deg_median']:5.1f} deg, distance "
                  f"x{rows[-1]['distance_ratio_median']:.2f} (worst clip x{worst:.2f}), orbits the right way "
                  f"{rows[-1]['orbit_same_way']:.0%}", flush=True)
        out[what] = rows
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6))
    labels = {"distance": "distance between the characters (m)", "speed": "animation speed (x)",
              "scale": "B's height relative to its own (x)"}
    for ax, (what, rows) in zip(axes, out.items()):
        v = [r["value"] for r in rows]
        ax.plot(v, [r["theta_deg_median"] for r in rows], "o-", label="theta error (deg)")
        ax.set_xlabel(labels[what])
        ax.set_ylabel("tracks: median theta error (deg)")
        twin = ax.twinx()
        twin.plot(v, [r["distance_ratio_median"] for r in rows], "s--", color="#dd8452", label="distance ratio")
        twin.set_ylabel("median distance ratio", color="#dd8452")
        twin.set_ylim(0, 2)
    axes[0].set_title("Generality (cf. Fig. 11): retargeting on changed held-out clips", fontsize=9, loc="left")
    fig.tight_layout()
    path = IMAGES / "camera_moe_generality.png"
    fig.savefig(path, dpi=110)
    record["generality"] = {"clips": len(clips), **out}
    print(f"generality: {path}")
    return str(path.relative_to(ROOT))


# ------------------------------------------------------------------------------- experts swept
def experts(record: dict, epochs: int) -> str:
    """The model trained with 4 to 12 experts, each evaluated on the held-out clips as train_camera_moe does."""
    import csv

    rows = []
    for m in EXPERTS:
        out = ROOT / "build" / f"camera_moe_experts_{m}"
        t0 = time.perf_counter()
        subprocess.run([sys.executable, str(ROOT / "tools" / "train_camera_moe.py"), "--out", str(out),
                        "--epochs", str(epochs), "--config", json.dumps({"experts": m}), "--moe-only",
                        "--retarget-clips", str(SWEEP_RETARGET_CLIPS)], check=True,
                       stdout=subprocess.DEVNULL)
        ret = {r["behavior"]: r for r in csv.DictReader(open(out / "retarget_summary.csv")) if r["shot"] == "all"}
        pred = list(csv.DictReader(open(out / "summary.csv")))
        hist = [r for r in csv.DictReader(open(out / "history.csv")) if r["model"] == "moe"]
        rows.append({"experts": m, "minutes": (time.perf_counter() - t0) / 60,   # shared machine: not quoted
                     "test_error": float(hist[-1]["test_error"]), "silhouette": float(hist[-1]["silhouette"]),
                     "direction_deg": float(np.mean([float(p["moe_direction_deg"]) for p in pred])),
                     "track_theta_deg": float(np.median([float(ret[b]["theta_deg_median"]) for b in ret
                                                         if b != "orbit"])),
                     "distance_ratio_worst": max(float(r["distance_ratio_worst"]) for r in ret.values()),
                     "orbit_same_way": float(ret["orbit"]["orbit_same_way"]),
                     "orbit_speed": float(ret["orbit"]["orbit_speed_median"])})
        print(json.dumps(rows[-1]), flush=True)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(10, 3.6))
    m = [r["experts"] for r in rows]
    ax[0].plot(m, [r["test_error"] for r in rows], "o-")
    ax[0].set_xlabel("experts")
    ax[0].set_ylabel("test error (normalised features)")
    ax[0].set_title(f"Experts swept, {epochs} epochs each (cf. Fig. 10, left)", fontsize=9)
    ax[1].plot(m, [r["track_theta_deg"] for r in rows], "o-", label="tracks: median theta error (deg)")
    ax[1].plot(m, [100 * r["orbit_same_way"] for r in rows], "s-", label="orbits the right way (%)")
    ax[1].set_xlabel("experts")
    ax[1].legend(fontsize=8)
    fig.tight_layout()
    path = IMAGES / "camera_moe_experts.png"
    fig.savefig(path, dpi=110)
    record["experts"] = {"epochs": epochs, "rows": rows}
    return str(path.relative_to(ROOT))


# The paper's recipe over the same time spans at 24 fps: 1 s of past camera (12 samples) and its Eq. 6 loss.
PAPER_RECIPE = {"past": 12, "eta": 0.1}
# The base recipe with a gate that also reads the style features and learns the controllers' parameters.
STYLE_GATE = {"gate_style": True, "style": 0.3}
# ... and experts that read the style features too (their means over the gate's window).
EXPERTS_STYLE = {**STYLE_GATE, "expert_style": True}


RECIPE_NAMES = ("shipped", "paper_recipe", "style_gate", "experts_style", "stage")


def recipes(record: dict) -> None:
    """The base recipe (recorded as "shipped": the film clips' model), the paper's (its windows and Eq. 6),
    one whose gate reads the style features and one whose experts read them too, trained alike, 25 epochs
    each, and scored on the same held-out clips, SWEEP_RETARGET_CLIPS per behavior
    (train_camera_moe's evaluation, from build/camera_moe_recipe_ours, build/camera_moe_paper_recipe,
    build/camera_moe_style_gate and build/camera_moe_experts_style, each trained first unless it is there)."""
    import csv

    out = {}
    for name, folder, config in (("shipped", ROOT / "build" / "camera_moe_recipe_ours", {}),
                                 ("paper_recipe", ROOT / "build" / "camera_moe_paper_recipe", PAPER_RECIPE),
                                 ("style_gate", ROOT / "build" / "camera_moe_style_gate", STYLE_GATE),
                                 ("experts_style", ROOT / "build" / "camera_moe_experts_style", EXPERTS_STYLE),
                                 ("stage", ROOT / "build" / "camera_moe_stage_recipe", STAGE_RECIPE)):
        if not (folder / "retarget_summary.csv").exists():
            subprocess.run([sys.executable, str(ROOT / "tools" / "train_camera_moe.py"), "--out", str(folder),
                            "--epochs", "25", "--config", json.dumps(config), "--moe-only",
                            "--retarget-clips", str(SWEEP_RETARGET_CLIPS)], check=True,
                           stdout=subprocess.DEVNULL)
        ret = {r["behavior"]: r for r in csv.DictReader(open(folder / "retarget_summary.csv")) if r["shot"] == "all"}
        pred = {r["behavior"]: r for r in csv.DictReader(open(folder / "summary.csv"))}
        hist = [r for r in csv.DictReader(open(folder / "history.csv")) if r["model"] == "moe"]
        out[name] = {"config": config, "test_error": float(hist[-1]["test_error"]),
                     **{b.replace("-", "_"): {"direction_deg": float(pred[b]["moe_direction_deg"]),
                                              "theta_deg_median": float(ret[b]["theta_deg_median"]),
                                              "distance_ratio_median": float(ret[b]["distance_ratio_median"]),
                                              "distance_ratio_worst": float(ret[b]["distance_ratio_worst"]),
                                              **({"orbit_same_way": float(ret[b]["orbit_same_way"]),
                                                  "orbit_speed": float(ret[b]["orbit_speed_median"])}
                                                 if b == "orbit" else {})}
                        for b in ret}}
        print(name, json.dumps(out[name]), flush=True)
    record["recipes"] = out


def main_character(record: dict) -> None:
    """Share of held-out clips whose larger character on screen (appendix B's M: the mean box, here the
    inverse square of the camera's distance to each head, as a box scales) is B, per behavior."""
    from usdcrowd.cameras.behaviors import BEHAVIORS
    from usdcrowd.cameras.moe_data import refilm_track

    clips = _clips(50)
    out = {}
    for b, name in enumerate(BEHAVIORS):
        is_b = []
        for clip in (c for c in clips if c.behavior == b):
            eye = refilm_track(clip, clip.params).cam_to_world[:, 3, :3]
            near_a, near_b = (np.mean(np.linalg.norm(eye - h, axis=1) ** -2) for h in (clip.heads_a, clip.heads_b))
            is_b.append(near_b > near_a)
        out[name.replace("-", "_")] = {"clips": len(is_b), "m_is_b": float(np.mean(is_b))}
    out["all"] = {"clips": sum(v["clips"] for v in out.values()),
                  "m_is_b": float(np.mean([v["m_is_b"] for v in out.values()]))}
    record["main_character"] = out
    print("main character M is B in " + ", ".join(f"{k} {v['m_is_b']:.0%}" for k, v in out.items()))


def tables(figures: dict) -> dict:
    """The guide's tables: the experts swept, and generality per control variable."""
    out = {}
    if "experts" in figures:
        out["experts"] = {"columns": ["experts", "test error", "silhouette", "one prediction, direction (deg)",
                                      "tracks' theta error, median (deg)", "worst distance ratio",
                                      "orbits the right way", "orbit speed (median)"],
                          "rows": [[str(r["experts"]), f"{r['test_error']:.4f}", f"{r['silhouette']:.3f}",
                                    f"{r['direction_deg']:.1f}", f"{r['track_theta_deg']:.1f}",
                                    f"{r['distance_ratio_worst']:.2f}", f"{r['orbit_same_way']:.0%}",
                                    f"{r['orbit_speed']:.2f}x"]
                                   for r in figures["experts"]["rows"]]}
    if "recipes" in figures:
        names = [n for n in RECIPE_NAMES if n in figures["recipes"]]
        rows = []
        for b in ("direct_track", "relative_track", "side_track", "orbit"):
            line = [b.replace("_", " ")]
            for name in names:
                r = figures["recipes"][name][b]
                extra = (f", {r['orbit_same_way']:.0%} the right way at {r['orbit_speed']:.2f}x"
                         if "orbit_same_way" in r else "")
                line.append(f"{r['direction_deg']:.1f} / {r['theta_deg_median']:.1f} / "
                            f"{r['distance_ratio_median']:.2f}{extra}")
            rows.append(line)
        headers = {"shipped": "base recipe (the film clips' model): one prediction (deg) / retargeted theta (deg, "
                              "median) / distance ratio",
                   "paper_recipe": "the paper's windows and Eq. 6: the same",
                   "style_gate": "a gate reading the style features: the same",
                   "experts_style": "experts reading them too: the same",
                   "stage": "the stage recipe (a quarter of the gate's windows read as a clip): the same"}
        out["recipes"] = {"columns": ["behavior", *(headers[n] for n in names)], "rows": rows}
    if "generality" in figures:
        names = {"distance": "distance between them (m)", "speed": "animation speed (x)",
                 "scale": "B's height (x its own)"}
        out["generality"] = {"columns": ["changed", "value", "tracks' theta error, median (deg)",
                                         "distance ratio, median", "worst clip's distance ratio",
                                         "orbits the right way"],
                             "rows": [[names[what], f"{r['value']:g}", f"{r['theta_deg_median']:.1f}",
                                       f"{r['distance_ratio_median']:.2f}", f"{r['distance_ratio_worst_clip']:.2f}",
                                       f"{r['orbit_same_way']:.0%}"]
                                      for what in ("distance", "speed", "scale")
                                      for r in figures["generality"][what]]}
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("parts", nargs="*", help="gates, generality, main, experts, recipes (default: all five)")
    p.add_argument("--epochs", type=int, default=10, help="epochs per model of the experts sweep")
    p.add_argument("--record", action="store_true", help="record to docs/data/camera_moe_figures.json")
    a = p.parse_args(argv)
    parts = a.parts or ["gates", "generality", "main", "experts", "recipes"]
    unknown = set(parts) - {"gates", "generality", "main", "experts", "recipes"}
    if unknown:
        p.error(f"unknown parts: {', '.join(sorted(unknown))}")
    data_path = ROOT / "docs" / "data" / "camera_moe_figures.json"
    figures = json.loads(data_path.read_text())["figures"] if data_path.exists() else {}
    images = []
    from docfigures import commit, machine

    for part in parts:
        if part in ("recipes", "main"):
            {"recipes": recipes, "main": main_character}[part](figures)
        else:
            images.append({"gates": lambda: gates(figures), "generality": lambda: generality(figures),
                           "experts": lambda: experts(figures, a.epochs)}[part]())
        # Parts are run apart (the sweeps take an hour): each says when, where and from what it was measured.
        figures[{"main": "main_character"}.get(part, part)]["measured"] = {
            "date": time.strftime("%Y-%m-%d", time.gmtime()), "commit": commit(), "machine": machine()}
    if a.record:
        from docfigures import record

        record("camera_moe_figures", "tools/camera_moe_figures.py", figures=figures, tables=tables(figures),
               images=sorted({*images, *(f"docs/images/camera_moe_{n}.png" for n in ("gates_tsne", "generality",
                                                                                        "experts")
                                         if (IMAGES / f"camera_moe_{n}.png").exists())}),
               command="python tools/camera_moe_figures.py --record")
    return 0


if __name__ == "__main__":
    sys.exit(main())
