"""Nobody moves faster than it may: walkers up to MAX_SPEED_FACTOR times their speed, fleeing ones up to the
panic factor, measured frame to frame on the positions written (constraint pushes included)."""

from __future__ import annotations

import numpy as np
import pytest

from usdcrowd.core.resources import data_dir
from usdcrowd.scenario import load_scenario
from usdcrowd.sim import SimSettings, Simulation
from usdcrowd.sim import params as P

FRAMES = 96
# Scenes where someone flees (explosion, eruption) may run; in the others everyone walks.
PANIC = {"explosion", "volcano"}


def _frame_speeds(scenario) -> np.ndarray:
    sim = Simulation(scenario, SimSettings())
    xy = sim.frames(FRAMES, scenario.time.codes[0]).position[:, :, :2].astype(np.float64)
    return np.linalg.norm(np.diff(xy, axis=0), axis=-1) * scenario.time.fps


@pytest.mark.parametrize("name", ["animals", "dialogue", "explosion", "harbour", "museum", "volcano"])
def test_no_one_in_an_example_scene_is_faster_than_its_maximum_speed(name):
    scenario = load_scenario(data_dir("stages") / f"{name}.usda")
    factor = P.PANIC_SPEED_FACTOR * 1.1 if name in PANIC else P.MAX_SPEED_FACTOR
    ratio = _frame_speeds(scenario) / np.asarray(scenario.agents.speed)[None]
    assert ratio.max() <= factor * 1.01, (name, float(ratio.max()))


def test_clones_spawned_where_they_do_not_fit_spread_without_flying(tmp_path):
    """1,500 visitors in the museum (its spawn discs hold far fewer): they spread over frames; before the
    overlap corrections were capped and the starts kept in bounds, some moved 20 m/s in the first frame."""
    from usdcrowd.jobs.templates import new_scenario

    path = tmp_path / "museum.usda"
    new_scenario("museum", path, agents=1500, seed=1)
    speeds = _frame_speeds(load_scenario(path))
    assert speeds.max() < 6.0, float(speeds.max())
    assert np.percentile(speeds, 99.9) < 2.5
