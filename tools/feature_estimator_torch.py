"""PyTorch side of the cinematic feature estimator (seed 002, section 4, appendix A): train, and run.

Runs in its own venv (torch==2.13.0, numpy), without usdcrowd:
``tools/train_feature_estimator.py`` makes the data with usdcrowd and calls

    python tools/feature_estimator_torch.py train DATA.npz OUT.npz [--epochs N] [--seed S]
    python tools/feature_estimator_torch.py forward WEIGHTS.npz INPUTS.npz OUT.npz

``train`` writes the weights usdcrowd ships (float32, the layout
:class:`usdcrowd.cameras.estimator.FeatureEstimator` reads) and prints the
loss per epoch; ``forward`` runs a weights file on given windows, for the
test that numpy's inference equals PyTorch's.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import torch
from torch import nn


class Estimator(nn.Module):
    """Appendix A: Conv1d + BN + ReLU + max-pool twice over the 8-frame window, then FC + ReLU and FC."""

    def __init__(self, n_in: int = 32, n_out: int = 11, window: int = 8):
        super().__init__()
        self.conv1, self.bn1 = nn.Conv1d(n_in, 64, 3, padding=1), nn.BatchNorm1d(64)
        self.conv2, self.bn2 = nn.Conv1d(64, 128, 3, padding=1), nn.BatchNorm1d(128)
        self.fc1, self.fc2 = nn.Linear(128 * (window // 4), 128), nn.Linear(128, n_out)

    def forward(self, x):
        x = nn.functional.max_pool1d(torch.relu(self.bn1(self.conv1(x))), 2)
        x = nn.functional.max_pool1d(torch.relu(self.bn2(self.conv2(x))), 2)
        return self.fc2(torch.relu(self.fc1(x.flatten(1))))


def train(data_path: str, out: str, epochs: int, seed: int, batch: int = 256, lr: float = 1e-3) -> None:
    torch.manual_seed(seed)
    torch.set_num_threads(2)
    rng = np.random.default_rng(seed)
    data = np.load(data_path)
    x, y, test = data["x"], data["y"], data["test"].astype(bool)
    in_std = x[~test].std(axis=(0, 2)) + 1e-6
    out_mean, out_std = y[~test].mean(axis=0), y[~test].std(axis=0) + 1e-6
    xn = torch.tensor(x / in_std[None, :, None], dtype=torch.float32)
    yn = torch.tensor((y - out_mean) / out_std, dtype=torch.float32)
    train_rows, test_rows = np.flatnonzero(~test), np.flatnonzero(test)
    model = Estimator(x.shape[1], y.shape[1], x.shape[2])
    opt = torch.optim.Adam(model.parameters(), lr=lr)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, epochs)
    for epoch in range(epochs):
        model.train()
        t0, total = time.time(), 0.0
        order = rng.permutation(train_rows)
        for k in range(0, len(order), batch):
            rows = torch.as_tensor(order[k:k + batch])
            # The paper's loss: the Euclidean norm of the error, per sample.
            loss = torch.linalg.vector_norm(model(xn[rows]) - yn[rows], dim=1).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += loss.item() * len(rows)
        sched.step()
        model.eval()
        with torch.no_grad():
            test_loss = float(torch.linalg.vector_norm(model(xn[test_rows]) - yn[test_rows], dim=1).mean())
        print(f"epoch {epoch + 1}/{epochs}: train {total / len(order):.4f}  test {test_loss:.4f}  "
              f"({time.time() - t0:.0f} s)", flush=True)
    arrays = {k: v.detach().numpy().astype(np.float32) for k, v in model.state_dict().items()
              if not k.endswith("num_batches_tracked")}
    about = {"epochs": epochs, "seed": seed, "samples": int(len(train_rows)), "test_loss": test_loss,
             "torch": torch.__version__}
    np.savez(out, **arrays, in_std=in_std.astype(np.float32), out_mean=out_mean.astype(np.float32),
             out_std=out_std.astype(np.float32), about=json.dumps(about))


def forward(weights: str, inputs: str, out: str) -> None:
    w = np.load(weights)
    x = np.load(inputs)["x"]
    model = Estimator(x.shape[1], w["fc2.bias"].shape[0], x.shape[2])
    model.load_state_dict({k: torch.tensor(w[k]) for k in model.state_dict() if k in w.files}, strict=False)
    model.eval()
    with torch.no_grad():
        y = model(torch.tensor(x / w["in_std"][None, :, None], dtype=torch.float32)).numpy()
    np.savez(out, y=y * w["out_std"] + w["out_mean"])


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    t = sub.add_parser("train")
    t.add_argument("data")
    t.add_argument("out")
    t.add_argument("--epochs", type=int, default=30)
    t.add_argument("--seed", type=int, default=0)
    f = sub.add_parser("forward")
    f.add_argument("weights")
    f.add_argument("inputs")
    f.add_argument("out")
    a = p.parse_args()
    if a.cmd == "train":
        train(a.data, a.out, a.epochs, a.seed)
    else:
        forward(a.weights, a.inputs, a.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
