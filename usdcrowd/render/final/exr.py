"""One multi-channel OpenEXR per frame: beauty, ground truth and the id table.

Channels (single part, scanline, ZIP; float32 unless said):

==============================  =========================================
``R``, ``G``, ``B``             beauty, linear, working-space primaries
``depth.z``                     distance along the view axis, m (+inf: sky)
``depth.distance``              distance to the camera centre, m (+inf: sky)
``normal.X/Y/Z``                world shading normal facing the camera
``position.X/Y/Z``              world position, Z-up metres
``albedo.R/G/B``                diffuse reflectance, linear
``id``                          uint32: track id, scenery id or 0
==============================  =========================================

Header attributes: ``usdcrowd:idTable`` (JSON object, id -> prim path),
``usdcrowd:camera``, ``usdcrowd:time``, ``usdcrowd:workingSpace``,
``usdcrowd:renderSettings`` (JSON: the settings that change pixels),
``usdcrowd:depthConvention``.
"""

from __future__ import annotations

import json
import os

import numpy as np

from ...atomic import atomic_path
from ...core.errors import UsdcrowdError

BEAUTY = ("R", "G", "B")
RAW_BEAUTY = ("raw.R", "raw.G", "raw.B")        # the path-traced beauty, where R, G, B hold it denoised
GROUND_TRUTH = ("depth.z", "depth.distance", "normal.X", "normal.Y", "normal.Z", "position.X", "position.Y",
                "position.Z", "albedo.R", "albedo.G", "albedo.B", "id")
ID_TABLE = "usdcrowd:idTable"


def require_openexr():
    """Import and return the ``OpenEXR`` module, or raise a one-line UsdcrowdError."""
    try:
        import OpenEXR
    except ImportError:
        raise UsdcrowdError("EXR output needs OpenEXR >= 3.2: pip install 'usdcrowd[final]'") from None
    return OpenEXR


def channels_of(beauty: np.ndarray, gt=None, raw: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Name -> (h, w) array for :func:`write_frame_exr`.

    Parameters
    ----------
    beauty : (h, w, 3) float
        The final beauty (denoised where it was).
    gt : GroundTruth, optional
    raw : (h, w, 3) float, optional
        The path-traced beauty before denoising (``raw.R``, ``raw.G``, ``raw.B``).
    """
    ch = {name: np.ascontiguousarray(beauty[..., k], dtype=np.float32) for k, name in enumerate(BEAUTY)}
    if raw is not None:
        ch.update({name: np.ascontiguousarray(raw[..., k], dtype=np.float32) for k, name in enumerate(RAW_BEAUTY)})
    if gt is not None:
        ch["depth.z"] = gt.depth_z.astype(np.float32)
        ch["depth.distance"] = gt.depth_distance.astype(np.float32)
        for layer, arr, comps in (("normal", gt.normal, "XYZ"), ("position", gt.position, "XYZ"),
                                  ("albedo", gt.albedo, "RGB")):
            for k, c in enumerate(comps):
                ch[f"{layer}.{c}"] = np.ascontiguousarray(arr[..., k], dtype=np.float32)
        ch["id"] = gt.ids.astype(np.uint32)
    return ch


def write_frame_exr(path, channels: dict[str, np.ndarray], id_paths: dict[int, str] | None = None,
                    attributes: dict[str, str | float] | None = None) -> str:
    """Write one frame's channels to ``path`` atomically (temporary name, then rename).

    Parameters
    ----------
    path : path-like
    channels : dict of str -> (h, w) float32 or uint32
    id_paths : dict of int -> str, optional
        Stored as the JSON header attribute ``usdcrowd:idTable``.
    attributes : dict, optional
        More header attributes (strings or floats).
    """
    OpenEXR = require_openexr()
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    if id_paths is not None:
        header[ID_TABLE] = json.dumps({str(k): v for k, v in sorted(id_paths.items())})
    for k, v in (attributes or {}).items():
        header[k] = v if isinstance(v, str) else float(v)
    with atomic_path(path) as tmp:
        with OpenEXR.File(header, channels) as f:
            f.write(os.fspath(tmp))
    return os.fspath(path)


def read_frame_exr(path, header_only: bool = False) -> tuple[dict, dict[str, np.ndarray]]:
    """Read a frame EXR: (header dict, name -> (h, w) array); the id table is decoded to ``{int: str}``.

    Raises
    ------
    UsdcrowdError
        If the file cannot be read as OpenEXR.
    """
    OpenEXR = require_openexr()
    try:
        with OpenEXR.File(os.fspath(path), separate_channels=True, header_only=header_only) as f:
            header = dict(f.header())
            channels = {} if header_only else {k: v.pixels for k, v in f.channels().items()}
    except Exception as exc:            # OpenEXR raises plain RuntimeError on damaged files
        raise UsdcrowdError(f"not a readable EXR ({exc})", file=os.fspath(path)) from None
    if ID_TABLE in header:
        header[ID_TABLE] = {int(k): v for k, v in json.loads(header[ID_TABLE]).items()}
    return header, channels


def channel_names(header: dict) -> list[str]:
    """Names of the channels listed in a header read by :func:`read_frame_exr`."""
    return [c.name for c in header.get("channels", [])]
