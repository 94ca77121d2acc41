"""Argument groups shared by the commands (after usdrecord): frames, camera,
resolution, seed, output."""

from __future__ import annotations

import argparse
import re

import numpy as np

# Frames a --frames spec may name at all (--max-frames then bounds a shot's length).
MAX_FRAME_SPEC = 10_000_000
_FRAMES = re.compile(r"^\s*(-?\d+(?:\.\d+)?)\s*(?::\s*(-?\d+(?:\.\d+)?)\s*(?:x\s*(\d+(?:\.\d+)?))?)?\s*$")


def parse_frames(spec: str) -> np.ndarray:
    """Time codes of a frame spec: ``10``, ``1:240`` or ``1:240x2`` (inclusive, stride).

    Raises
    ------
    argparse.ArgumentTypeError
        On a malformed spec, an end before the start, or a stride <= 0.
    """
    m = _FRAMES.match(spec)
    if not m:
        raise argparse.ArgumentTypeError(f"bad frame spec {spec!r}: use N, START:END or START:ENDxSTRIDE")
    start = float(m.group(1))
    end = float(m.group(2)) if m.group(2) is not None else start
    stride = float(m.group(3)) if m.group(3) is not None else 1.0
    if end < start or stride <= 0:
        raise argparse.ArgumentTypeError(f"bad frame spec {spec!r}: need START <= END and STRIDE > 0")
    count = int((end - start) // stride) + 1
    if count > MAX_FRAME_SPEC:              # before an array of them is made
        raise argparse.ArgumentTypeError(f"frame spec {spec!r} names {count:,} frames: at most {MAX_FRAME_SPEC:,}")
    # Inclusive of END only when the stride lands on it (1:48x12 -> 1, 13, 25, 37).
    return start + stride * np.arange(count, dtype=np.float64)


def int_at_least(minimum: int):
    """An argparse type: a whole number >= ``minimum``, else a one-line usage error."""
    what = "a positive integer" if minimum == 1 else f"a whole number >= {minimum}"

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = minimum - 1
        if value < minimum:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
        return value

    return parse


def int_list(minimum: int, what: str):
    """An argparse type: comma-separated whole numbers >= ``minimum`` (``what`` names them in the error)."""
    def parse(text: str) -> tuple[int, ...]:
        try:
            values = tuple(int(v) for v in text.split(","))
        except ValueError:
            values = ()
        if not values or min(values) < minimum:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
        return values

    return parse


def add_executor(parser: argparse.ArgumentParser, workers_help: str, address_help: str,
                 min_workers: int = 1) -> None:
    """Where the work runs: --executor local|inline|ray, --workers N, --address ADDR (a Ray cluster's)."""
    parser.add_argument("--executor", choices=("local", "inline", "ray"), default="local",
                        help="local processes (default), this process, or Ray")
    parser.add_argument("--workers", type=int_at_least(min_workers), default=1, help=workers_help)
    parser.add_argument("--address", help=address_help)


def add_frames(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--frames", type=parse_frames, metavar="SPEC",
                        help="frames to use: N, START:END or START:ENDxSTRIDE (default: the stage's range)")


# Seeds are stored in customLayerData as unsigned 32-bit integers (numpy's generators take any, USD's int64 not).
MAX_SEED = 2**32 - 1


def int_in(lo: int, hi: int, what: str = "a whole number"):
    """An argparse type: a whole number in [lo, hi], else a one-line usage error naming the range."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what} from {lo:,} to {hi:,}, got {text!r}") from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"expected {what} from {lo:,} to {hi:,}, got {text!r}")
        return value

    return parse


def finite_float(lo: float = -float("inf"), hi: float = float("inf"), what: str = "a number"):
    """An argparse type: a finite number in [lo, hi] (nan and inf refused), else a one-line usage error."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        if not (np.isfinite(value) and lo <= value <= hi):
            bounds = f" from {lo:g} to {hi:g}" if np.isfinite(lo) and np.isfinite(hi) else (
                f" >= {lo:g}" if np.isfinite(lo) else (f" <= {hi:g}" if np.isfinite(hi) else ""))
            raise argparse.ArgumentTypeError(f"expected {what}{bounds} (finite), got {text!r}")
        return value

    return parse


def add_seed(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seed", type=int_in(0, MAX_SEED, "a seed"),
                        help="seed of every random draw (default: the stage's, else 0)")


def add_camera(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--camera", metavar="PATH", help="camera prim path (default: the first camera)")


def add_resolution(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--resolution", type=_resolution, metavar="WxH", help="image size, e.g. 640x360")


# Largest image side accepted (OpenGL's usual texture limit; 16384 x 16384 float RGBA
# is already 4 GiB in a renderer's film).
MAX_RESOLUTION = 16384


def _resolution(spec: str) -> tuple[int, int]:
    m = re.match(r"^(\d+)x(\d+)$", spec.strip())
    if not m or int(m.group(1)) < 1 or int(m.group(2)) < 1:
        raise argparse.ArgumentTypeError(f"bad resolution {spec!r}: use WIDTHxHEIGHT, e.g. 640x360")
    w, h = int(m.group(1)), int(m.group(2))
    if max(w, h) > MAX_RESOLUTION:
        raise argparse.ArgumentTypeError(f"resolution {spec!r} too large: at most {MAX_RESOLUTION} pixels a side")
    return w, h


def add_limits(parser: argparse.ArgumentParser) -> None:
    """--max-agents, --max-frames, --max-image-pixels: raise the resource bounds (usdcrowd.core.limits)."""
    from ..core.limits import DEFAULT

    parser.add_argument("--max-agents", type=int_at_least(1), default=DEFAULT.max_agents, metavar="N",
                        help=f"refuse scenarios with more agents (default {DEFAULT.max_agents:,})")
    parser.add_argument("--max-frames", type=int_at_least(1), default=DEFAULT.max_frames, metavar="N",
                        help=f"refuse shots with more frames (default {DEFAULT.max_frames:,})")
    parser.add_argument("--max-image-pixels", type=int_at_least(1), default=DEFAULT.max_image_pixels, metavar="N",
                        help=f"refuse larger behavior-map images (default {DEFAULT.max_image_pixels:,})")


def limits_of(args):
    """The Limits the options of :func:`add_limits` ask for."""
    from ..core.limits import Limits

    return Limits(args.max_agents, args.max_frames, args.max_image_pixels)


def add_force(parser: argparse.ArgumentParser, also: str = "") -> None:
    """--force: write into an output folder that holds files usdcrowd did not write (never replacing them)."""
    parser.add_argument("--force", action="store_true",
                        help="write into an output folder that holds files usdcrowd did not write (they are never "
                             f"replaced or removed), or replace a named output file usdcrowd did not write{also}")


def add_progress(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--no-progress", dest="progress", action="store_false", help="hide progress bars")
