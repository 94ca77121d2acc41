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


def test_a_missing_peer_stops_the_benchmark_in_one_line(monkeypatch):
    """A row measured against JuPedSim is not printed with n/a in its place: without JuPedSim the sim and
    realism benchmarks stop at once, naming it and how to install it."""
    import sys

    import pytest

    monkeypatch.setitem(sys.modules, "jupedsim", None)          # import jupedsim -> ImportError
    with pytest.raises(SystemExit) as stop:
        _bench().run(sizes=(400,), steps=5)
    message = str(stop.value)
    assert "JuPedSim" in message and "pip install -e '.[bench]'" in message and "\n" not in message
    with pytest.raises(SystemExit, match="realism: JuPedSim"):
        load_tool("bench_realism").run(quick=True)


def test_over_a_run_takes_turns_block_by_block(monkeypatch):
    """The run-long rates alternate a block of usdcrowd with a block of the peer, so a ratio per block
    compares two runs that met the machine in the same state."""
    bench = _bench()
    calls = []

    class Peer:
        def iterate(self):
            calls.append("peer")

    monkeypatch.setattr(bench, "_jupedsim_simulation", lambda n: Peer())
    real = bench.Simulation.step
    monkeypatch.setattr(bench.Simulation, "step", lambda self: (calls.append("usdcrowd"), real(self))[1])
    out = bench.over_a_run(60, steps=9, block=3)
    blocks = [calls[i] for i in range(6, len(calls), 3)]          # after each side's 3 warm-up steps
    assert blocks == ["usdcrowd", "peer"] * 3
    assert len(out["usdcrowd"]) == len(out["jupedsim"]) == 3
    assert np.allclose(out["ratio"], np.array(out["usdcrowd"]) / np.array(out["jupedsim"]))
    assert (out["ratio_first_third"], out["ratio_last_third"]) == (out["ratio"][0], out["ratio"][-1])
