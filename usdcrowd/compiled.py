"""numba's on-disk cache, kept in step with the constants compiled loops freeze.

numba keys the machine code it caches (``cache=True``) on the source file of
the compiled functions alone, and freezes into it the module-level values
they read. The crowd step's loops (:mod:`usdcrowd.sim.kernels`) read their
constants from :mod:`usdcrowd.sim.params`, the pose's
(:mod:`usdcrowd.character.kernels`) from :mod:`usdcrowd.character.gait` and
the rig: edit one of those, and numba would go on running the old values.
Each kernel module therefore calls :func:`forget_stale_machine_code` with the
modules it reads before any loop runs: when their constants differ from the
ones the cached code was built with, that code is deleted and built again.
"""

from __future__ import annotations

import hashlib
import os
from types import ModuleType

import numpy as np


def constants_digest(*modules: ModuleType) -> str:
    """sha256 of the upper-case names of ``modules`` and their values (arrays by their bytes)."""
    digest = hashlib.sha256()
    for module in modules:
        for name in sorted(n for n in vars(module) if n.isupper()):
            value = getattr(module, name)
            digest.update(f"{module.__name__}.{name}={type(value).__name__}:".encode())
            digest.update(np.asarray(value).tobytes() if isinstance(value, np.ndarray) else repr(value).encode())
    return digest.hexdigest()


def forget_stale_machine_code(module_file: str, *sources: ModuleType) -> bool:
    """Delete the cached machine code of the module at ``module_file`` if ``sources``' constants changed.

    The digest of the constants the cache was built with is kept beside it
    (``__pycache__/<module>.constants``). Returns whether anything was deleted.
    Where the folder cannot be written (an installed, read-only package, whose
    constants nobody edits) nothing is done: numba then caches elsewhere.
    """
    folder = os.path.join(os.path.dirname(os.path.abspath(module_file)), "__pycache__")
    stem = os.path.splitext(os.path.basename(module_file))[0]
    stamp = os.path.join(folder, f"{stem}.constants")
    key = constants_digest(*sources)
    try:
        with open(stamp, encoding="ascii") as f:
            if f.read() == key:
                return False
    except OSError:
        pass
    deleted = False
    try:
        os.makedirs(folder, exist_ok=True)
        for name in os.listdir(folder):
            if name.startswith(f"{stem}.") and name.endswith((".nbi", ".nbc")):
                os.unlink(os.path.join(folder, name))
                deleted = True
        # Written whole or not at all: another process may be reading it.
        partial = f"{stamp}.{os.getpid()}"
        with open(partial, "w", encoding="ascii") as f:
            f.write(key)
        os.replace(partial, stamp)
    except OSError:
        pass
    return deleted
