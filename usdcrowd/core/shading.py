"""Surfaces and lights as numpy, shared by both renderers and the ground truth.

Pure core (no ``pxr``, no renderer). :class:`usdcrowd.scenario.shot_scene.ShotScene`
fills these from a stage's UsdPreviewSurface materials and UsdLux lights.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

# Agents' ids are small positive integers (their track ids); scenery gets ids
# from this offset up so the two never collide in an id buffer.
SCENERY_ID_BASE = 1 << 24
# Light shapes (sphere, rect, disk and cylinder lights) from this one up.
LIGHT_ID_BASE = 1 << 25


def is_agent_id(ids):
    """True where an id (or an array of them) is an agent's: in [1, SCENERY_ID_BASE); 0 is the background."""
    return (ids > 0) & (ids < SCENERY_ID_BASE)


@dataclass
class Material:
    """What UsdPreviewSurface (or displayColor) says about a surface, linear RGB."""

    base_color: np.ndarray = field(default_factory=lambda: np.array([0.6, 0.6, 0.6]))
    roughness: float = 0.5
    metallic: float = 0.0
    opacity: float = 1.0
    base_color_texture: str | None = None      # resolved file path


@dataclass
class Light:
    """A UsdLux light, resolved to what a renderer needs.

    Attributes
    ----------
    kind : str
        "distant", "dome", "sphere", "rect", "disk" or "cylinder".
    rgb : (3,) float
        Linear colour times the colour-temperature tint.
    intensity : float
        ``inputs:intensity * 2 ** inputs:exposure``; for a DistantLight, the
        illuminance it gives a surface facing it (UsdLux: the intensity when
        ``inputs:normalize`` is on, else that times its disc's size factor,
        :func:`distant_illuminance`).
    to_world : (4, 4) float
        Light space to canonical world (lights shine along their local -Z).
    radius, width, height, length, angle : float
        Shape parameters in metres (angle in degrees).
    texture : str or None
        Dome texture file, resolved.
    normalize : bool
        inputs:normalize (power independent of size).
    pole_axis : str
        A dome's top pole in the light's own (stage) axes, "Y" or "Z":
        DomeLight's is +Y whatever the stage's up axis (UsdLux, the OpenEXR
        lat-long convention); DomeLight_1 says with ``poleAxis`` ("scene":
        the stage's up axis).
    """

    path: str
    kind: str
    rgb: np.ndarray
    intensity: float
    to_world: np.ndarray
    radius: float = 0.0
    width: float = 0.0
    height: float = 0.0
    length: float = 0.0
    angle: float = 0.0
    texture: str | None = None
    normalize: bool = False
    pole_axis: str = "Y"


def distant_illuminance(angle: float, normalize: bool) -> float:
    """Illuminance on a surface facing a DistantLight, per unit of its intensity.

    UsdLux: the intensity is the sun disc's luminance, divided by a size
    factor when ``inputs:normalize`` is on, which makes the intensity the
    illuminance itself. Unnormalised, the illuminance is the intensity times
    the size factor ``pi sin^2(t)`` (``(2 - sin^2(t)) pi`` past t = pi/2),
    ``t`` half the angular diameter ``angle`` (degrees); a 0.53-degree sun
    then gives 6.7e-5 of its intensity. Angle 0 (a delta light): 1 either way.
    """
    t = min(max(np.radians(float(angle)) / 2.0, 0.0), np.pi)
    if normalize or t == 0.0:
        return 1.0
    s2 = np.sin(t) ** 2
    return float(np.pi * (s2 if t <= np.pi / 2 else 2.0 - s2))
