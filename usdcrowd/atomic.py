"""Outputs appear whole or not at all: write to a temporary name, then rename."""

from __future__ import annotations

import contextlib
import os
import shutil
import uuid
from pathlib import Path

from .guard import PARTIAL_NAME          # the temporary names atomic_path makes


@contextlib.contextmanager
def atomic_path(final: str | os.PathLike):
    """Yield a temporary path next to ``final``; rename it over ``final`` on success.

    The temporary name keeps ``final``'s extension (USD picks the file format
    from it). On any exception the temporary file is removed and ``final`` is
    left untouched.
    """
    import errno

    import signal

    from . import guard
    from .interrupts import signals_held

    final = Path(final)
    guard.check_write(final)
    for folder in (final.parent, *final.parent.parents):
        if folder.exists():
            if not folder.is_dir():          # "x.usda" under /dev/null, or under a file
                raise OSError(errno.ENOTDIR, "is not a folder, so nothing can be written in it", os.fspath(folder))
            break
    guard.make_dir(final.parent)            # a new folder in an output folder is recorded as usdcrowd's
    tmp = final.with_name(f".{final.stem}.partial-{uuid.uuid4().hex[:8]}{final.suffix}")
    try:
        yield tmp
        guard.check_write(final)            # again: a long write (a video) gives others time to put a file there
        with signals_held(signal.SIGINT, signal.SIGTERM):   # a kill between the rename and its record
            # would leave a file the record does not know, refused as someone else's for ever
            guard.will_write(tmp, final)
            os.replace(tmp, final)
            guard.wrote(final)
    except OSError as exc:
        if exc.filename in (None, os.fspath(tmp)):      # name the file the user asked for, not ours
            raise OSError(exc.errno, exc.strerror, os.fspath(final)) from None
        raise
    finally:
        if tmp.exists():
            tmp.unlink()


@contextlib.contextmanager
def restored_on_failure(paths):
    """Within, the files ``paths`` may be replaced one by one; if the block fails (an error, Ctrl-C, kill)
    each is put back as it was, and those that did not exist are removed.

    The previous files are kept as hard links under temporary names (no copy of the bytes), which a
    later run's :func:`clean_partials` removes if this process is killed outright.
    """
    kept = {}
    try:
        for path in map(Path, paths):
            backup = path.with_name(f".{path.stem}.previous.partial-{uuid.uuid4().hex[:8]}{path.suffix}")
            if path.is_dir() and not path.is_symlink():     # a clip folder: its files linked one by one
                shutil.copytree(path, backup, copy_function=_link_or_copy)
                kept[path] = backup
            elif path.is_file():
                _link_or_copy(path, backup)
                kept[path] = backup
            else:
                kept[path] = None
        yield
    except BaseException:
        for path, backup in kept.items():
            with contextlib.suppress(OSError):
                _put_back(path, backup)
        raise
    else:
        for backup in kept.values():
            if backup is not None:
                with contextlib.suppress(OSError):
                    shutil.rmtree(backup) if backup.is_dir() else backup.unlink()


def _link_or_copy(src, dst) -> None:
    try:
        os.link(src, dst)
    except OSError:                         # no hard links here (some network or FUSE file systems)
        shutil.copy2(src, dst)


def _put_back(path: Path, backup: Path | None) -> None:
    """``path`` as ``backup`` holds it (removed when there was nothing before)."""
    if backup is None:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        elif path.exists():
            path.unlink()
    elif backup.is_dir():
        if path.exists():
            shutil.rmtree(path)
        os.replace(backup, path)
    elif path.exists() and os.path.samefile(backup, path):
        backup.unlink()                     # never replaced (a rename over its own hard link does nothing)
    else:
        os.replace(backup, path)


def file_sha256(path: str | os.PathLike) -> str:
    """The sha256 of a file's bytes, read a megabyte at a time."""
    import hashlib

    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def clean_partials(folder: str | os.PathLike, depth: int = 2) -> int:
    """Remove the temporary files an interrupted run left in ``folder`` (and its subfolders, ``depth`` deep).

    Only names :func:`atomic_path` makes are touched (files, and the
    temporary clip folders named the same way). Returns how many were removed.
    """
    removed = 0
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return 0
    for entry in entries:
        if entry.is_dir(follow_symlinks=False) and PARTIAL_NAME.match(entry.name):
            shutil.rmtree(entry.path, ignore_errors=True)       # a clip folder (usdcrowd.usd.clips)
            removed += 1
        elif (entry.is_dir(follow_symlinks=False) and depth > 0
              and not os.path.isdir(os.path.join(entry.path, ".usdcrowd"))):
            # (an output folder of its own is cleaned by its own runs: another may be writing in it now)
            removed += clean_partials(entry.path, depth - 1)
        elif entry.is_file(follow_symlinks=False) and PARTIAL_NAME.match(entry.name):
            with contextlib.suppress(OSError):
                os.unlink(entry.path)
                removed += 1
    return removed


def output_dir(path: str | os.PathLike, what: str | None = None) -> Path:
    """The folder ``path``, created if needed; a one-line error if it cannot be an output folder.

    Inside a command's :func:`usdcrowd.guard.session` the folder is claimed
    first: locked against a second run, and refused when it holds what
    usdcrowd did not write (unless ``--force``) or another kind of output
    (``what``: "shot", "render"...). Then what an interrupted
    run left there half-written (temporary ``.partial`` files) is removed.

    Raises
    ------
    UsdcrowdError
        ``path`` exists and is not a folder (a file, /dev/null), cannot be
        created, or cannot be written to.
    """
    from . import guard
    from .core.errors import UsdcrowdError

    out = Path(path)
    if out.exists() and not out.is_dir():
        raise UsdcrowdError("exists and is not a folder: give a folder for the outputs", file=os.fspath(out))
    guard.check_not_input(out, "output folder")
    guard.check_free(out)
    try:
        guard.make_dir(out)
    except OSError as exc:
        raise UsdcrowdError(f"cannot create the output folder: {exc.strerror}", file=os.fspath(out)) from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise UsdcrowdError("cannot write to the output folder: permission denied", file=os.fspath(out))
    guard.claim(out, what)      # locked for this run before anything in it is touched
    clean_partials(out)
    return out


def export_layer(layer, final: str | os.PathLike) -> str:
    """Save an Sdf layer to ``final`` atomically; a failed write is one clear error.

    USD reports a failed save (a full disk) as a Tf error carrying thousands
    of lines; it becomes an OSError (ENOSPC when the disk is full) naming the
    file, and nothing is left half-written.
    """
    import errno

    from pxr import Tf

    final = os.fspath(final)
    with atomic_path(final) as tmp:
        try:
            ok = layer.Export(os.fspath(tmp))
        except Tf.ErrorException as exc:
            ok, detail = False, str(exc).strip().splitlines()
        else:
            detail = []
        if not ok:
            try:
                full = shutil.disk_usage(os.path.dirname(os.path.abspath(final))).free < 1 << 20
            except OSError:
                full = False
            if full:
                raise OSError(errno.ENOSPC, "no space left on device", final)
            raise OSError(errno.EIO, f"USD could not save the layer{': ' + detail[0] if detail else ''}", final)
    return final
