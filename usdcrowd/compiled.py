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

numba's cache is also not safe to share between processes as it stands: an
overload is saved as an index (signature to file) written before its data
file, each read, changed and written back whole, so two runs compiling at
once can point one's index at the other's data, and a stop that lands
between the two leaves them out of step. A run that then loads the pair
crashes inside LLVM (a segmentation fault, no traceback). Each kernel
module therefore ends with :func:`cache_one_process_at_a_time`: every load
and save of its machine code holds a lock on the cache folder and defers
Ctrl-C and SIGTERM until it is done (waiting for the lock and a compile
itself stay interruptible).
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import signal
import threading
from types import ModuleType

import numpy as np

try:
    import fcntl
except ImportError:         # not POSIX: numba's cache goes unlocked there
    fcntl = None

LOCK_NAME = "usdcrowd-machine-code.lock"


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
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError:
        return False
    with cache_folder_held(folder):
        try:
            with open(stamp, encoding="ascii") as f:
                if f.read() == key:         # another run did it while this one waited
                    return False
        except OSError:
            pass
        return _forget(folder, stem, stamp, key)


def _forget(folder: str, stem: str, stamp: str, key: str) -> bool:
    deleted = False
    try:
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


_held = threading.local()    # .folders: those this thread holds (a module's kernels share one folder)


@contextlib.contextmanager
def cache_folder_held(folder: str):
    """Within: no other process reads or writes numba's cache in ``folder``, and Ctrl-C and SIGTERM
    wait (they are delivered on leaving). Waiting for the lock can be interrupted; where the lock cannot
    be had (no lock file, a file system without locks), only the signals wait."""
    from .interrupts import signals_held

    folders = _held.__dict__.setdefault("folders", set())
    fd = None
    if fcntl is not None and folder not in folders:
        try:
            fd = os.open(os.path.join(folder, LOCK_NAME), os.O_RDWR | os.O_CREAT, 0o666)
        except OSError:
            fd = None
        try:
            if fd is not None:
                fcntl.flock(fd, fcntl.LOCK_EX)
        except BaseException as exc:     # no locks here (carry on unlocked), or a stop while waiting
            os.close(fd)
            fd = None
            if not isinstance(exc, OSError):
                raise
    try:
        if fd is not None:
            folders.add(folder)
        with signals_held(signal.SIGINT, signal.SIGTERM):
            yield
    finally:
        if fd is not None:
            folders.discard(folder)
            os.close(fd)            # closing releases the lock


def _held_while(method, folder: str):
    def call(*args, **kwargs):
        with cache_folder_held(folder):
            return method(*args, **kwargs)
    call.__wrapped__ = method
    return call


def cache_one_process_at_a_time(namespace: dict) -> int:
    """Make every load and save of the cached machine code of the numba functions in ``namespace`` (a
    module's ``globals()``; a loop's ``serial`` and ``parallel`` twins too) hold the cache folder
    (:func:`cache_folder_held`). Returns how many functions were guarded."""
    from numba.core.dispatcher import Dispatcher

    found = []
    for value in list(namespace.values()):
        found += [d for d in (value, getattr(value, "serial", None), getattr(value, "parallel", None))
                  if isinstance(d, Dispatcher)]
    guarded = 0
    for dispatcher in found:
        cache = getattr(dispatcher, "_cache", None)       # numba's FunctionCache; NullCache: not cached
        folder = getattr(cache, "cache_path", None)
        if folder is None or hasattr(cache.load_overload, "__wrapped__"):
            continue
        cache.load_overload = _held_while(cache.load_overload, folder)
        cache.save_overload = _held_while(cache.save_overload, folder)
        guarded += 1
    return guarded
