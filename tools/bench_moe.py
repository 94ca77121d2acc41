"""Prediction rate of the learned camera behaviors in numpy (seed 002 reports above 200 Hz; target 2,000/s).

One prediction is one pass of the prediction network (``out`` camera samples
from the past camera and the characters around the present), with the
experts already blended for the reference clip, as a roll-out runs it. Also
timed: the gating network on one reference (once per clip) and a whole
roll-out of 20 s at 24 fps.
"""

from __future__ import annotations

import time

import numpy as np

TARGET_PER_S = 2000.0


def _rate(fn, min_seconds: float = 1.0) -> tuple[float, int]:
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < min_seconds:
        fn()
        n += 1
    return n / (time.perf_counter() - t0), n


def run() -> dict:
    """Print and return the learned cameras' rates and the weights' size."""
    from usdcrowd.cameras.moe import CameraMoE
    from usdcrowd.cameras.moe_data import make_clip

    model = CameraMoE()
    c = model.config
    rng = np.random.default_rng(0)
    clip = make_clip(rng, 3, frames=480)
    print(f"weights: {model.path} ({model.size_bytes / 1e6:.2f} MB of float32; {c.experts} experts, hidden "
          f"{c.hidden}, input {c.n_in}, {c.out} samples out)")
    w = model.gate(clip.character, clip.camera)
    layers = model.blend(w)
    x = rng.normal(size=(1, c.n_in))
    single, _ = _rate(lambda: model.predict(layers, x))
    batch = rng.normal(size=(256, c.n_in))
    batched, _ = _rate(lambda: model.predict(layers, batch))
    gate, _ = _rate(lambda: model.gate(clip.character, clip.camera))
    roll, _ = _rate(lambda: model.rollout(w, clip.character, clip.camera[0]))
    print(f"prediction, one at a time: {single:,.0f}/s ({single / TARGET_PER_S:.1f}x the {TARGET_PER_S:,.0f}/s "
          f"target; the paper: above 200 Hz)")
    print(f"prediction, batches of 256: {batched * 256:,.0f}/s")
    print(f"gating network on one reference: {1e3 / gate:.1f} ms; roll-out of 480 frames: {1e3 / roll:.1f} ms "
          f"({480 * roll:,.0f} frames/s)")
    return {"weights_mb": model.size_bytes / 1e6, "predictions_per_s": single, "batched_per_s": batched * 256,
            "gate_ms": 1e3 / gate, "rollout_ms": 1e3 / roll, "target_per_s": TARGET_PER_S}
