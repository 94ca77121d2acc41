"""Fast OpenGL preview of a shot: headless through EGL (Mesa's llvmpipe is
enough) or in a glfw window.

moderngl, glfw and imageio are optional (``usdcrowd[preview]``) and imported
only where used.
"""

from __future__ import annotations

from .lod import LodSettings
from .renderer import PreviewFrame, PreviewRenderer, boxes_from_ids

__all__ = ["LodSettings", "PreviewFrame", "PreviewRenderer", "boxes_from_ids"]
