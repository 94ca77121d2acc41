"""usdcrowd cameras SHOT [--count N] [--static N] [--seed S]"""

from __future__ import annotations

from .args import add_force, add_limits, add_progress, add_seed, int_at_least, limits_of


def add_parser(sub):
    p = sub.add_parser("cameras", help="re-run the camera agents on an existing shot (replaces cameras.usda)",
                       description="Film an existing shot again with seed 000's steering camera agents, "
                                   "without re-simulating the crowd. Only cameras.usda is replaced (atomically); "
                                   "the crowd layer, the scenario and stronger layers stay as they are.")
    p.add_argument("shot", help="the shot stage (shot.usda)")
    p.add_argument("--count", type=int_at_least(0), metavar="N",
                   help="camera agents: the scenario's first N, generated ones beyond (default: the scenario's)")
    p.add_argument("--static", type=int_at_least(0), default=0, metavar="N",
                   help="also N static cameras at strategic positions around the crowd")
    add_seed(p)
    add_limits(p)
    add_force(p, " (cameras.usda changed since usdcrowd wrote it)")
    add_progress(p)
    p.set_defaults(run=run, inputs=("shot",))


def run(args) -> int:
    from pathlib import Path

    from .. import guard
    from ..filming import refilm_shot
    from ..usd.cameras import CAMERAS

    guard.edit_in_place(Path(args.shot).parent / CAMERAS)

    path, tracks, sc = refilm_shot(args.shot, count=args.count, static=args.static, seed=args.seed,
                                   progress=args.progress, limits=limits_of(args))
    agents = [t for t in tracks if t.state is not None]
    print(f"wrote {path}: {len(tracks)} cameras ({len(agents)} agents), {len(sc.events)} events"
          + (" (detected now)" if sc.detected_now else ""))
    for t in agents:
        tracking = float((t.state == 1).mean())
        followed = sorted({p for p in t.tracked if p})
        print(f"  {t.path:<32} tracking {tracking:5.0%} of frames, {len(followed)} event(s)")
    return 0
