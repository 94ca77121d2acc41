"""What people wear: seeded per-agent colours for the body's regions.

An agent's *palette* is one linear-RGB colour per row of
:data:`usdcrowd.character.body.REGIONS` (top, trousers, skin, hair, shoes,
eye whites, face).
The stage holds it as the body's indexed ``primvars:displayColor`` (the
shared body maps each vertex to a row, each agent authors its rows), so the
GL preview, Mitsuba and DCC tools all read the same colours.

Tables are 8-bit sRGB, as such colours are usually published, decoded to
linear once. Skin tones are the ten swatches of the Monk Skin Tone scale
(Monk 2019, skintone.google); the others are ordinary clothing colours.
"""

from __future__ import annotations

import numpy as np

from .body import REGIONS

# Roughness of each region's material (UsdPreviewSurface roughness):
# matte cotton tops, denim, skin, glossier hair, polished shoes, moist eyes and lips.
ROUGHNESS = {"top": 0.8, "trousers": 0.7, "skin": 0.45, "hair": 0.3, "shoes": 0.35, "eye_whites": 0.2,
             "face": 0.25}

# How far an authored group colour pulls the drawn top towards itself (0: not
# at all, 1: a uniform); the drawn shade keeps members of a group apart.
GROUP_TINT = 0.65

# Brightness jitter (log-normal sigma) so that no two drawn palettes repeat exactly.
JITTER = 0.08

_SKIN = ["f6ede4", "f3e7db", "f7ead0", "eadaba", "d7bd96", "a07e56", "825c43", "604134", "3a312a", "292420"]
_HAIR = {"1c1816": 0.25, "3b281e": 0.25, "604028": 0.15, "8c6441": 0.10, "c4a064": 0.07,
         "78371e": 0.05, "969491": 0.08, "c8c6c3": 0.05}
_TROUSERS = ["283755", "465f82", "19191c", "3c3c3e", "aa966e", "5a412d", "1e233c", "4b5032", "969696", "c8b9a0"]
_SHOES = {"141414": 0.35, "322319": 0.25, "e1e1dc": 0.15, "6e6e6e": 0.15, "966e46": 0.10}
# Named palettes a scenario may ask for (customLayerData usdcrowd.palette):
# tops None keep the scenario's drawn clothing colour (crowd:color's table).
PALETTES = {
    "everyday": {"tops": None, "trousers": _TROUSERS, "shoes": _SHOES},
    "winter": {"tops": ["1e233c", "2d2d30", "141416", "9a7b4f", "5c1f24", "23412e", "4a4a52", "6b3a2a"],
               "trousers": ["19191c", "28282c", "283755", "3c3c3e", "4b3a2e"],
               "shoes": {"141414": 0.5, "322319": 0.4, "6e6e6e": 0.1}},
    "summer": {"tops": ["f2f2ee", "e8c547", "e07a5f", "81b29a", "f4a3b4", "5fa8d3", "ffffff", "c94f4f", "f6bd60"],
               "trousers": ["465f82", "aa966e", "c8b9a0", "e6e1d3", "3c3c3e", "6f8fae"],
               "shoes": {"e1e1dc": 0.4, "966e46": 0.3, "141414": 0.2, "6e6e6e": 0.1}},
}
# Rows everyone has alike, drawn from no table: the eyes' whites, and irises and mouth in a dark brown.
_FIXED = {"eye_whites": "e6e1d8", "face": "2b201c"}
# Fallback for rows a stage does not author (old stages, hand-written agents).
_PLAIN = {"trousers": "3c3c3e", "skin": "a07e56", "hair": "3b281e", "shoes": "141414", **_FIXED}


def srgb_to_linear(hexes) -> np.ndarray:
    """(k, 3) float64 linear RGB of 8-bit sRGB hex strings (IEC 61966-2-1 decoding)."""
    c = np.array([[int(h[i:i + 2], 16) for i in (0, 2, 4)] for h in hexes], dtype=np.float64) / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def roughness() -> np.ndarray:
    """(r,) float64: each region's roughness, in REGIONS order."""
    return np.array([ROUGHNESS[name] for name in REGIONS], dtype=np.float64)


# The swatches are how skin looks on a display; a diffuse albedo is darker
# (measured skin reflectance peaks near 0.6), so they are scaled by this.
SKIN_ALBEDO = 0.7


def _pick(rng: np.random.Generator, table, n: int) -> np.ndarray:
    """(n, 3) linear colours drawn from a list (uniform) or a {hex: weight} dict."""
    hexes = list(table)
    p = np.array([table[h] for h in hexes], dtype=np.float64) if isinstance(table, dict) else np.ones(len(hexes))
    return srgb_to_linear(hexes)[rng.choice(len(hexes), size=n, p=p / p.sum())]


def draw_palettes(rng: np.random.Generator, top: np.ndarray, palette: str = "everyday") -> np.ndarray:
    """Draw a palette per row of ``top``.

    Parameters
    ----------
    rng : numpy.random.Generator
        Used in a fixed order (skin, hair, trousers, shoes, jitter, then the
        palette's own tops), so a seed gives the same crowd on every machine.
    top : (n, 3) float
        Linear RGB of each top, drawn by the caller; used unless the named
        palette has tops of its own. A group colour tints it afterwards (:func:`tint`).
    palette : str
        A name of :data:`PALETTES`.

    Returns
    -------
    (n, r, 3) float64
        Linear RGB in [0, 1], rows in REGIONS order.
    """
    table = PALETTES[palette]
    top = np.asarray(top, dtype=np.float64).reshape(-1, 3)
    n = len(top)
    drawn = {"skin": SKIN_ALBEDO * _pick(rng, _SKIN, n), "hair": _pick(rng, _HAIR, n),
             "trousers": _pick(rng, table["trousers"], n), "shoes": _pick(rng, table["shoes"], n)}
    jittered = [k for k, name in enumerate(REGIONS) if name not in _FIXED]
    gain = np.exp(JITTER * rng.standard_normal((n, len(jittered))))
    if table["tops"] is not None:
        top = _pick(rng, table["tops"], n)
    drawn.update({name: np.broadcast_to(srgb_to_linear([h])[0], (n, 3)) for name, h in _FIXED.items()})
    out = np.stack([top if name == "top" else drawn[name] for name in REGIONS], axis=1)
    out[:, jittered[1:]] *= gain[:, 1:, None]   # the top is the caller's, untouched; fixed rows are alike
    return np.clip(out, 0.0, 1.0)


def tint(top: np.ndarray, color: np.ndarray, weight: float = GROUP_TINT) -> np.ndarray:
    """(n, 3) tops pulled towards an authored group colour (linear blend)."""
    return (1.0 - weight) * np.asarray(top, dtype=np.float64) + weight * np.asarray(color, dtype=np.float64)


def plain_palettes(top: np.ndarray) -> np.ndarray:
    """(n, r, 3) palettes of the given tops with fixed, ordinary other regions.

    For agents whose stage authors a single colour (a constant displayColor):
    that colour is the top, as it was the whole body's before palettes.
    """
    top = np.asarray(top, dtype=np.float64).reshape(-1, 3)
    fixed = {name: srgb_to_linear([h])[0] for name, h in _PLAIN.items()}
    return np.stack([top if name == "top" else np.broadcast_to(fixed[name], top.shape) for name in REGIONS], axis=1)


def fit_problem(n_colours: int, rows: int) -> str | None:
    """What is wrong with a body's ``n_colours`` displayColor values for indices asking for ``rows``, or None.

    One colour dresses the whole body; otherwise there is one per row.
    """
    if n_colours in (1, rows):
        return None
    return f"has {n_colours} colours but the body's indices ask for {rows} (or 1 for the whole body)"
