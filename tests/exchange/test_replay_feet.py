"""The figure behind "the feet slide": how fast a replayed walker's soles move while they bear weight
(tools/measure_feet.py), checked against feet whose motion is known and against what the guide quotes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.helpers.tools import load_tool


@pytest.fixture(scope="module")
def feet():
    return load_tool("measure_feet")


def test_a_planted_foot_measures_still_and_a_sliding_one_its_speed(feet):
    """A compass step: on the ground at x = 0 for ten frames, lifted straight up, carried 0.7 m, set down
    and still again: every weight-bearing frame measures 0. A sole dragged along the ground at 1.2 m/s
    measures 1.2 on every frame."""
    fps = 25.0
    x = np.r_[np.zeros(11), np.linspace(0.0, 0.7, 6)[1:], np.full(10, 0.7)]
    z = np.r_[np.zeros(10), np.full(6, 0.1), np.zeros(10)]
    corners = np.stack([np.column_stack([x + dx, np.zeros_like(x), z]) for dx in (0.0, 0.2)], axis=1)
    planted = feet.stance_speeds(corners, fps)
    assert len(planted) == 19 and np.allclose(planted, 0.0)
    t = np.arange(30) / fps
    dragged = np.stack([np.column_stack([1.2 * t + dx, np.zeros_like(t), np.zeros_like(t)]) for dx in (0.0, 0.2)], 1)
    assert np.allclose(feet.stance_speeds(dragged, fps), 1.2)


def test_the_soles_are_the_shoes_on_the_ground_one_per_side(feet):
    from usdcrowd.character.body import build_body

    left, right = feet.soles(build_body())
    for sole, side in ((left, 1.0), (right, -1.0)):
        assert len(sole) >= 4 and np.allclose(sole[:, 2], 0.0, atol=1e-4)
        assert np.all(np.sign(sole[:, 1]) == side) and abs(abs(sole[:, 1].mean()) - 0.1) < 0.02


def test_the_guides_foot_speed_is_what_a_replay_gives(feet, tmp_path):
    """docs/data/feet.json (the crowd designer's guide quotes it) against a fresh measurement; the replayed
    hips walk at the file's speed."""
    recorded = json.loads((feet.ROOT / "docs" / "data" / "feet.json").read_text())["figures"]
    now = feet.measure(recorded["speed"], workdir=tmp_path)
    assert now["hips_speed"] == pytest.approx(recorded["speed"], abs=0.02)
    for side in ("left", "right"):
        for key in ("stance_median", "stance_max", "stance_frames"):
            assert now[side][key] == pytest.approx(recorded[side][key], rel=1e-6), (side, key)
