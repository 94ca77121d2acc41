"""PyTorch side of the learned camera behaviors (seed 002, section 5): train, and run for comparison.

Runs in its own venv (torch==2.13.0, numpy, scikit-learn), without usdcrowd:
``tools/train_camera_moe.py`` makes the dataset with usdcrowd and calls

    python tools/camera_moe_torch.py train DATA.npz OUT_DIR [--epochs N] [--seed S]
    python tools/camera_moe_torch.py forward WEIGHTS.npz INPUTS.npz OUT.npz
    python tools/camera_moe_torch.py time CONFIG_JSON [--samples N]

``train`` writes OUT_DIR/camera_moe.npz (the weights usdcrowd ships, float32,
in the layout :class:`usdcrowd.cameras.moe.CameraMoE` reads), history.csv
(losses and the silhouette coefficient of the gating outputs on labelled
test clips, per epoch: Figure 10), errors.csv (per test sample, behavior,
MoE and shared-bottom errors: Figure 9) and gates.npz (the final gating
outputs). ``forward`` runs the gating and prediction networks of a weights
file on given inputs, for the test that numpy's inference equals PyTorch's.
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from pathlib import Path

import numpy as np
import torch
from torch import nn

N_CHAR, N_CAM = 10, 8          # features per frame (usdcrowd.cameras.moe); set from the data read
N_STYLE = 0                    # the gate's style features (usdcrowd.cameras.moe.style_features), if trained on
STYLE_FEATURES = 5             # how many there are (usdcrowd.cameras.moe.N_STYLE; this side runs without usdcrowd)


def _sizes(n_char: int, n_cam: int, n_style: int = 0) -> None:
    global N_CHAR, N_CAM, N_STYLE
    N_CHAR, N_CAM, N_STYLE = int(n_char), int(n_cam), int(n_style)


def absolute(pred: torch.Tensor, base: torch.Tensor, cfg: dict) -> torch.Tensor:
    """(b, out * n_cam) predicted features; a residual model's are changes from ``base`` (b, n_cam)."""
    return pred + base.repeat(1, cfg["out"]) if cfg.get("residual") else pred


class Gate(nn.Module):
    """LSTM over the reference features, its last state through FC and softmax."""

    def __init__(self, hidden: int, experts: int):
        super().__init__()
        self.lstm = nn.LSTM(N_CHAR + N_CAM + N_STYLE, hidden, batch_first=True)
        self.fc = nn.Linear(hidden, experts)

    def forward(self, x):
        return torch.softmax(self.logits(x), dim=-1)

    def logits(self, x):
        _, (h, _) = self.lstm(x)
        return self.fc(h[-1])


class Experts(nn.Module):
    """Three layers whose weights are the gated blend of ``experts`` sets (ELU between)."""

    def __init__(self, experts: int, n_in: int, hidden: int, n_out: int):
        super().__init__()
        sizes = [(n_in, hidden), (hidden, hidden), (hidden, n_out)]
        for k, (i, o) in enumerate(sizes, 1):
            w = torch.empty(experts, i, o)
            for e in range(experts):
                nn.init.kaiming_uniform_(w[e].T, a=np.sqrt(5))
            setattr(self, f"w{k}", nn.Parameter(w))
            setattr(self, f"b{k}", nn.Parameter(torch.zeros(experts, o)))

    def forward(self, x, weights):
        out = x
        for k in (1, 2, 3):
            per = torch.einsum("bi,mio->bmo", out, getattr(self, f"w{k}")) + getattr(self, f"b{k}")[None]
            out = torch.einsum("bm,bmo->bo", weights, per)
            if k < 3:
                out = nn.functional.elu(out)
        return out


class MoE(nn.Module):
    def __init__(self, cfg: dict):
        super().__init__()
        self.gate = Gate(cfg["gate_hidden"], cfg["experts"])
        # Config "expert_style": the experts also read the reference's style features (their means over the
        # gate's window), after the past camera and the characters.
        self.expert_style = bool(cfg.get("expert_style")) and N_STYLE > 0
        n_in = cfg["past"] * N_CAM + (cfg["char_past"] + cfg["char_future"]) * N_CHAR
        self.experts = Experts(cfg["experts"], n_in + (N_STYLE if self.expert_style else 0), cfg["hidden"],
                               cfg["out"] * N_CAM)
        if cfg.get("style") and cfg.get("n_style"):
            # Training only: the style labels read linearly from the gate's logits (config "style").
            self.style = nn.Linear(cfg["experts"], cfg["n_style"])

    def forward(self, gate_x, x):
        w = self.weights(gate_x)
        return self.step(x, w), w[..., :self.gate.fc.out_features]

    def weights(self, gate_x):
        """(b, m) expert weights, followed with config "expert_style" by the (b, 5) style the experts read."""
        return self.with_style(self.gate(gate_x), gate_x)

    def with_style(self, w, gate_x):
        return torch.cat([w, gate_x[:, :, -N_STYLE:].mean(1)], 1) if self.expert_style else w

    def step(self, x, w):
        m = self.gate.fc.out_features
        return self.experts(torch.cat([x, w[:, m:]], 1) if self.expert_style else x, w[:, :m])


class SharedBottom(nn.Module):
    """The paper's baseline: one shared layer, then a branch (Appendix A), no gating."""

    def __init__(self, cfg: dict):
        super().__init__()
        n_in = cfg["past"] * N_CAM + (cfg["char_past"] + cfg["char_future"]) * N_CHAR
        h = cfg["hidden"]
        self.net = nn.Sequential(nn.Linear(n_in, 2 * h), nn.ELU(), nn.Linear(2 * h, h), nn.ELU(),
                                 nn.Linear(h, cfg["out"] * N_CAM))

    def forward(self, gate_x, x):
        return self.net(x), None

    def weights(self, gate_x):
        return None

    def step(self, x, w):
        return self.net(x)


# ------------------------------------------------------------------------------------ samples
class Windows:
    """Samples cut from clips: prediction windows, and the gate's reference window (from the same clip, or
    with probability config "pair" from its paired reference: the same behavior filming another pair)."""

    def __init__(self, data, cfg: dict, stats: dict, rng, stride: int = 4):
        self.cfg, self.rng = cfg, rng
        self.char = (data["character"] - stats["char_mean"]) / stats["char_std"]      # (c, t, 9)
        self.cam = (data["camera"] - stats["cam_mean"]) / stats["cam_std"]            # (c, t, 6)
        self.cam_raw = data["camera"]
        # The same behavior filming other characters (see train_camera_moe.paired_references), if made.
        paired = "ref_character" in data
        self.ref_char = (data["ref_character"] - stats["char_mean"]) / stats["char_std"] if paired else None
        self.ref_cam = (data["ref_camera"] - stats["cam_mean"]) / stats["cam_std"] if paired else None
        self.labels = data["behavior"]
        # The gate's style features, after its character and camera features, of the clips and their references.
        self.gate_extra = self.ref_extra = None
        if "gate_style" in data:
            self.gate_extra = (data["gate_style"] - stats["style_mean"]) / stats["style_std"]
            self.ref_extra = (data["ref_gate_style"] - stats["style_mean"]) / stats["style_std"]
        # The same with the pair's motion unknown, as a film clip gives it (config "unseen_motion").
        self.gate_still = self.ref_still = None
        if "gate_style_still" in data:
            self.gate_still = (data["gate_style_still"] - stats["style_mean"]) / stats["style_std"]
            self.ref_still = (data["ref_gate_style_still"] - stats["style_mean"]) / stats["style_std"]
        self.style = data["style"] if "style" in data else None
        c, t, _ = self.char.shape
        lo = (cfg["past"] - 1) * cfg["step"]
        hi = t - 1 - cfg.get("unroll", 1) * cfg["out"] * cfg["step"]
        frames = np.arange(lo, hi, stride)
        self.index = np.array([(i, f) for i in range(c) for f in frames])

    def __len__(self):
        return len(self.index)

    def gate_inputs(self, clips, random=True):
        cfg = self.cfg
        t = self.char.shape[1]
        span = (cfg["gate_len"] - 1) * cfg["gate_step"]
        if random:
            start = self.rng.integers(0, t - span, len(clips))
        else:
            start = np.full(len(clips), (t - 1 - span) // 2)
        idx = start[:, None] + np.arange(cfg["gate_len"]) * cfg["gate_step"]
        extra = lambda a: [] if a is None else [a[clips[:, None], idx]]  # noqa: E731
        own = np.concatenate([self.char[clips[:, None], idx], self.cam[clips[:, None], idx], *extra(self.gate_extra)],
                             axis=-1)
        x, from_ref = own, np.zeros(len(clips), bool)
        if random and self.ref_char is not None and cfg.get("pair", 0.0):
            paired = np.concatenate([self.ref_char[clips[:, None], idx], self.ref_cam[clips[:, None], idx],
                                     *extra(self.ref_extra)], axis=-1)
            from_ref = self.rng.random(len(clips)) < cfg["pair"]
            x = np.where(from_ref[:, None, None], paired, own)
        if not random or self.gate_still is None or not cfg.get("unseen_motion"):
            return x
        # As a clip: the pair's velocity and turn at the training mean (0 once normalised), the style made from it.
        hide = self.rng.random(len(clips)) < cfg["unseen_motion"]
        still = np.where(from_ref[:, None, None], self.ref_still[clips[:, None], idx],
                         self.gate_still[clips[:, None], idx])
        x[hide, :, 7:N_CHAR] = 0.0
        x[hide, :, -N_STYLE:] = still[hide]
        return x

    def batch(self, rows, random_gate=True):
        """An evaluation batch: the true past camera (training's batches are :meth:`unrolled`)."""
        cfg = self.cfg
        clips, frames = self.index[rows, 0], self.index[rows, 1]
        t = self.char.shape[1]
        past_idx = frames[:, None] + np.arange(-(cfg["past"] - 1), 1) * cfg["step"]
        char_idx = np.clip(frames[:, None] + np.arange(-(cfg["char_past"] - 1), cfg["char_future"] + 1) * cfg["step"],
                           0, t - 1)
        past = self.cam[clips[:, None], past_idx]
        base = past[:, -1].copy()       # the last sample: a residual model predicts the change from it
        x = np.concatenate([past.reshape(len(rows), -1), self.char[clips[:, None], char_idx].reshape(len(rows), -1)], 1)
        out_idx = np.clip(frames[:, None] + np.arange(1, cfg["out"] + 1) * cfg["step"], 0, t - 1)
        y = self.cam[clips[:, None], out_idx].reshape(len(rows), -1)
        return (torch.tensor(self.gate_inputs(clips, random_gate), dtype=torch.float32),
                torch.tensor(x, dtype=torch.float32), torch.tensor(y, dtype=torch.float32),
                torch.tensor(base, dtype=torch.float32))


    def unrolled(self, rows, steps: int, noise: float):
        """A batch for ``steps`` predictions in a row: gate input, the first past (noised, sometimes
        hidden), and per step the character window and the truth; later steps' past is the model's own."""
        cfg = self.cfg
        clips, frames = self.index[rows, 0], self.index[rows, 1]
        t = self.char.shape[1]
        past_idx = frames[:, None] + np.arange(-(cfg["past"] - 1), 1) * cfg["step"]
        past = self.cam[clips[:, None], past_idx]
        # Some samples start from another clip's camera (config "reset"; tried, worse than blind samples,
        # off by default; its draw is kept so that the default recipe stays bit-reproducible).
        reset = np.flatnonzero(self.rng.random(len(rows)) < cfg.get("reset", 0.0))
        if len(reset):
            src = self.index[self.rng.integers(len(self.index), size=len(reset))]
            past[reset] = self.cam[src[:, :1], src[:, 1:] + np.arange(-(cfg["past"] - 1), 1) * cfg["step"]]
        past = past + self.rng.normal(0.0, noise, past.shape)
        # Some see no past camera at all (config "blind"): the framing must come from the gate and the
        # characters, as in a roll-out that starts blind (`usdcrowd frame --like`).
        past[self.rng.random(len(rows)) < cfg.get("blind", 0.0)] = 0.0
        chars, ys = [], []
        for r in range(steps):
            at = frames + r * cfg["out"] * cfg["step"]
            char_idx = np.clip(at[:, None] + np.arange(-(cfg["char_past"] - 1), cfg["char_future"] + 1) * cfg["step"],
                               0, t - 1)
            chars.append(self.char[clips[:, None], char_idx].reshape(len(rows), -1))
            out_idx = np.clip(at[:, None] + np.arange(1, cfg["out"] + 1) * cfg["step"], 0, t - 1)
            ys.append(self.cam[clips[:, None], out_idx].reshape(len(rows), -1))
        f32 = lambda a: torch.tensor(np.asarray(a), dtype=torch.float32)  # noqa: E731
        style = f32(self.style[clips]) if self.style is not None else None
        return (f32(self.gate_inputs(clips)), f32(past.reshape(len(rows), -1)), f32(chars), f32(ys),
                f32(past[:, -1]), style)


def _stats(data) -> dict:
    """Normalisation, and the range of camera features the training spans (a roll-out stays inside it)."""
    char, cam = data["character"].reshape(-1, N_CHAR), data["camera"].reshape(-1, N_CAM)
    stats = {"char_mean": char.mean(0), "char_std": char.std(0) + 1e-6, "cam_mean": cam.mean(0),
             "cam_std": cam.std(0) + 1e-6, "cam_lo": cam.min(0), "cam_hi": cam.max(0)}
    if "gate_style" in data:
        style = data["gate_style"].reshape(-1, N_STYLE)
        stats.update(style_mean=style.mean(0), style_std=style.std(0) + 1e-6)
    return stats


def sample_weights(cfg: dict) -> torch.Tensor:
    """(out,) loss weight of each predicted sample: the paper's Eq. 6 weighs the first 1 and the rest eta."""
    w = torch.full((cfg["out"],), float(cfg.get("eta", 1.0)))
    w[0] = 1.0
    return w / w.sum() * cfg["out"]


def _errors(model, windows: Windows, stats, batch=2048):
    """Per sample: mean absolute error of the predicted camera features, in their units."""
    model.eval()
    errs = []
    with torch.no_grad():
        for lo in range(0, len(windows), batch):
            rows = np.arange(lo, min(lo + batch, len(windows)))
            g, x, y, base = windows.batch(rows, random_gate=False)
            pred, _ = model(g, x)
            pred = absolute(pred, base, windows.cfg)
            p = pred.numpy().reshape(len(rows), -1, N_CAM) * stats["cam_std"] + stats["cam_mean"]
            t = y.numpy().reshape(len(rows), -1, N_CAM) * stats["cam_std"] + stats["cam_mean"]
            # and the angle between predicted and true directions from A to the camera, degrees
            u = slice(*windows.cfg.get("u", (3, 6)))
            cos = np.einsum("bsk,bsk->bs", p[..., u], t[..., u]) / np.maximum(
                np.linalg.norm(p[..., u], axis=-1) * np.linalg.norm(t[..., u], axis=-1), 1e-12)
            angle = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))).mean(axis=1)
            errs.append(np.column_stack([np.abs(p - t).mean(axis=1), angle]))
    model.train()
    return np.concatenate(errs)                        # (n, n_cam + 1): the features, then the direction's angle


def _gate_outputs(model, windows: Windows):
    clips = np.arange(windows.char.shape[0])
    with torch.no_grad():
        return model.gate(torch.tensor(windows.gate_inputs(clips, random=False), dtype=torch.float32)).numpy()


def window_weights(cfg: dict, style) -> torch.Tensor | None:
    """(b,) loss weight of each training window, or None for equal weights: config "long_orbit_weight"
    weighs the windows of long-shot orbits (the style labels' orbit and long columns) that much more."""
    extra = cfg.get("long_orbit_weight")
    if not extra or style is None:
        return None
    return 1.0 + (float(extra) - 1.0) * style[:, 3] * style[:, -1]


def train(data_path: str, out_dir: str, epochs: int, seed: int, batch: int = 256, lr: float = 2e-3,
          baseline: bool = True) -> None:
    from sklearn.metrics import silhouette_score

    torch.manual_seed(seed)
    torch.set_num_threads(max(1, torch.get_num_threads()))
    rng = np.random.default_rng(seed)
    data = np.load(data_path)
    cfg = json.loads(str(data["config"]))
    _sizes(data["character"].shape[-1], data["camera"].shape[-1],
           data["gate_style"].shape[-1] if "gate_style" in data.files else 0)
    split = data["test"]                                # 1 for test clips
    keys = [k for k in ("character", "camera", "behavior", "ref_character", "ref_camera", "style", "gate_style",
                        "ref_gate_style", "gate_style_still", "ref_gate_style_still") if k in data.files]
    if "style" in data.files:
        cfg["n_style"] = int(data["style"].shape[-1])
    train_d = {k: data[k][split == 0] for k in keys}
    test_d = {k: data[k][split == 1] for k in keys}
    train_d["config"] = test_d["config"] = data["config"]
    stats = _stats(train_d)
    tr, te = Windows(train_d, cfg, stats, rng), Windows(test_d, cfg, stats, np.random.default_rng(seed + 1), stride=8)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    history = []
    models = {"moe": MoE(cfg), "shared_bottom": SharedBottom(cfg)} if baseline else {"moe": MoE(cfg)}
    for name, model in models.items():
        # The gate's few weights steer all the experts; a larger step lets it leave the uniform mix.
        gate_params = list(model.gate.parameters()) if name == "moe" else []
        rest = [p for p in model.parameters() if all(p is not q for q in gate_params)]
        groups = [{"params": rest}]
        if gate_params:
            groups.append({"params": gate_params, "lr": lr * cfg.get("gate_lr", 1.0)})
        opt = torch.optim.Adam(groups, lr=lr)
        sched = torch.optim.lr_scheduler.ExponentialLR(opt, 0.95)
        per_sample = sample_weights(cfg)
        for epoch in range(1, epochs + 1):
            t0 = time.perf_counter()
            order = rng.permutation(len(tr))
            total = 0.0
            steps = cfg.get("unroll", 1)
            for lo in range(0, len(order), batch):
                # Trained on its own roll-outs: after the first step the past camera is the model's prediction.
                g, past, chars, ys, base, style = tr.unrolled(order[lo:lo + batch], steps, cfg.get("noise", 0.2))
                loss = 0.0
                if name == "moe" and cfg.get("style"):
                    logits = model.gate.logits(g)
                    w = model.with_style(torch.softmax(logits, dim=-1), g)
                    loss = cfg["style"] * torch.mean((model.style(logits) - style) ** 2)
                else:
                    w = model.weights(g)
                focus = window_weights(cfg, style)
                for r in range(steps):
                    pred = absolute(model.step(torch.cat([past, chars[r]], 1), w), base, cfg)
                    err = ((pred - ys[r]) ** 2).view(len(pred), cfg["out"], N_CAM)
                    sq = err.mean(dim=(0, 2)) if focus is None else (err.mean(2) * focus[:, None]).sum(0) / focus.sum()
                    loss = loss + torch.mean(sq * per_sample) / steps
                    samples = pred.view(len(pred), cfg["out"], N_CAM)
                    past = samples[:, -cfg["past"]:].reshape(len(pred), -1)
                    base = samples[:, -1]
                y = ys[0]
                opt.zero_grad()
                loss.backward()
                opt.step()
                total += float(loss.detach()) * len(y)
            sched.step()
            test_err = _errors(model, te, stats)[:, :N_CAM].mean(axis=0)
            row = {"model": name, "epoch": epoch, "train_loss": total / len(tr),
                   "test_error": float(test_err.mean()), "seconds": time.perf_counter() - t0}
            if name == "moe":
                gates = _gate_outputs(model, te)
                row["silhouette"] = float(silhouette_score(gates, te.labels)) if len(set(te.labels)) > 1 else 0.0
            history.append(row)
            print(json.dumps(row), flush=True)
    # Errors per test sample and behavior, both models.
    with open(out / "errors.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["model", "behavior", "clip", *[f"err_{k}" for k in range(N_CAM)], "err_direction_deg"])
        for name, model in models.items():
            errs = _errors(model, te, stats)
            for (clip, _), e in zip(te.index, errs):
                w.writerow([name, int(te.labels[clip]), int(clip), *[f"{v:.6g}" for v in e]])
    with open(out / "history.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["model", "epoch", "train_loss", "test_error", "silhouette", "seconds"])
        w.writeheader()
        w.writerows(history)
    moe = models["moe"]
    np.savez(out / "gates.npz", gates=_gate_outputs(moe, te), labels=te.labels)
    save_weights(moe, cfg, stats, out / "camera_moe.npz",
                 about={"epochs": epochs, "seed": seed, "train_clips": int((split == 0).sum()),
                        "test_clips": int((split == 1).sum()), "train_samples": len(tr), "torch": torch.__version__})


def save_weights(model: MoE, cfg: dict, stats: dict, path, about: dict) -> None:
    sd = {k: v.detach().numpy().astype(np.float32) for k, v in model.state_dict().items()}
    arrays = {k.replace("_l0", ""): v for k, v in sd.items()}
    arrays.update({k: np.asarray(v, dtype=np.float32) for k, v in stats.items()})
    np.savez(path, config=json.dumps(cfg), about=json.dumps(about), **arrays)


def load_weights(path) -> tuple[MoE, dict]:
    data = np.load(path)
    cfg = json.loads(str(data["config"]))
    _sizes(data["char_mean"].shape[-1], data["cam_mean"].shape[-1],
           data["style_mean"].shape[-1] if "style_mean" in data.files else 0)
    model = MoE(cfg)
    sd = {}
    for k in model.state_dict():
        sd[k] = torch.tensor(data[k.replace("_l0", "")])
    model.load_state_dict(sd)
    return model, cfg


def forward(weights: str, inputs: str, out: str) -> None:
    model, _ = load_weights(weights)
    model.eval()
    data = np.load(inputs)
    torch.set_default_dtype(torch.float64)
    model = model.double()
    with torch.no_grad():
        gate = model.weights(torch.tensor(data["gate_x"], dtype=torch.float64))
        pred = model.step(torch.tensor(data["x"], dtype=torch.float64), torch.tensor(data["w"], dtype=torch.float64))
    np.savez(out, gate=gate.numpy(), pred=pred.numpy())


def time_sizes(config: str, samples: int, batches: int = 3, batch: int = 256, seed: int = 0) -> dict:
    """Seconds one training batch takes (forward and backward, both networks as trained) for a config's
    sizes, on random inputs, and what an epoch of ``samples`` would take: the cost of a recipe, measured."""
    cfg = json.loads(config)
    _sizes(cfg.get("n_char", N_CHAR), cfg.get("n_cam", N_CAM), STYLE_FEATURES if cfg.get("gate_style") else 0)
    torch.manual_seed(seed)
    model = MoE(cfg)
    opt = torch.optim.Adam(model.parameters(), lr=1e-3)
    n_in = cfg["past"] * N_CAM + (cfg["char_past"] + cfg["char_future"]) * N_CHAR
    g = torch.randn(batch, cfg["gate_len"], N_CHAR + N_CAM + N_STYLE)
    x, y = torch.randn(batch, n_in), torch.randn(batch, cfg["out"] * N_CAM)
    times = []
    for k in range(batches + 1):
        t0 = time.perf_counter()
        pred, _ = model(g, x)
        loss = torch.mean((pred - y) ** 2)
        opt.zero_grad()
        loss.backward()
        opt.step()
        if k:                                   # the first warms up
            times.append(time.perf_counter() - t0)
    per_batch = float(np.median(times))
    out = {"config": cfg, "n_in": n_in, "batch": batch, "threads": torch.get_num_threads(),
           "seconds_per_batch": per_batch, "samples": samples,
           "seconds_per_epoch": per_batch * samples / batch,
           "parameters": int(sum(p.numel() for p in model.parameters()))}
    print(json.dumps(out), flush=True)
    return out


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    t = sub.add_parser("train")
    t.add_argument("data")
    t.add_argument("out")
    t.add_argument("--epochs", type=int, default=20)
    t.add_argument("--seed", type=int, default=0)
    t.add_argument("--moe-only", action="store_true", help="no shared-bottom baseline (sweeps that do not compare)")
    f = sub.add_parser("forward")
    f.add_argument("weights")
    f.add_argument("inputs")
    f.add_argument("out")
    c = sub.add_parser("time")
    c.add_argument("config", help="the sizes, as JSON (the keys of the training config)")
    c.add_argument("--samples", type=int, default=185_600, help="training samples per epoch")
    c.add_argument("--batches", type=int, default=3)
    a = p.parse_args()
    if a.cmd == "train":
        train(a.data, a.out, a.epochs, a.seed, baseline=not a.moe_only)
    elif a.cmd == "time":
        time_sizes(a.config, a.samples, a.batches)
    else:
        forward(a.weights, a.inputs, a.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
