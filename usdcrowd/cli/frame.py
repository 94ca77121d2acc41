"""usdcrowd frame SHOT (--behavior B | --like REF.usda|CLIP.mp4 [REF2 --like-from F]) --targets A B|auto [...]"""

from __future__ import annotations

from .args import add_force, add_progress, add_resolution, finite_float

# Orbits faster than this (degrees per second) turn more than 150 degrees a frame at 24 fps: no shot.
MAX_ORBIT_SPEED = 3600.0
# A span longer than this (seconds, 10 days) is a typing mistake, not a shot.
MAX_SPAN = 864_000.0


def prim_name(text: str) -> str:
    """An argparse type: a valid USD prim name (Sdf.Path.IsValidIdentifier), else a one-line usage error."""
    import argparse

    from pxr import Sdf, Tf

    if not Sdf.Path.IsValidIdentifier(text):
        raise argparse.ArgumentTypeError(f"{text!r} is not a USD prim name (letters, digits and _, not starting "
                                         f"with a digit): e.g. {Tf.MakeValidIdentifier(text or 'Camera')!r}")
    return text


def add_parser(sub):
    from ..cameras.behaviors import BEHAVIORS, SHOT_SIZES

    p = sub.add_parser("frame", help="add a toric camera that films two characters with a named behavior",
                       description="Seed 002's camera behaviors in toric space: a camera that frames two "
                                   "characters of an existing shot (direct, relative or side track, or an "
                                   "orbit) in a close-up, medium or long shot, added to the shot's cameras.usda "
                                   "beside the other cameras (which stay as they are).")
    p.add_argument("shot", help="the shot stage (shot.usda)")
    how = p.add_mutually_exclusive_group(required=True)
    how.add_argument("--behavior", choices=BEHAVIORS, help="how the camera moves with the pair")
    how.add_argument("--like", metavar="REFERENCE", nargs="+",
                     help="film the pair the way a camera of another stage films two characters (seed 002's "
                          "learned behaviors: the behavior mix is read from it and retargeted here), or the way a "
                          "film clip films its two main characters (a video, or a folder of frames: their poses "
                          "are detected, needs the video extra); with several references, each takes over at its "
                          "--like-from frame")
    p.add_argument("--like-from", nargs="+", type=float, default=[], metavar="FRAME",
                   help="with several --like references: the frame each after the first takes over from (the "
                        "camera eases from one style into the next over two seconds)")
    p.add_argument("--camera", metavar="PATH", nargs="+",
                   help="with --like: the reference's camera (default: its toric camera, the first if several); "
                        "with several references, one for each or one for all")
    p.add_argument("--like-lens", type=float, default=50.0, metavar="MM",
                   help="with a clip reference: the lens it was shot with, mm on a 36 mm aperture (default 50)")
    p.add_argument("--like-fps", type=float, default=None, metavar="FPS",
                   help="with a folder of frames as the reference: its frame rate (default 24; a video says its own)")
    p.add_argument("--like-targets", nargs=2, metavar=("A", "B"),
                   help="with --like: the reference's two characters (default: its toric camera's targets)")
    p.add_argument("--targets", nargs="+", required=True, metavar="NAME",
                   help="the two characters (prim paths, or names when unique; A is the main character), or "
                        "'auto': per span of --span seconds, the pair the scene brings together (a talk or a "
                        "trade between two, else the closest two)")
    p.add_argument("--span", type=finite_float(0.0, MAX_SPAN, "seconds"), default=5.0, metavar="SECONDS",
                   help="with --targets auto: how long a pair is kept at least (default 5)")
    p.add_argument("--shot", dest="shot_size", default="medium", choices=tuple(SHOT_SIZES),
                   help="how large the main character is on screen (default: medium; with --like, the "
                        "reference's)")
    p.add_argument("--switch", nargs=3, action="append", default=[], metavar=("FRAME", "A", "B"),
                   help="from FRAME on, frame another pair (repeatable; the targets are blended over 1 s)")
    p.add_argument("--smooth", action="store_true",
                   help="smooth the final track (seed 002, section 7.2: 20-frame average, 3 passes)")
    p.add_argument("--side", choices=("left", "right"), default="left",
                   help="side of the pair (side track: of their travel; orbit and direct track: of A to B)")
    p.add_argument("--offset", type=finite_float(-360.0, 360.0, "degrees"), default=35.0, metavar="DEG",
                   help="relative track: angle from A's facing to the camera, degrees (default 35)")
    p.add_argument("--orbit-speed", type=finite_float(-MAX_ORBIT_SPEED, MAX_ORBIT_SPEED, "degrees per second"),
                   default=15.0, metavar="DEG_PER_S",
                   help="orbit: degrees per second, positive counter-clockwise from above (default 15)")
    p.add_argument("--focal-length", type=float, default=50.0, metavar="MM",
                   help="lens on a 36 mm horizontal aperture, mm (default 50)")
    p.add_argument("--name", type=prim_name,
                   help="camera prim name (default: behavior and characters, e.g. Orbit_A_B)")
    add_resolution(p)
    add_force(p, " (cameras.usda changed since usdcrowd wrote it)")
    add_progress(p)
    p.set_defaults(run=run, inputs=("shot", "like"))


def _reference(args, path: str, camera: str | None):
    """A --like reference: a stage's camera, or a clip's poses."""
    from ..cameras.clip_poses import is_clip
    from ..core.errors import UsdcrowdError
    from ..jobs.toric_filming import read_clip_reference, read_reference

    if is_clip(path):
        if camera is not None or args.like_targets:
            raise UsdcrowdError(f"--camera and --like-targets name a stage's camera and characters: {path} is a "
                                "clip (its two main characters are found in it)")
        if not 1.0 <= args.like_lens <= 2000.0:
            raise UsdcrowdError(f"--like-lens {args.like_lens:g} mm is not a lens (1 to 2000 mm)")
        if args.like_fps is not None and not 1.0 <= args.like_fps <= 1000.0:
            raise UsdcrowdError(f"--like-fps {args.like_fps:g} is not a frame rate (1 to 1000)")
        return read_clip_reference(path, args.like_lens, args.like_fps, progress=args.progress)
    return read_reference(path, camera, tuple(args.like_targets) if args.like_targets else None,
                          progress=args.progress)


def run(args) -> int:
    from pathlib import Path

    import numpy as np

    from .. import guard
    from ..usd.shot import find_shot
    from ..cameras.behaviors import Behavior
    from ..core.errors import UsdcrowdError
    from ..jobs.toric_filming import PairSpan, frame_shot

    if not 1.0 <= args.focal_length <= 2000.0:
        raise UsdcrowdError(f"--focal-length {args.focal_length:g} mm is not a lens (1 to 2000 mm)")
    if args.targets == ["auto"]:
        if args.switch:
            raise UsdcrowdError("--switch names pairs itself: use it with --targets A B, not auto")
        if not args.span > 0:
            raise UsdcrowdError(f"--span {args.span:g}: a span lasts more than 0 seconds")
        spans = "auto"
    elif len(args.targets) == 2:
        spans = [PairSpan(0.0, *args.targets)]
    else:
        raise UsdcrowdError(f"--targets takes two characters or 'auto', not {' '.join(args.targets)!r}")
    for frame, a, b in args.switch:
        try:
            spans.append(PairSpan(float(frame), a, b))
        except ValueError:
            raise UsdcrowdError(f"--switch {frame} {a} {b}: {frame!r} is not a frame number") from None
    width, height = args.resolution or (1920, 1080)
    from ..usd.cameras import CAMERAS

    # A stage over the shot, or a set placing it: its cameras are the shot's, authored in its space.
    args.shot = find_shot(args.shot)
    guard.edit_in_place(Path(args.shot).parent / CAMERAS)
    if args.like:
        from ..jobs.toric_filming import frame_like

        if len(args.like_from) != len(args.like) - 1 or list(args.like_from) != sorted(args.like_from):
            raise UsdcrowdError(f"--like-from takes one frame, in increasing order, for each reference after the "
                                f"first ({len(args.like) - 1} here), not {len(args.like_from)}")
        cameras = args.camera or [None]
        if len(cameras) not in (1, len(args.like)):
            raise UsdcrowdError(f"--camera takes one camera for all references or one for each ({len(args.like)} "
                                f"here), not {len(cameras)}")
        cameras = cameras * len(args.like) if len(cameras) == 1 else cameras
        references = [_reference(args, ref, cam) for ref, cam in zip(args.like, cameras)]
        starts = [float("-inf"), *args.like_from]
        path, track, result, signals, weights = frame_like(
            args.shot, list(zip(references, starts)), spans, name=args.name, smooth=args.smooth,
            focal_length=args.focal_length, aspect=width / height, span=args.span, progress=args.progress)
        what = ", then ".join(f"like {r.camera} of {ref} ({r.shot_size})" + (f" from frame {f:g}" if k else "")
                              for k, (r, ref, f) in enumerate(zip(references, args.like, starts)))
        gates = weights if weights.ndim == 2 else weights[None]
        detail = "\n".join(f"  experts   {', '.join(f'{w:.2f}' for w in g)} (the gating network's reading of "
                           f"{r.camera} of {ref})" for g, r, ref in zip(gates, references, args.like))
    else:
        if args.camera or args.like_targets or args.like_from or args.like_fps is not None or args.like_lens != 50.0:
            raise UsdcrowdError("--camera, --like-targets, --like-from, --like-lens and --like-fps describe the "
                                "references of --like")
        behavior = Behavior(args.behavior, args.shot_size, side=1 if args.side == "left" else -1,
                            offset=args.offset, orbit_speed=args.orbit_speed)
        path, track, result, signals = frame_shot(args.shot, behavior, spans, name=args.name, smooth=args.smooth,
                                                  focal_length=args.focal_length, aspect=width / height,
                                                  span=args.span, progress=args.progress)
        what, detail = f"{args.behavior}, {args.shot_size}", None
    screen = np.concatenate([result.p_a, result.p_b], axis=1)
    inside = np.isfinite(screen).all(axis=1) & (np.abs(screen) <= 1.0).all(axis=1)
    print(f"wrote {path}: {track.path} ({what}{', smoothed' if args.smooth else ''}), {len(track.times)} frames")
    if detail:
        print(detail)
    print(f"  targets   {' -> '.join(dict.fromkeys(f'{a} & {b}' for a, b in zip(signals.target_a, signals.target_b)))}")
    print(f"  on screen both heads in {inside.mean():.0%} of frames; camera {np.nanmin(result.distance):.2f}-"
          f"{np.nanmax(result.distance):.2f} m from the characters")
    return 0
