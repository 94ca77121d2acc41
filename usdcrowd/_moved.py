"""Modules that moved, still importable by their old names with a DeprecationWarning.

``usdcrowd.pipeline`` is now ``usdcrowd.jobs.pipeline``, ``usdcrowd.model`` is
``usdcrowd.core.model``, and so on (:data:`MOVED`): code written against the
old layout keeps working, and is told where things are now.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import warnings

MOVED = {
    **{f"usdcrowd.{name}": f"usdcrowd.core.{name}" for name in (
        "errors", "limits", "tolerances", "model", "view", "shading", "geometry", "framestore", "resources")},
    **{f"usdcrowd.{name}": f"usdcrowd.jobs.{name}" for name in (
        "pipeline", "filming", "toric_filming", "templates", "summary", "validation", "plots")},
    "usdcrowd.poses": "usdcrowd.character.poses",
    "usdcrowd.render.scene": "usdcrowd.scenario.shot_scene",
    "usdcrowd.scenery": "usdcrowd.scenario.scenery",
}


class _Alias(importlib.abc.Loader):
    def __init__(self, new: str):
        self.new = new

    def create_module(self, spec):
        warnings.warn(f"{spec.name} moved to {self.new}; import it from there", DeprecationWarning, stacklevel=3)
        return importlib.import_module(self.new)

    def exec_module(self, module):
        pass


class _Finder(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname, path=None, target=None):
        new = MOVED.get(fullname)
        return importlib.util.spec_from_loader(fullname, _Alias(new)) if new else None


def install() -> None:
    """Put the finder on ``sys.meta_path`` (once)."""
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.append(_Finder())
