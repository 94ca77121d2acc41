"""usdcrowd cameras SHOT [--count N] [--static N] [--seed S]"""

from __future__ import annotations

from .args import add_force, add_limits, add_progress, add_seed, int_at_least, limits_of


def camera_count(text: str) -> int:
    """An argparse type: a number of cameras, 0 to :data:`~usdcrowd.jobs.filming.MAX_CAMERAS`."""
    import argparse

    from ..jobs.filming import MAX_CAMERAS

    value = int_at_least(0)(text)
    if value > MAX_CAMERAS:
        raise argparse.ArgumentTypeError(f"{text} cameras is too many (at most {MAX_CAMERAS:,} cameras)")
    return value


def add_parser(sub):
    from ..jobs.filming import MAX_CAMERAS

    p = sub.add_parser("cameras", help="re-run the camera agents on an existing shot (replaces cameras.usda)",
                       description="Film an existing shot again with seed 000's steering camera agents, "
                                   "without re-simulating the crowd. Only cameras.usda is replaced (atomically); "
                                   "the crowd layer, the scenario and stronger layers stay as they are.")
    p.add_argument("shot", help="the shot stage (shot.usda)")
    p.add_argument("--count", type=camera_count, metavar="N",
                   help="camera agents: the scenario's first N, generated ones beyond (default: the scenario's; "
                        f"at most {MAX_CAMERAS})")
    p.add_argument("--static", type=camera_count, default=0, metavar="N",
                   help=f"also N static cameras at strategic positions around the crowd (at most {MAX_CAMERAS})")
    add_seed(p)
    add_limits(p)
    add_force(p, " (cameras.usda changed since usdcrowd wrote it)")
    add_progress(p)
    p.set_defaults(run=run, inputs=("shot",))


def run(args) -> int:
    from pathlib import Path

    from .. import guard
    from ..usd.shot import find_shot
    from ..jobs.filming import refilm_shot
    from ..usd.cameras import CAMERAS, cameras_in

    # A stage over the shot, or a set placing it: its cameras are the shot's, authored in its space.
    args.shot = find_shot(args.shot)
    guard.edit_in_place(Path(args.shot).parent / CAMERAS)

    path, tracks, sc = refilm_shot(args.shot, count=args.count, static=args.static, seed=args.seed,
                                   progress=args.progress, limits=limits_of(args))
    # The counts are the file's: what was filmed now, and the toric cameras (usdcrowd frame's) it kept.
    held = cameras_in(path)
    filmed = {t.path for t in tracks}
    agents = [t for t in tracks if t.state is not None]
    static = [t for t in tracks if t.state is None and "/Static" in t.path]
    parts = [f"{len(agents)} agents"] + ([f"{len(static)} static"] if static else [])
    parts += [p.rsplit("/", 1)[-1] for p in held if p in filmed - {t.path for t in agents + static}]  # CrowdCam
    kept = [p for p in held if p not in filmed]
    if kept:
        parts.append(f"{len(kept)} toric kept")
    print(f"wrote {path}: {len(held)} cameras ({', '.join(parts)}), {len(sc.events)} events"
          + (" (detected now)" if sc.detected_now else ""))
    for t in agents:
        tracking = float((t.state == 1).mean())
        followed = sorted({p for p in t.tracked if p})
        print(f"  {t.path:<32} tracking {tracking:5.0%} of frames, {len(followed)} event(s)")
    return 0
