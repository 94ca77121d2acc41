"""Make the behavior-map images the example stages use (stages/maps/*.png).

Deterministic: the same numpy and Pillow give byte-identical files, so the
PNGs are committed and this script is only rerun when a map's design
changes. Every map is laid over the extent its stage authors on the
BehaviorLayer (crowd:extentMin / crowd:extentMax); row 0 is the +Y edge, as
usdcrowd reads painted layers. Each image spans its full pixel range (0 to
the largest value of its dtype), so the stage's crowd:valueRange is exactly
the range of values the layer takes.

    python tools/make_stage_maps.py [--out stages/maps]

Maps
----
volcano_height.png  16-bit greyscale ('I;16'): terrain height, 0..40 m in
                    volcano.usda. A Gaussian cone with a crater on its top,
                    a terraced hill north of the village, and a
                    flat plain where the village stands.
animals_food.png    8-bit: food patches (blurred blobs from a fixed seed,
                    one meadow per sector, plus a small patch of seeds
                    about 7.6 m from the ant hill).
animals_rest.png    8-bit: resting places for the birds (the tree groves).
harbour_water.png   8-bit: the harbour water as a forbidden area (1 = water,
                    0 = quay and pier).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image

SIZE = 256  # pixels per side of every map

# --- volcano.usda: BehaviorLayer extent (-80, -80) .. (80, 80) metres -------
VOLCANO_EXTENT = ((-80.0, -80.0), (80.0, 80.0))
CRATER = (35.0, 35.0)        # centre of the cone and crater, metres
CONE_SIGMA = 20.0            # m, spread of the cone
CRATER_RADIUS = 6.0          # m, Gaussian radius of the crater's dip
CRATER_DEPTH = 0.3           # fraction of the cone's height
HILL = (-35.0, 20.0)         # terraced hill north of the village
HILL_SIGMA = 12.0
HILL_HEIGHT = 0.2            # fraction of the cone's height

# --- animals.usda: extent (-60, -60) .. (60, 60) metres ---------------------
ANIMALS_EXTENT = ((-60.0, -60.0), (60.0, 60.0))
FOOD_SEED = 4                # seed 004's animal scene
FOOD_PATCHES = 6             # random meadows for the herd
ANT_NEST = (-30.0, -30.0)    # the ant hill
ANT_FOOD = (7.0, 3.0)        # offset of the ants' small seed patch from the nest, metres
GROVES = ((25.0, 30.0), (-35.0, 25.0), (40.0, -20.0))   # tree groves (rest places)

# --- harbour.usda: extent (-50, -40) .. (50, 40) metres ---------------------
HARBOUR_EXTENT = ((-50.0, -40.0), (50.0, 40.0))
QUAY_EDGE_Y = 0.0            # water north of this line
PIER = ((8.0, -1.0), (12.0, 26.0))   # pier deck (x0, y0), (x1, y1)


def grid(extent, size=SIZE):
    """World X, Y of the pixel centres, (size, size) each; row 0 at +Y."""
    (x0, y0), (x1, y1) = extent
    xs = x0 + (np.arange(size) + 0.5) / size * (x1 - x0)
    ys = y1 - (np.arange(size) + 0.5) / size * (y1 - y0)
    return np.meshgrid(xs, ys)


def gaussian(X, Y, cx, cy, sigma):
    return np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2.0 * sigma ** 2))


def normalise(a: np.ndarray) -> np.ndarray:
    a = a - a.min()
    return a / a.max()


def to_u16(a: np.ndarray) -> Image.Image:
    return Image.fromarray(np.round(normalise(a) * 65535).astype(np.uint16))   # mode I;16


def to_u8(a: np.ndarray) -> Image.Image:
    return Image.fromarray(np.round(np.clip(a, 0, 1) * 255).astype(np.uint8))  # mode L


def volcano_height() -> Image.Image:
    X, Y = grid(VOLCANO_EXTENT)
    h = gaussian(X, Y, *CRATER, CONE_SIGMA)
    h -= CRATER_DEPTH * gaussian(X, Y, *CRATER, CRATER_RADIUS)
    h += HILL_HEIGHT * gaussian(X, Y, *HILL, HILL_SIGMA)
    return to_u16(h)


def _blobs(X, Y, centres, sigma, rng, lobes=4):
    """Irregular blurred blobs: each a few overlapping Gaussians, peak 1."""
    out = np.zeros_like(X)
    for cx, cy in centres:
        blob = gaussian(X, Y, cx, cy, sigma)
        for _ in range(lobes):
            dx, dy = rng.normal(0.0, sigma * 0.6, 2)
            blob = np.maximum(blob, 0.8 * gaussian(X, Y, cx + dx, cy + dy, sigma * rng.uniform(0.5, 0.9)))
        out = np.maximum(out, blob)
    return np.clip(out * 1.25, 0.0, 1.0)   # flat tops: the centre of each patch is full food


def animals_food() -> Image.Image:
    rng = np.random.default_rng(FOOD_SEED)
    X, Y = grid(ANIMALS_EXTENT)
    # One meadow per sector around the centre, so the patches spread out.
    k = np.arange(FOOD_PATCHES)
    angle = 2 * np.pi * (k + rng.uniform(0.2, 0.8, FOOD_PATCHES)) / FOOD_PATCHES
    radius = rng.uniform(15.0, 45.0, FOOD_PATCHES)
    centres = [(float(r * np.cos(a)), float(r * np.sin(a))) for a, r in zip(angle, radius)]
    meadows = _blobs(X, Y, centres, 6.0, rng)
    seeds = _blobs(X, Y, [(ANT_NEST[0] + ANT_FOOD[0], ANT_NEST[1] + ANT_FOOD[1])], 2.5, rng, lobes=2)
    return to_u8(np.maximum(meadows, seeds))


def animals_rest() -> Image.Image:
    rng = np.random.default_rng(FOOD_SEED + 1)
    X, Y = grid(ANIMALS_EXTENT)
    return to_u8(_blobs(X, Y, GROVES, 4.0, rng, lobes=2))


def harbour_water() -> Image.Image:
    X, Y = grid(HARBOUR_EXTENT)
    water = Y > QUAY_EDGE_Y
    (px0, py0), (px1, py1) = PIER
    pier = (X >= px0) & (X <= px1) & (Y >= py0) & (Y <= py1)
    return to_u8((water & ~pier).astype(np.float64))


MAPS = {
    "volcano_height.png": volcano_height,
    "animals_food.png": animals_food,
    "animals_rest.png": animals_rest,
    "harbour_water.png": harbour_water,
}


def main(argv=None) -> int:
    default = Path(__file__).resolve().parent.parent / "stages" / "maps"
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=default, help=f"output folder (default {default})")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for name, make in MAPS.items():
        im = make()
        im.save(args.out / name, optimize=True)
        print(f"{args.out / name}  {im.mode} {im.size[0]}x{im.size[1]}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
