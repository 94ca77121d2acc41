"""Fast OpenGL preview of a shot: headless through EGL (Mesa's llvmpipe is
enough) or in a glfw window.

moderngl, glfw and imageio are optional (``usdcrowd[preview]``) and imported
only where used.
"""

from __future__ import annotations

from .lod import LodSettings
from .renderer import PreviewFrame, PreviewRenderer, boxes_from_ids

__all__ = ["LodSettings", "PreviewFrame", "PreviewRenderer", "boxes_from_ids", "demo_outputs"]


def demo_outputs(shot_path, out_dir, camera=None, resolution=(640, 360), frames=None,
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
    from .output import render_shot

    kw = {} if frames is None else {"frames": frames, "max_frames": len(frames)}
    return render_shot(shot_path, out_dir, camera=camera, resolution=resolution, progress=progress, **kw)
