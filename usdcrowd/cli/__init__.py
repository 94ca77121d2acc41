"""The ``usdcrowd`` command line.

Each command lives in its own module with ``add_parser(subparsers)`` and
``run(args) -> int``. A user's mistake (a :class:`~usdcrowd.core.errors.UsdcrowdError`)
prints one line and exits 2; a bug still shows its traceback.
"""

from __future__ import annotations

import argparse
import errno
import os
import sys

from .. import __version__
from ..core.errors import UsdcrowdError
from ..interrupts import Terminated, stops_as_exceptions
from . import (cameras, dataset, demo, edit, export, features, frame, inspect_cmd, metrics, new, place, preview,
               render, replay, simulate, validate)

COMMANDS = (new, inspect_cmd, validate, simulate, replay, cameras, frame, edit, metrics, features, preview, render,
            export, place, dataset, demo)
EXIT_USER_ERROR = 2
# OSErrors that are the environment's (reported in one line), not a bug.
_ENVIRONMENT_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.ENOENT,
                       errno.EIO, errno.EMFILE, errno.ENOTDIR, errno.EEXIST, errno.EISDIR}


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors, like every other user mistake."""

    commands: dict = {}     # the top level's: each command's own parser, by name

    def error(self, message):
        self.exit(EXIT_USER_ERROR, f"{self.prog}: error: {message} (see --help)\n")

    def parse_args(self, args=None, namespace=None):
        # A word the command does not take is that command's mistake: `usdcrowd simulate: error: ...`.
        parsed, extra = self.parse_known_args(args, namespace)
        if extra:
            self.commands.get(getattr(parsed, "command", None), self).error(
                f"unrecognized arguments: {' '.join(extra)}")
        return parsed


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="usdcrowd",
        description="Crowd scenes described in USD: simulated, filmed and rendered with exact ground truth.")
    parser.add_argument("--version", action="version", version=f"usdcrowd {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True, parser_class=_Parser)
    for module in COMMANDS:
        module.add_parser(sub)
    parser.commands = sub.choices
    return parser


def _named(args, names) -> list:
    """The paths the options ``names`` hold (an option may hold several)."""
    found = []
    for name in names:
        value = getattr(args, name, None)
        if value is not None:
            found += list(value) if isinstance(value, (list, tuple)) else [value]
    return found


def _run_guarded(args) -> int:
    """The command inside a guard session: its inputs are never written, its outputs only where it may."""
    from .. import guard

    files = _named(args, getattr(args, "outputs", ()))
    folders = _named(args, getattr(args, "output_folders", ()))
    with guard.session(_named(args, getattr(args, "inputs", ())), outputs=files + folders,
                       force=getattr(args, "force", False), command=args.command):
        # Before any work, not when the output is finally written (folders are checked as they are claimed).
        for path in files + folders:
            guard.check_not_input(path)
        for path in files:
            if not os.path.isdir(path):
                guard.check_write(path)
        _warn_if_stale(args)
        return int(args.run(args) or 0)


def _warn_if_stale(args) -> None:
    """A shot whose scenario changed since simulate: every command that reads it says so (one line)."""
    import stat

    from ..usd.shot import stale_scenario

    for path in _named(args, getattr(args, "inputs", ())):
        try:
            if not (stat.S_ISREG(os.stat(path).st_mode) and str(path).endswith((".usd", ".usda", ".usdc"))):
                continue
        except OSError:
            continue
        why = stale_scenario(path)
        if why:
            print(f"usdcrowd {args.command}: warning: {path}: {why}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit code."""
    args = None
    try:
        with stops_as_exceptions():         # from the start: a stop never lands in Python's default handlers
            parser = build_parser()
            try:
                args = parser.parse_args(argv)
            except SystemExit as exc:       # a usage error (printed), --help or --version: an exit code, as the rest
                return int(exc.code or 0)
            return _run_reported(args)
    except (KeyboardInterrupt, Terminated) as exc:
        return _after_a_stop(getattr(args, "command", None) or "", exc)


def _run_reported(args) -> int:
    """The command, with a user's mistake or the machine's failure said in one line."""
    try:
        return _run_guarded(args)
    except UsdcrowdError as exc:
        print(f"usdcrowd {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_USER_ERROR
    except BrokenPipeError:
        # The reader stopped reading (`inspect ... | head`): nothing left to say, and Python's own
        # flush at exit must not fail on the closed pipe either.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:
        # The machine, not the code: a full disk, a read-only or vanished folder.
        if exc.errno not in _ENVIRONMENT_ERRNOS:
            raise
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"usdcrowd {args.command}: error: {where}{(exc.strerror or str(exc)).lower()}", file=sys.stderr)
        return EXIT_USER_ERROR


def _after_a_stop(command: str, stop: BaseException) -> int:
    """Say in one line that ``command`` was stopped (Ctrl-C: 130, SIGTERM: 143) and free now what the stopped
    work left in reference cycles (USD layers and stages among them), while USD is whole: left to the
    interpreter's exit, they would be destroyed after USD's own statics."""
    import gc

    how, code = ("interrupted", 130) if isinstance(stop, KeyboardInterrupt) else ("terminated", 143)
    who = f"usdcrowd {command}" if command else "usdcrowd"      # stopped before its command was read
    print(f"{who}: {how} (finished outputs kept; run it again to resume)", file=sys.stderr)
    gc.collect()
    return code


if __name__ == "__main__":
    sys.exit(main())
