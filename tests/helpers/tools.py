"""The scripts in tools/, loaded from their files (tools/ is no package)."""

from __future__ import annotations

import importlib.util
from types import ModuleType

from tests.helpers.paths import TOOLS


def load_tool(name: str) -> ModuleType:
    """``tools/<name>.py`` as a fresh module (its top level runs again at each call)."""
    spec = importlib.util.spec_from_file_location(name, TOOLS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
