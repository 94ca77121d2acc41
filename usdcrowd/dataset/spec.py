"""A dataset spec (TOML): what varies between sequences and how, and the draw of each sequence's plan.

Every randomized value of sequence ``k`` comes from ``numpy.random.default_rng([seed, k])``
in a fixed order (:func:`draw_plan`), so a sequence's plan depends only on the
spec and its index: adding sequences never changes the earlier ones, and any
one can be re-made alone. Ranges are ``[low, high]`` (uniform; integers
inclusive); lists of names are drawn from uniformly.

An example, with every key (``docs/dataset_example.toml`` holds a runnable one)::

    [dataset]
    name = "museum-crowds"
    seed = 7
    sequences = 8
    frames = 24            # rendered frames per sequence and camera
    stride = 1             # simulated frames per rendered frame
    split = { train = 0.75, val = 0.125, test = 0.125 }

    [scene]
    templates = ["museum", "dialogue"]
    sceneries = []         # DCC scenery files (relative to the spec); [] keeps the template's
    agents = [20, 60]

    [light]                # time of day
    sun_elevation = [15, 75]        # degrees above the horizon
    sun_azimuth = [0, 360]          # degrees, counter-clockwise from +X
    sun_strength = [2.0, 4.0]       # DistantLight intensity
    sky_strength = [0.3, 1.0]       # DomeLight intensity
    color_temperature = [4000, 7000]  # kelvin, of the sun

    [appearance]
    palettes = ["everyday", "winter"]   # character.appearance.PALETTES

    [cameras]
    steering = [1, 2]      # steering camera agents (seed 000)
    static = 1             # fixed cameras around the crowd
    focal_length = [24, 50]   # mm, static cameras
    height = [2.0, 6.0]       # m, static cameras
    distance = [8.0, 16.0]    # m from the crowd's centre, static cameras
    toric = ["orbit", "side-track"]     # one toric camera per sequence when not empty
    toric_shots = ["medium", "long"]
    overview = false       # also render the shot's overview camera

    [render]
    preset = "groundtruth"
    resolution = [640, 360]
    spp = 16
    people_spp = 32        # more samples on the people's pixels (default: the preset's)
"""

from __future__ import annotations

import hashlib
import json
import os
import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..core.errors import UsdcrowdError

SPLITS = ("train", "val", "test")
BEHAVIORS = ("orbit", "direct-track", "relative-track", "side-track")
SHOTS = ("close-up", "medium", "long")
# More than this many sequences is a typo rather than a plan (a cluster's worth is far less).
# Every sequence's plan is drawn and listed in the manifest before the work starts: 10,000 take about
# 1 s and 10 MB; a million took minutes of silence and a gigabyte of manifest.
MAX_SEQUENCES = 100_000
MAX_FRAMES = 100_000
# The largest number any key takes (metres, degrees, kelvin, counts).
MAX_MAGNITUDE = 1_000_000


@dataclass
class DatasetSpec:
    """A parsed, checked spec (see the module docstring for the meaning of each field)."""

    path: str
    name: str = "usdcrowd-dataset"
    seed: int = 0
    sequences: int = 4
    frames: int = 24
    stride: int = 1
    split: dict = field(default_factory=lambda: {"train": 0.75, "val": 0.125, "test": 0.125})
    templates: list = field(default_factory=lambda: ["museum"])
    sceneries: list = field(default_factory=list)
    agents: list = field(default_factory=lambda: [20, 60])
    sun_elevation: list = field(default_factory=lambda: [20.0, 70.0])
    sun_azimuth: list = field(default_factory=lambda: [0.0, 360.0])
    sun_strength: list = field(default_factory=lambda: [2.5, 3.5])
    sky_strength: list = field(default_factory=lambda: [0.4, 0.8])
    color_temperature: list = field(default_factory=lambda: [4500.0, 6500.0])
    palettes: list = field(default_factory=lambda: ["everyday"])
    steering: list = field(default_factory=lambda: [1, 1])
    static: int = 1
    focal_length: list = field(default_factory=lambda: [24.0, 50.0])
    height: list = field(default_factory=lambda: [2.5, 5.0])
    distance: list = field(default_factory=lambda: [8.0, 14.0])
    toric: list = field(default_factory=list)
    toric_shots: list = field(default_factory=lambda: ["medium"])
    overview: bool = False
    preset: str = "groundtruth"
    resolution: list = field(default_factory=lambda: [640, 360])
    spp: int | None = None
    people_spp: int | None = None

    def canonical(self) -> dict:
        """The spec's values (not its path): what the dataset is made from."""
        d = asdict(self)
        d.pop("path")
        return d

    def digest(self) -> str:
        """sha256 of :meth:`canonical` (a changed spec is refused against an existing dataset)."""
        return hashlib.sha256(json.dumps(self.canonical(), sort_keys=True).encode()).hexdigest()

    def scenery_path(self, name: str) -> str:
        """A scenery file named in the spec, resolved against the spec's folder."""
        return os.fspath((Path(self.path).parent / name).resolve())


# TOML table -> {key: (field, kind)}; kinds: int, float, bool, str, range_i, range_f, names, split, size.
_KEYS = {
    "dataset": {"name": "str", "seed": "int", "sequences": "int", "frames": "int", "stride": "int",
                "split": "split"},
    "scene": {"templates": "names", "sceneries": "names", "agents": "range_i"},
    "light": {"sun_elevation": "range_f", "sun_azimuth": "range_f", "sun_strength": "range_f",
              "sky_strength": "range_f", "color_temperature": "range_f"},
    "appearance": {"palettes": "names"},
    "cameras": {"steering": "range_i", "static": "int", "focal_length": "range_f", "height": "range_f",
                "distance": "range_f", "toric": "names", "toric_shots": "names", "overview": "bool"},
    "render": {"preset": "str", "resolution": "size", "spp": "int", "people_spp": "int"},
}


def load_spec(path: str | os.PathLike) -> DatasetSpec:
    """Read and check a spec file.

    Raises
    ------
    UsdcrowdError
        One line naming the file, the table and key, and what is wrong.
    """
    path = os.fspath(path)
    try:
        with open(path, "rb") as f:
            doc = tomllib.load(f)
    except FileNotFoundError:
        raise UsdcrowdError("no such spec file", file=path) from None
    except tomllib.TOMLDecodeError as exc:
        raise UsdcrowdError(f"not valid TOML: {exc}", file=path) from None
    spec = DatasetSpec(path=os.fspath(Path(path).resolve()))
    for table, values in doc.items():
        if table not in _KEYS:
            raise UsdcrowdError(f"unknown table [{table}] (tables: {', '.join(_KEYS)})", file=path)
        if not isinstance(values, dict):
            raise UsdcrowdError(f"[{table}] must be a table", file=path)
        for key, value in values.items():
            if key not in _KEYS[table]:
                raise UsdcrowdError(f"unknown key (keys of [{table}]: {', '.join(_KEYS[table])})",
                                    file=path, attribute=f"{table}.{key}")
            setattr(spec, key, _checked(value, _KEYS[table][key], path, f"{table}.{key}"))
    _check_meaning(spec, path)
    return spec


def _checked(value, kind: str, path: str, where: str):
    def fail(what):
        raise UsdcrowdError(f"{what}, got {value!r}", file=path, attribute=where)

    def number(v, integer):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or (integer and not isinstance(v, int)):
            fail("expected " + ("a whole number" if integer else "a number"))
        if not np.isfinite(v):
            fail("expected a finite number")
        if abs(v) > MAX_MAGNITUDE and where != "dataset.seed":     # (seeds: checked on their own)
            # No quantity here is that large; draws between such bounds would overflow.
            fail(f"expected a number within +-{MAX_MAGNITUDE:,}")
        return v

    if kind in ("int", "float"):
        return number(value, kind == "int")
    if kind == "bool":
        if not isinstance(value, bool):
            fail("expected true or false")
        return value
    if kind == "str":
        if not isinstance(value, str) or not value.strip():
            fail("expected a non-empty string")
        return value
    if kind in ("range_i", "range_f"):
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            value = [value, value]              # a single value: no variation
        if not isinstance(value, list) or len(value) != 2:
            fail("expected [low, high] or a single number")
        lo, hi = (number(v, kind == "range_i") for v in value)
        if hi < lo:
            fail("expected low <= high")
        return [lo, hi]
    if kind == "names":
        if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
            fail("expected a list of names")
        return list(value)
    if kind == "size":
        if (not isinstance(value, list) or len(value) != 2
                or not all(isinstance(v, int) and not isinstance(v, bool) and 16 <= v <= 16384 for v in value)):
            fail("expected [width, height] in pixels, 16 to 16384")
        return list(value)
    if kind == "split":
        if not isinstance(value, dict) or not value or set(value) - set(SPLITS):
            fail(f"expected a table of {', '.join(SPLITS)} fractions")
        fractions = {k: float(number(v, False)) for k, v in value.items()}
        if min(fractions.values()) < 0 or sum(fractions.values()) <= 0:
            fail("expected fractions >= 0 that do not all vanish")
        return fractions
    raise AssertionError(kind)


def _check_meaning(spec: DatasetSpec, path: str) -> None:
    """Values that parse but cannot be made: one line each, naming the key."""
    from ..character.appearance import PALETTES
    from ..render.settings import load_presets
    from ..jobs.templates import list_templates

    def fail(where, what):
        raise UsdcrowdError(what, file=path, attribute=where)

    if not 0 <= spec.seed <= 2**32 - 1:
        fail("dataset.seed", f"expected a seed from 0 to 4,294,967,295, got {spec.seed}")
    if not 1 <= spec.sequences <= MAX_SEQUENCES:
        fail("dataset.sequences", f"expected 1 to {MAX_SEQUENCES:,} sequences, got {spec.sequences}")
    if not 2 <= spec.frames <= MAX_FRAMES:
        fail("dataset.frames", f"expected 2 to {MAX_FRAMES:,} frames, got {spec.frames}")
    if spec.stride < 1:
        fail("dataset.stride", f"expected a stride >= 1, got {spec.stride}")
    known = list_templates()
    for t in spec.templates:
        if t not in known:
            fail("scene.templates", f"unknown template {t!r} (templates: {', '.join(known)})")
    if not spec.templates:
        fail("scene.templates", "name at least one template")
    for s in spec.sceneries:
        if not Path(spec.scenery_path(s)).is_file():
            fail("scene.sceneries", f"no such scenery file {s!r} (paths are relative to the spec)")
    if spec.agents[0] < 1:
        fail("scene.agents", f"expected at least 1 agent, got {spec.agents[0]}")
    from ..core.limits import DEFAULT

    if spec.agents[1] > DEFAULT.max_agents:
        fail("scene.agents", f"expected at most {DEFAULT.max_agents:,} agents, got {spec.agents[1]:,}")
    if not (0 <= spec.sun_elevation[0] and spec.sun_elevation[1] <= 90):
        fail("light.sun_elevation", "expected degrees in [0, 90]")
    for key in ("sun_strength", "sky_strength"):
        if getattr(spec, key)[0] < 0:
            fail(f"light.{key}", "expected intensities >= 0")
    if not (1000 <= spec.color_temperature[0] and spec.color_temperature[1] <= 40000):
        fail("light.color_temperature", "expected kelvin in [1000, 40000]")
    for p in spec.palettes:
        if p not in PALETTES:
            fail("appearance.palettes", f"unknown palette {p!r} (palettes: {', '.join(PALETTES)})")
    if not spec.palettes:
        fail("appearance.palettes", "name at least one palette")
    if spec.steering[0] < 0 or spec.steering[1] > 16:
        fail("cameras.steering", "expected 0 to 16 steering cameras")
    if not 0 <= spec.static <= 16:
        fail("cameras.static", f"expected 0 to 16 static cameras, got {spec.static}")
    if spec.focal_length[0] <= 0 or spec.height[0] < 0 or spec.distance[0] <= 0:
        fail("cameras", "focal lengths and distances must be > 0, heights >= 0")
    if spec.focal_length[1] > 2000:
        fail("cameras.focal_length", f"expected a lens of at most 2000 mm, got {spec.focal_length[1]:g}")
    for b in spec.toric:
        if b not in BEHAVIORS:
            fail("cameras.toric", f"unknown behavior {b!r} (behaviors: {', '.join(BEHAVIORS)})")
    for s in spec.toric_shots:
        if s not in SHOTS:
            fail("cameras.toric_shots", f"unknown shot size {s!r} (sizes: {', '.join(SHOTS)})")
    if spec.toric and not spec.toric_shots:
        fail("cameras.toric_shots", "name at least one shot size for the toric cameras")
    if spec.steering[1] == 0 and spec.static == 0 and not spec.toric and not spec.overview:
        fail("cameras", "no camera would film anything: ask for steering, static, toric or overview cameras")
    if spec.preset not in load_presets():
        fail("render.preset", f"unknown preset {spec.preset!r} (presets: {', '.join(load_presets())})")
    if spec.spp is not None and not 1 <= spec.spp <= 65536:
        fail("render.spp", f"expected 1 to 65536 samples per pixel, got {spec.spp}")
    if spec.people_spp is not None and not 0 <= spec.people_spp <= 65536:
        fail("render.people_spp", f"expected 0 to 65536 more samples per person's pixel, got {spec.people_spp}")


# --------------------------------------------------------------------- plans
def sequence_name(index: int) -> str:
    return f"seq_{index:04d}"


def assign_splits(spec: DatasetSpec) -> list[str]:
    """The split of every sequence: a seeded shuffle cut by the fractions (largest remainder).

    Whole sequences (all their cameras) go to one split, so no scene is seen in two.
    """
    names = [s for s in SPLITS if spec.split.get(s, 0.0) > 0]
    w = np.array([spec.split[s] for s in names], dtype=np.float64)
    exact = spec.sequences * w / w.sum()
    counts = np.floor(exact).astype(int)
    for k in np.argsort(-(exact - counts), kind="stable")[: spec.sequences - counts.sum()]:
        counts[k] += 1
    order = np.random.default_rng([spec.seed & 0xFFFFFFFF, 0x5B117]).permutation(spec.sequences)
    out = [""] * spec.sequences
    start = 0
    for name, c in zip(names, counts):
        for i in order[start:start + c]:
            out[int(i)] = name
        start += c
    return out


def draw_plan(spec: DatasetSpec, index: int, split: str) -> dict:
    """Everything random about sequence ``index``, drawn in a fixed order from its own generator.

    Returns
    -------
    dict
        JSON-ready; written into the sequence's scenario stage (customLayerData
        ``usdcrowd.dataset``) and its ``plan.json``.
    """
    rng = np.random.default_rng([spec.seed & 0xFFFFFFFF, index])

    def uniform(r):
        return float(rng.uniform(r[0], r[1])) if r[1] > r[0] else float(r[0])

    def integer(r):
        return int(rng.integers(r[0], r[1] + 1))

    def pick(names):
        return str(names[int(rng.integers(len(names)))]) if names else None

    plan = {
        "name": sequence_name(index), "index": index, "split": split,
        "seed": int(rng.integers(0, 2**31 - 1)),
        "template": pick(spec.templates),
        "scenery": pick(spec.sceneries),
        "agents": integer(spec.agents),
        "light": {"sun_elevation": uniform(spec.sun_elevation), "sun_azimuth": uniform(spec.sun_azimuth) % 360.0,
                  "sun_strength": uniform(spec.sun_strength), "sky_strength": uniform(spec.sky_strength),
                  "color_temperature": uniform(spec.color_temperature)},
        "palette": pick(spec.palettes),
        "steering": integer(spec.steering),
        "static": [{"azimuth": float(rng.uniform(0.0, 360.0)), "height": uniform(spec.height),
                    "distance": uniform(spec.distance), "focal_length": uniform(spec.focal_length)}
                   for _ in range(spec.static)],
        "toric": ({"behavior": pick(spec.toric), "shot": pick(spec.toric_shots)} if spec.toric else None),
        "overview": bool(spec.overview),
        "frames": int(spec.frames), "stride": int(spec.stride),
        "render": {"preset": spec.preset, "resolution": list(spec.resolution), "spp": spec.spp,
                   "people_spp": spec.people_spp},
    }
    plan["digest"] = hashlib.sha256(json.dumps(plan, sort_keys=True).encode()).hexdigest()
    return plan
