"""Crowd simulation: a :class:`~usdcrowd.core.model.Scenario` in, :class:`~usdcrowd.core.model.CrowdFrames` out.

Pure numpy/scipy, no USD. Seeds: co-field dynamics, time-to-impact
collision avoidance, flocking, invisible leaders with memory and interest
fields (seed 003); behavior maps, attribute-dependent reactions and
Bezier / gradient paths (seed 004); walkers' way and pace by sight
(Moussaïd, Helbing & Theraulaz 2011), which gives the crowd its
speed-density relation.

Public API
----------
SimSettings
    fps (default: the scenario's), substeps per frame, seed override,
    chunk_frames, distance_method, grid_cell, neighbor_k.
simulate(scenario, settings=None) -> CrowdFrames
    The whole shot.
simulate_chunks(scenario, settings=None) -> Iterator[CrowdFrames]
    The shot in consecutive chunks (long shots: memory bounded by a chunk).
Simulation
    The stepping object (``step()``, ``frames(k, t0)``, ``run_chunks()``).

Module map: ``params`` (constants with units), ``steering`` (Reynolds'
behaviours), ``vision`` (way and pace by sight), ``collision``
(time-to-impact avoidance, overlap and wall constraints), ``neighbors`` (Verlet lists), ``groups`` (leaders,
memory, flocking), ``interest`` (interest fields), ``behavior_maps``
(generated layers, reactions, health), ``paths`` (Bezier, slope, rule),
``grid`` (walkable grid), ``distance_maps`` (Dijkstra / Algorithm 1),
``simulation`` (state, integration, frames), ``kernels`` (the step's loops,
compiled), ``validate``.
"""

from __future__ import annotations

from typing import Iterator

from ..core.model import CrowdFrames, Scenario
from .simulation import SimSettings, Simulation, concat_frames

__all__ = ["SimSettings", "Simulation", "simulate", "simulate_chunks"]


def simulate_chunks(scenario: Scenario, settings: SimSettings | None = None) -> Iterator[CrowdFrames]:
    """Simulate a shot, yielding :class:`CrowdFrames` of ``settings.chunk_frames`` frames.

    Parameters
    ----------
    scenario : Scenario
    settings : SimSettings, optional

    Yields
    ------
    CrowdFrames
        Consecutive chunks; their ``times`` continue one another and cover
        ``scenario.time`` (frames start..end).

    Raises
    ------
    usdcrowd.core.errors.ScenarioError
        On values the simulation cannot use (negative speed, empty group...).
    """
    sim = Simulation(scenario, settings)
    yield from sim.run_chunks()


def simulate(scenario: Scenario, settings: SimSettings | None = None) -> CrowdFrames:
    """Simulate a whole shot at once (see :func:`simulate_chunks`).

    Returns
    -------
    CrowdFrames
        ``position`` (t, n, 3), ``heading`` (t, n), ``velocity`` (t, n, 2),
        ``behavior``, ``anim_class``, ``anim_phase``, ``health`` (t, n),
        ``look_at`` (t, n, 3), ``path_method`` (n,), with
        ``t = scenario.time.n_frames``.
    """
    return concat_frames(list(simulate_chunks(scenario, settings)))
