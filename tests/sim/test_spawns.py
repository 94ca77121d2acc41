"""No agent ever moves faster than its character's speed cap: overlapping spawns are set apart before frame 1."""

from __future__ import annotations

import numpy as np
import pytest

from usdcrowd.core.resources import data_dir
from usdcrowd.scenario import load_scenario
from usdcrowd.sim import params as P
from usdcrowd.sim.simulation import Simulation


def fastest(path) -> tuple[float, float]:
    """(largest frame-to-frame ground speed in m/s, its ratio to the agent's speed cap) over every agent-frame."""
    scenario = load_scenario(str(path))
    sim = Simulation(scenario)
    pos = np.concatenate([chunk.position for chunk in sim.run_chunks()])
    speed = np.linalg.norm(np.diff(pos[..., :2], axis=0), axis=-1) * sim.fps
    cap = np.asarray(P.SPEED_CAP)[np.asarray(scenario.agents.character_type)]
    return float(speed.max()), float((speed / cap).max())


@pytest.mark.parametrize("name", sorted(p.name for p in data_dir("stages").glob("*.usda")))
def test_every_agent_frame_of_every_example_scene_is_within_the_speed_cap(name):
    _, ratio = fastest(data_dir("stages") / name)
    assert ratio <= 1.0, f"{name}: an agent moved at {ratio:.2f} times its speed cap"


PILE = """#usda 1.0
(
    defaultPrim = "World"
    startTimeCode = 1
    endTimeCode = 36
    upAxis = "Z"
    metersPerUnit = 1
)
def Xform "World"
{{
{groups}
}}
"""


def group(name: str, clones: int, radius: float, centre=(0, 0), behavior="wander") -> str:
    return (f'    def CrowdGroup "{name}"\n    {{\n        uniform int crowd:clones = {clones}\n'
            f'        uniform float crowd:spawnRadius = {radius}\n'
            f'        uniform point3f crowd:spawnCenter = ({centre[0]}, {centre[1]}, 0)\n'
            f'        uniform token crowd:behavior = "{behavior}"\n    }}\n')


@pytest.mark.parametrize("groups", [
    group("Pile", 100, 0.0),                                          # everyone on one point
    group("Pile", 60, 0.0, behavior="rest"),                          # and nobody walking away
    group("Tight", 200, 0.5),                                         # 200 people in half a metre
    group("A", 40, 0.0) + group("B", 40, 0.0),                        # two groups on the same point
    group("A", 30, 0.0, (3, 0)) + group("B", 30, 0.0, (3.2, 0)),      # two piles side by side
    group("Pile", 2000, 0.0),                                         # far more than the padded bounds hold
], ids=["pile", "resting-pile", "tight-disc", "two-groups-one-point", "two-piles", "pile-of-2000"])
def test_hostile_spawns_are_set_apart_before_the_first_frame(tmp_path, groups):
    path = tmp_path / "pile.usda"
    path.write_text(PILE.format(groups=groups))
    speed, ratio = fastest(path)
    assert ratio <= 1.0, f"an agent moved at {speed:.1f} m/s ({ratio:.2f} times its cap)"
