"""Display transforms: scene-referred linear light -> 8-bit pictures, through colour-science.

Renders are linear light. Mitsuba's ``*_rgb`` variants work in linear
Rec.709/sRGB primaries; a render may optionally be stored in ACEScg
(AP1 primaries, linear) as the working space. Pictures for people (PNG
frames, contact sheets, MP4) are made by one transform:

1. exposure: multiply by ``2 ** exposure`` (stops);
2. working space -> sRGB primaries (colour-science's RGB_to_RGB with CAT
   where the white points differ: ACEScg is D60, sRGB D65);
3. clip to [0, 1] and encode with the sRGB transfer function
   (``colour.cctf_encoding``), quantise to 8 bits.

No hand-written gamma anywhere.
"""

from __future__ import annotations

import numpy as np

WORKING_SPACES = ("sRGB", "ACEScg")
# Mitsuba's RGB variants render in linear sRGB (Rec.709) primaries.
RENDER_SPACE = "sRGB"


def _space(name: str):
    import colour

    if name not in WORKING_SPACES:
        raise ValueError(f"working space must be one of {WORKING_SPACES}, not {name!r}")
    return colour.RGB_COLOURSPACES[name]


def convert(rgb: np.ndarray, source: str, target: str) -> np.ndarray:
    """Linear RGB from one working space's primaries to another's.

    Parameters
    ----------
    rgb : (..., 3) float
        Linear values.
    source, target : str
        "sRGB" or "ACEScg".

    Returns
    -------
    (..., 3) float32
    """
    if source == target:
        return np.asarray(rgb, dtype=np.float32)
    import colour

    out = colour.RGB_to_RGB(np.asarray(rgb, dtype=np.float64), _space(source), _space(target),
                            chromatic_adaptation_transform="CAT02")
    return out.astype(np.float32)


def to_display(rgb: np.ndarray, working_space: str = RENDER_SPACE, exposure: float = 0.0) -> np.ndarray:
    """Linear scene-referred RGB -> 8-bit sRGB for display.

    Parameters
    ----------
    rgb : (h, w, 3) float
        Linear light in ``working_space``.
    working_space : str
        "sRGB" (Mitsuba's output) or "ACEScg".
    exposure : float
        Stops: the image is multiplied by ``2 ** exposure`` first.

    Returns
    -------
    (h, w, 3) uint8
    """
    from ..core.srgb import srgb8

    linear = np.nan_to_num(np.asarray(rgb, dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0) * 2.0 ** exposure
    return srgb8(convert(linear, working_space, "sRGB"))


def write_png(rgb: np.ndarray, path, working_space: str = RENDER_SPACE, exposure: float = 0.0) -> str:
    """Write the display transform of ``rgb`` (h, w, 3 linear) as an sRGB PNG, atomically."""
    import os

    from PIL import Image

    from ..atomic import atomic_path

    with atomic_path(path) as tmp:
        Image.fromarray(to_display(rgb, working_space, exposure)).save(tmp, format="PNG")
    return os.fspath(path)


def write_mp4(frames_rgb8: list, path, fps: float = 24.0) -> str:
    """Encode 8-bit display frames (each (h, w, 3) uint8) as an H.264 MP4 (needs imageio-ffmpeg).

    Raises
    ------
    UsdcrowdError
        If imageio / imageio-ffmpeg are not installed.
    """
    import os

    from ..atomic import atomic_path
    from ..core.errors import UsdcrowdError

    try:
        import imageio.v2 as imageio
        import imageio_ffmpeg  # noqa: F401
    except ImportError:
        raise UsdcrowdError("MP4 output needs imageio and imageio-ffmpeg: pip install 'usdcrowd[preview]'") from None
    with atomic_path(path) as tmp:
        # yuv420p for players; macro_block_size=1 keeps odd sizes instead of resizing the frames.
        with imageio.get_writer(os.fspath(tmp), format="FFMPEG", fps=fps, codec="libx264", quality=8,
                                pixelformat="yuv420p", macro_block_size=1) as writer:
            for frame in frames_rgb8:
                writer.append_data(np.asarray(frame, dtype=np.uint8))
    return os.fspath(path)
