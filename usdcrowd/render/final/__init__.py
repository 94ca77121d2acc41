"""Final frames with Mitsuba 3: physically based beauty and exact ground truth.

Modules, in the order a frame flows through them:

- :mod:`.variant`   which Mitsuba variant (cuda, llvm, scalar), probed safely;
- :mod:`.materials` UsdPreviewSurface -> principled BSDF;
- :mod:`.lights`    UsdLux -> emitters (the radiometric mapping);
- :mod:`.camera`    UsdGeom.Camera -> sensor, and the ground-truth pixel rays;
- :mod:`.meshes`    numpy -> ``mi.Mesh`` carrying ground-truth ids;
- :mod:`.build`     the shot -> one Mitsuba scene, once per sequence;
- :mod:`.frame`     per frame: update, beauty, ground-truth passes;
- :mod:`.exr`       the multi-channel EXR of a frame.

Mitsuba, Dr.Jit and OpenEXR are imported inside the functions that use them.
"""

from __future__ import annotations

import os
from pathlib import Path


def demo_outputs(shot_path, out_dir, camera: str | None = None, frames=(1.0, 2.0),
                 resolution=(320, 180), spp: int = 16) -> dict[str, str]:
    """Render a couple of frames of a shot with ground truth, for the demo.

    Parameters
    ----------
    shot_path : path-like
        A shot stage (``shot.usda``).
    out_dir : path-like
        Output folder (see :mod:`usdcrowd.render.sequence` for its layout).
    camera : str, optional
        Camera prim path (default: the first camera).
    frames : sequence of float
        Time codes to render.
    resolution : (int, int)
    spp : int

    Returns
    -------
    dict of str -> str
        ``frame_png``, ``exr``, ``frame_json``, ``contact_sheet``, ``mot``
        (the MOTChallenge folder), ``coco``, ``manifest``, and ``variant``
        (the Mitsuba variant's name, not a path).
    """
    import numpy as np

    from ..sequence import frame_files, render_sequence, settings_from_preset

    settings = settings_from_preset("groundtruth", resolution=tuple(resolution), spp=int(spp))
    r = render_sequence(shot_path, out_dir, camera=camera, frames=np.asarray(frames, dtype=np.float64),
                        settings=settings, executor="inline", progress=False)
    first = frame_files(r.times[0], True)
    out = Path(out_dir)
    paths = {"frame_png": os.fspath(out / first["png"]), "exr": os.fspath(out / first["exr"]),
             "frame_json": os.fspath(out / first["json"]), **r.outputs}
    paths["variant"] = r.variant
    return paths
