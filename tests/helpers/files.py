"""What a folder holds, to see that a command left it untouched."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path


def digest_tree(folder: Path) -> dict[str, str]:
    """sha256 of every file under ``folder`` (usdcrowd's state folder left out)."""
    return {os.fspath(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and ".usdcrowd" not in p.parts}
