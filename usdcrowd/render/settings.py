"""What a render does to every frame: one :class:`RenderSettings`, made from a preset and the
command line's overrides, checked once where it is made, and handed whole to whoever renders."""

from __future__ import annotations

import tomllib
from dataclasses import asdict, dataclass

from ..core.errors import UsdcrowdError

AOV_NAMES = ("depth", "normal", "position", "albedo", "id")
# Mitsuba's samplers a render may use (render/final/camera.py builds the sensor's).
SAMPLERS = ("independent", "stratified", "multijitter", "orthogonal", "ldsampler")


@dataclass
class RenderSettings:
    """What a render does to every frame (a preset plus overrides)."""

    resolution: tuple[int, int] = (640, 360)
    spp: int = 64
    max_depth: int = 6
    ground_truth: bool = True
    aovs: tuple[str, ...] = AOV_NAMES
    working_space: str = "sRGB"
    exposure: float = 0.0
    seed: int = 0
    variant: str | None = None
    sampler: str = "multijitter"
    denoise: bool = False
    shutter: float = 0.0
    subframes: int = 8
    people_spp: int = 0

    def __post_init__(self):
        """Checked once, here, where settings are made (a preset, the command line, a worker's copy)."""
        self.resolution = tuple(int(v) for v in self.resolution)
        self.aovs = tuple(self.aovs)
        bad = set(self.aovs) - set(AOV_NAMES)
        if bad:
            raise UsdcrowdError(f"unknown AOV(s) {sorted(bad)} (known: {', '.join(AOV_NAMES)})")
        from .colour import WORKING_SPACES

        checks = ((self.working_space in WORKING_SPACES, f"working space must be one of {', '.join(WORKING_SPACES)}"),
                  (self.sampler in SAMPLERS, f"sampler must be one of {', '.join(SAMPLERS)}, not {self.sampler!r}"),
                  (len(self.resolution) == 2 and min(self.resolution) >= 1, f"resolution {self.resolution} is no image"),
                  (int(self.spp) >= 1, f"spp must be >= 1, not {self.spp}"),
                  (int(self.max_depth) >= 1, f"max_depth must be >= 1, not {self.max_depth}"),
                  (int(self.people_spp) >= 0, f"people_spp must be >= 0, not {self.people_spp}"),
                  (0.0 <= float(self.shutter) <= 1.0, f"the shutter is open between 0 and 1 frame, not {self.shutter}"),
                  (int(self.subframes) >= 1, f"subframes must be >= 1, not {self.subframes}"))
        for ok, message in checks:
            if not ok:
                raise UsdcrowdError(message)

    def fingerprint(self) -> dict:
        """The settings that change output pixels (variant excluded: same picture, other noise)."""
        d = asdict(self)
        d.pop("variant")
        d["resolution"] = list(self.resolution)
        d["aovs"] = list(self.aovs)
        return d


def load_presets() -> dict[str, dict]:
    """The presets of ``render/presets.toml`` (name -> values)."""
    from ..core.resources import data_dir

    with open(data_dir("render") / "presets.toml", "rb") as f:
        return tomllib.load(f)


def settings_from_preset(name: str = "groundtruth", **overrides) -> RenderSettings:
    """A preset with ``overrides`` (None values are ignored).

    Raises
    ------
    UsdcrowdError
        On an unknown preset, or settings :class:`RenderSettings` refuses.
    """
    presets = load_presets()
    if name not in presets:
        raise UsdcrowdError(f"unknown render preset {name!r} (presets: {', '.join(presets)})")
    values = dict(presets[name])
    values.update({k: v for k, v in overrides.items() if v is not None})
    known = set(RenderSettings.__dataclass_fields__)
    return RenderSettings(**{k: v for k, v in values.items() if k in known})
