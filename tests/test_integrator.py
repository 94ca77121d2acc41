"""The beauty's path tracer (a shadow ray to every light) converges to what Mitsuba's own does, with less noise."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("mitsuba")

from usdcrowd.render.final import integrator  # noqa: E402
from usdcrowd.render.final.frame import FrameRenderer  # noqa: E402

W, H = 128, 72
FRAME = 6
SPP = 256


def relative_mse(x, ref):
    return float(np.mean((x - ref) ** 2 / (ref ** 2 + 1e-2)))


def _frames(shot, mitsuba_path: bool, monkeypatch, seeds) -> list[np.ndarray]:
    monkeypatch.setattr(integrator, "MAX_LIGHTS", -1 if mitsuba_path else 4)
    out = []
    for seed in seeds:
        r = FrameRenderer(shot, None, (W, H), spp=SPP, max_depth=4, ground_truth=False, sampler="independent",
                          seed=seed)
        assert (type(r.built.scene.integrator()).__name__ == "AllLightsPath") != mitsuba_path
        out.append(r.render(FRAME).beauty.astype(np.float64))
    return out


def test_every_light_path_tracer_converges_to_mitsubas_with_less_noise(walking_museum, monkeypatch):
    """The museum's sun, sky and lamp, two independent frames from each tracer.

    A frame's noise is half the relative MSE between two frames of other
    seeds. Unbiased, the two tracers' mean frames differ by their noise only;
    ours has at most half the noise of Mitsuba's at the same samples.
    """
    o1, o2 = _frames(walking_museum, False, monkeypatch, (1, 2))
    t1, t2 = _frames(walking_museum, True, monkeypatch, (3, 4))
    noise_ours, noise_theirs = relative_mse(o1, o2) / 2, relative_mse(t1, t2) / 2
    ours, theirs = (o1 + o2) / 2, (t1 + t2) / 2
    expected = (noise_ours + noise_theirs) / 2          # each mean frame has half its frames' noise
    assert relative_mse(ours, theirs) < 1.5 * expected, (relative_mse(ours, theirs), expected)
    assert ours.mean() == pytest.approx(theirs.mean(), rel=2e-3)
    assert noise_ours * 2 < noise_theirs, (noise_ours, noise_theirs)
