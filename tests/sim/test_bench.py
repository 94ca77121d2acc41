"""The simulation benchmark (tools/bench_sim.py) runs and reports its table."""

from __future__ import annotations

import numpy as np

from usdcrowd.sim import Simulation

from tests.helpers.tools import load_tool


def _bench():
    return load_tool("bench_sim")


def test_bench_run_small():
    rows = _bench().run(sizes=(400,), steps=5, jupedsim=False)
    assert len(rows) == 1
    r = rows[0]
    assert r["agents"] == 400 and r["steps_per_s"] > 0 and r["peak_mib"] > 0
    assert r["jupedsim_steps_per_s"] is None and r["ratio"] is None


def test_bench_scene_is_valid_and_overlap_free_at_start():
    sc = _bench().scene(2000)
    sim = Simulation(sc)
    p = sim.pos[:, :sim.n]
    from scipy.spatial import cKDTree
    assert len(cKDTree(p.T).query_pairs(0.5)) == 0
    assert np.all(np.abs(p) < 100.0)
