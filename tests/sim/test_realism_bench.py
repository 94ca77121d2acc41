"""The yardsticks of `tools/bench.py realism`: the reference curve, the flow, the scenes' starts, the overspeed."""

from __future__ import annotations

import numpy as np
import pytest

from tests.helpers.tools import load_tool


@pytest.fixture(scope="module")
def realism():
    return load_tool("bench_realism")


def test_weidmanns_curve_has_its_published_free_speed_and_jam_density(realism):
    """1.34 m/s nearly free, about 1.06 at one person per square metre, none at the jam density 5.4."""
    assert realism.weidmann(0.05) == pytest.approx(1.34, abs=1e-3)
    assert realism.weidmann(1.0) == pytest.approx(1.06, abs=0.01)
    assert realism.weidmann(5.4) == pytest.approx(0.0, abs=1e-9)
    v = realism.weidmann(np.linspace(0.2, 5.4, 50))
    assert (np.diff(v) < 0).all()


def test_specific_flow_counts_the_steady_passages_per_metre(realism):
    """Two people a second through a 1.25 m line, after a slow start and before a slow end: 1.6 per m per s."""
    fps = realism.FPS
    steady = np.arange(0, 40 * fps, fps / 2)                   # every half second
    crossings = np.concatenate([[0.0, 30.0], steady + 60.0, steady[-1] + 60.0 + [200.0, 400.0]])
    assert realism.specific_flow(crossings, 1.25) == pytest.approx(2.0 / 1.25, rel=0.05)


def test_starts_never_overlap_and_too_many_are_refused(realism):
    rng = np.random.default_rng(0)
    xy = realism._fill(rng, 320, 1.0, 30.0, 0.3, 3.7)
    d = np.linalg.norm(xy[:, None] - xy[None], axis=-1) + np.eye(len(xy)) * 9
    assert d.min() >= 2.1 * 0.25 - 1e-9 and len(xy) == 320
    assert (xy[:, 0] > 1.0).all() and (xy[:, 0] < 30.0).all() and (xy[:, 1] > 0.3).all() and (xy[:, 1] < 3.7).all()
    with pytest.raises(ValueError, match="do not fit"):
        realism._fill(rng, 1000, 0.0, 10.0, 0.0, 4.0)


def test_overspeed_is_one_at_the_free_speed_and_sees_a_jump(realism):
    fps = realism.FPS
    t = np.arange(64) / fps
    speed = np.array([1.0, 1.5])
    xy = np.stack([np.column_stack([t * s, np.zeros_like(t)]) for s in speed], axis=1)
    assert realism.overspeed(xy, speed) == pytest.approx(1.0)
    xy[40:, 0, 0] += 3.0                                        # a 3 m jump in one frame
    assert realism.overspeed(xy, speed) > 3.0


def test_residuals_by_density_are_the_mean_distance_to_weidmann_in_each_bin(realism):
    """A crowd 0.1 m/s faster than Weidmann at 0.5-1 per square metre and 0.2 slower at 2-2.5: two bins,
    with their frame counts; an empty bin is left out."""
    density = np.array([0.6, 0.8, 0.9, 2.2, 2.4])
    speed = realism.weidmann(density) + np.array([0.1, 0.1, 0.1, -0.2, -0.2])
    got = realism.residuals_by_density(density, speed)
    assert [(lo, hi, n) for lo, hi, _, n in got] == [(0.5, 1.0, 3), (2.0, 2.5, 2)]
    np.testing.assert_allclose([d for _, _, d, _ in got], [0.1, -0.2], atol=1e-12)


def test_tuning_runs_record_nothing(realism, capsys):
    """--tune runs usdcrowd alone, so there is no peer to record beside it: refused in one line, exit 2."""
    with pytest.raises(SystemExit) as stop:
        realism.main(["--tune", "--record"])
    assert stop.value.code == 2
    assert "nothing to record" in capsys.readouterr().err


def _door_flow(realism, width):
    """Specific flow (persons / m / s) of 150 people through the realism bench's bottleneck of ``width``."""
    xy = realism.run_usdcrowd(realism.bottleneck(width, seed=0), 150.0)
    x = xy[..., 0]
    crossed = (x[:-1] < 2.0) & (x[1:] >= 2.0)
    frames = [int(np.argmax(crossed[:, i])) for i in range(x.shape[1]) if crossed[:, i].any()]
    assert len(frames) == 150
    return realism.specific_flow(frames, width)


def test_a_door_narrower_than_two_bodies_passes_the_juelich_flow_with_turned_shoulders(realism, monkeypatch):
    """The 0.8 m door inside the empirical band (1.6-2.0 per metre per second) with shoulders turned in and
    before it; bodies kept square, a single file at the time gap stays below it (its bound is
    v / (0.5 m + VISION_TAU v), 1.43 per metre at 1.34 m/s)."""
    from usdcrowd.sim import params as P

    assert 1.6 <= _door_flow(realism, 0.8) <= 2.0
    monkeypatch.setattr(P, "SIDEWAYS_RADIUS", 1.0)
    assert _door_flow(realism, 0.8) < 1.45
