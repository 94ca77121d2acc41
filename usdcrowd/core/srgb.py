"""8-bit sRGB for display: the IEC 61966-2-1 transfer function."""

from __future__ import annotations

import numpy as np


def srgb8(linear: np.ndarray) -> np.ndarray:
    """Linear RGB in [0, 1] to 8-bit sRGB with the IEC 61966-2-1 encoding.

    The one sRGB encoder of the package (pictures, previews, final PNGs). Written out
    rather than taken from colour-science: importing colour costs 1.4 s, which every
    ``simulate`` paid for a few thousand colours (tests/render/preview/test_preview.py checks
    it against colour.cctf_encoding).
    """
    c = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
    encoded = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)
    return np.round(encoded * 255).astype(np.uint8)
