"""The values of a stage's UsdLux lights, checked once for ``validate``, ``simulate`` and the renderers.

A light's emission is ``inputs:intensity * 2 ** inputs:exposure`` times its
colour: each must be a finite number a renderer can use (a negative intensity
is no light, an exposure of 2000 overflows), and a dome's texture must be an
image that exists (the renderer's worker would otherwise die on it).
"""

from __future__ import annotations

import os

import numpy as np

# inputs:exposure accepted, in stops: 2 ** 64 is past any light there is.
EXPOSURE_RANGE = (-64.0, 64.0)
# Largest emission (intensity * 2 ** exposure): the sun's disc is 1.6e9 nits.
MAX_EMISSION = 1e15
# inputs:colorTemperature accepted when enabled, kelvin (a crater's glow is 1,200 K).
COLOR_TEMPERATURE_RANGE = (100.0, 100_000.0)
# The first bytes of the images the renderers read for a dome (Mitsuba's Bitmap).
_IMAGE_MAGIC = {
    b"\x76\x2f\x31\x01": "OpenEXR", b"#?RADIANCE": "Radiance HDR", b"#?RGBE": "Radiance HDR",
    b"\x89PNG\r\n\x1a\n": "PNG", b"\xff\xd8\xff": "JPEG", b"II*\x00": "TIFF", b"MM\x00*": "TIFF",
    b"PF\n": "PFM", b"Pf\n": "PFM", b"BM": "BMP", b"P6": "PPM", b"P3": "PPM",
}
_IMAGE_SUFFIXES = (".tga",)           # no magic number


def light_problems(prim) -> list[tuple[str, str]]:
    """(attribute, message) for each value of a UsdLux light no renderer can use, at its default time and
    every authored sample; [] for a good light or a prim that is not one."""
    from pxr import UsdLux

    if not prim.HasAPI(UsdLux.LightAPI):
        return []
    api = UsdLux.LightAPI(prim)
    out = []
    for attr, check in ((api.GetIntensityAttr(), _intensity), (api.GetExposureAttr(), _exposure),
                        (api.GetColorAttr(), _colour)):
        for t, value in _values(attr):
            problem = "not a finite value" if not _finite(value) else check(value) if value is not None else None
            if problem:
                out.append((attr.GetName(), problem + ("" if t is None else f" at time {t:g}")))
                break
    if not out:
        intensity, exposure = api.GetIntensityAttr().Get(), api.GetExposureAttr().Get()
        emission = float(intensity) * 2.0 ** float(exposure)
        if emission > MAX_EMISSION:
            out.append((api.GetExposureAttr().GetName() if exposure else api.GetIntensityAttr().GetName(),
                        f"intensity {intensity:g} times 2 ** exposure {exposure:g} is {emission:.3g}, "
                        f"more than the {MAX_EMISSION:g} any light gives"))
    if api.GetEnableColorTemperatureAttr().Get():
        kelvin = api.GetColorTemperatureAttr().Get()
        low, high = COLOR_TEMPERATURE_RANGE
        if not low <= kelvin <= high:
            out.append((api.GetColorTemperatureAttr().GetName(),
                        f"must be {low:g} to {high:g} K, got {kelvin:g}"))
    texture = prim.GetAttribute("inputs:texture:file")
    problem = _texture_problem(texture.Get()) if texture and texture.HasAuthoredValue() else None
    if problem:
        out.append((texture.GetName(), problem))
    return out


def _values(attr):
    """(time or None, value) of an attribute: its default, then each authored sample."""
    if not attr:
        return
    yield None, attr.Get()
    for t in attr.GetTimeSamples():
        yield t, attr.Get(t)


def _finite(value) -> bool:
    return value is None or bool(np.isfinite(np.asarray(value, dtype=np.float64)).all())


def _intensity(value) -> str | None:
    return f"must be >= 0, got {value:g}" if value < 0 else None


def _exposure(value) -> str | None:
    low, high = EXPOSURE_RANGE
    return None if low <= value <= high else f"must be {low:g} to {high:g} stops, got {value:g}"


def _colour(value) -> str | None:
    return f"must be >= 0 in each channel, got {tuple(value)}" if min(value) < 0 else None


def _texture_problem(asset) -> str | None:
    """What is wrong with a dome's texture file: missing, unreadable or not an image; None when fine."""
    if asset is None or not asset.path:
        return None
    from .stageio import unpacked

    resolved = unpacked(asset.resolvedPath)         # a texture inside a usdz: a copy on disk
    if not resolved or not os.path.isfile(resolved):
        return f"texture @{asset.path}@ not found"
    try:
        with open(resolved, "rb") as f:
            head = f.read(16)
    except OSError as exc:
        return f"texture @{asset.path}@ cannot be read: {exc.strerror}"
    if not any(head.startswith(m) for m in _IMAGE_MAGIC) and not resolved.lower().endswith(_IMAGE_SUFFIXES):
        kinds = sorted(set(_IMAGE_MAGIC.values())) + ["TGA"]
        return f"texture @{asset.path}@ is not an image ({', '.join(kinds)})"
    return None
