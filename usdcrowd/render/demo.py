"""What ``usdcrowd demo`` shows of a shot: a couple of final frames with ground truth, and a short
preview. Kept out of the renderers' packages, which know nothing of the demo."""

from __future__ import annotations

import os
from pathlib import Path


def final_outputs(shot_path, out_dir, camera: str | None = None, frames=(1.0, 2.0),
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

    from .sequence import frame_files, render_sequence
    from .settings import settings_from_preset

    settings = settings_from_preset("groundtruth", resolution=tuple(resolution), spp=int(spp))
    r = render_sequence(shot_path, out_dir, camera=camera, frames=np.asarray(frames, dtype=np.float64),
                        settings=settings, executor="inline", progress=False)
    first = frame_files(r.times[0], True)
    out = Path(out_dir)
    paths = {"frame_png": os.fspath(out / first["png"]), "exr": os.fspath(out / first["exr"]),
             "frame_json": os.fspath(out / first["json"]), **r.outputs}
    paths["variant"] = r.variant
    return paths


def preview_outputs(shot_path, out_dir, camera=None, resolution=(640, 360), frames=None,
                 progress: bool = False) -> dict[str, str]:
    """Write a short preview MP4 and a contact sheet of a shot.

    Parameters
    ----------
    shot_path : path-like
        The shot stage.
    out_dir : path-like
        Folder for ``preview.mp4`` and ``preview_sheet.png``.
    camera : str, optional
        Camera prim path (default: the stage's first camera).
    resolution : (int, int)
        Width, height.
    frames : array of time codes, optional
        Default: the first 48 frames of the stage's range.
    progress : bool
        Show a progress bar.

    Returns
    -------
    dict
        ``{"mp4": path, "contact_sheet": path}``.
    """
    from .preview.output import render_shot

    kw = {} if frames is None else {"frames": frames, "max_frames": len(frames)}
    return render_shot(shot_path, out_dir, camera=camera, resolution=resolution, progress=progress, **kw)
