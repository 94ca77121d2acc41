"""A tiny dataset spec, for the dataset tests and the command-line tests that run `usdcrowd dataset`."""

from __future__ import annotations

from pathlib import Path

TINY = """
[dataset]
name = "tiny"
seed = {seed}
sequences = 3
frames = 4
stride = 3
split = {{ train = 0.34, val = 0.33, test = 0.33 }}

[scene]
templates = ["dialogue", "museum"]
agents = [8, 14]

[light]
sun_elevation = [25, 65]
sun_azimuth = [0, 360]
color_temperature = [4500, 6500]

[appearance]
palettes = ["everyday", "winter"]

[cameras]
steering = [0, 1]
static = 1
distance = [6.0, 9.0]
toric = ["side-track"]
toric_shots = ["long"]

[render]
preset = "preview"
resolution = [160, 90]
spp = 2
"""


def write_spec(folder: Path, seed: int = 3, name: str = "spec.toml") -> Path:
    path = folder / name
    path.write_text(TINY.format(seed=seed))
    return path
