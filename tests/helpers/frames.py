"""Hand-made CrowdFrames for testing the writers without the simulation."""

from __future__ import annotations

import numpy as np

from usdcrowd.core import model
from usdcrowd.character.animation import advance_phase, classify


def straight_walk(agents: model.AgentTable, time: model.TimeRange, seed: int = 0) -> model.CrowdFrames:
    """Every agent walks in a straight line from its start at its own speed and heading."""
    rng = np.random.default_rng(seed)
    t = time.n_frames
    n = len(agents)
    dt = 1.0 / time.fps
    heading = np.broadcast_to(agents.start_heading, (t, n)).astype(np.float32)
    direction = np.stack([np.cos(agents.start_heading), np.sin(agents.start_heading)], 1)
    velocity = np.broadcast_to(direction * agents.speed[:, None], (t, n, 2)).astype(np.float32)
    steps = np.arange(t, dtype=np.float64)[:, None, None] * dt
    position = agents.start[None] + np.concatenate([velocity * steps, np.zeros((t, n, 1))], axis=2)
    anim_class = classify(velocity, heading)
    phase = advance_phase(np.linalg.norm(velocity, axis=2), anim_class, dt, rng.random(n))
    look = np.full((t, n, 3), np.nan, dtype=np.float32)
    return model.CrowdFrames(
        times=time.codes, position=position.astype(np.float32), heading=heading, velocity=velocity,
        behavior=np.broadcast_to(agents.behavior, (t, n)).astype(np.int8), anim_class=anim_class,
        anim_phase=phase, health=np.zeros((t, n), np.int8), look_at=look,
        path_method=np.zeros(n, np.int8))
