"""Where the data folders (schemas/, stages/, render/) are.

In a wheel they sit inside the package as ``usdcrowd/_data/<name>``; in a
source checkout (editable install, CI) at the top level of the repository.
"""

from __future__ import annotations

from pathlib import Path

_PACKAGE = Path(__file__).resolve().parents[1]          # usdcrowd/, above core/


def data_dir(name: str) -> Path:
    """Return the folder ``name`` ("schemas", "stages" or "render").

    Raises
    ------
    FileNotFoundError
        If neither the installed nor the checkout location exists.
    """
    for candidate in (_PACKAGE / "_data" / name, _PACKAGE.parent / name):
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError(f"usdcrowd data folder {name!r} not found next to {_PACKAGE}")
