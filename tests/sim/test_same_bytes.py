"""A seed gives the same crowd, to the bit, however the step's loops are spread over the cores."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from usdcrowd.sim import SimSettings, Simulation, kernels

from tests.helpers.tools import load_tool


def _digest(scenario, steps: int) -> str:
    """sha256 of everything a step leaves (positions, velocities, headings, behaviors, looks, health)."""
    sim = Simulation(scenario, SimSettings(fps=25.0, substeps=1))
    for _ in range(steps):
        sim.step()
    h = hashlib.sha256()
    for a in (sim.pos, sim.vel, sim.heading, sim.behavior, sim.look, sim.health):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


@pytest.fixture(scope="module")
def square_crowd_and_harbour():
    """The bench square's crowd (groups, leaders, a blast) and the harbour's (110 people among 44 walls)."""
    from usdcrowd.core.resources import data_dir
    from usdcrowd.scenario import load_scenario

    return [load_tool("bench_sim").scene(600), load_scenario(str(data_dir("stages") / "harbour.usda"))]


def test_a_crowd_is_the_same_bytes_on_threads_on_one_thread_and_in_plain_loops(square_crowd_and_harbour, monkeypatch):
    """The step's loops run spread over the cores from PARALLEL_MIN items and in one plain loop below:
    each item's result depends on its own iteration alone, so the bytes do not depend on either (or on
    the run)."""
    import numba

    for scenario in square_crowd_and_harbour:
        threaded = _digest(scenario, 120)
        assert _digest(scenario, 120) == threaded
        every = numba.get_num_threads()
        numba.set_num_threads(1)
        try:
            one_thread = _digest(scenario, 120)
        finally:
            numba.set_num_threads(every)
        monkeypatch.setattr(kernels, "PARALLEL_MIN", 10 ** 9)
        plain = _digest(scenario, 120)
        monkeypatch.setattr(kernels, "PARALLEL_MIN", 64)
        assert one_thread == threaded and plain == threaded, scenario.name
