"""usdcrowd edit SHOT -o DIR [--cameras C ...] [--weight KIND=W ...] [--hold MIN MAX] [--no-video]"""

from __future__ import annotations

import argparse

from .args import add_force, add_limits, add_progress, add_resolution, finite_float, limits_of


def weight(text: str) -> tuple[str, float]:
    """An argparse type: ``KIND=W`` or ``EVENT=W`` (an event's prim path or name), W a number >= 0."""
    name, sep, value = text.rpartition("=")
    if not sep or not name:
        raise argparse.ArgumentTypeError(f"expected KIND=W or EVENT=W (e.g. arrival=2), got {text!r}")
    return name, finite_float(0.0, 1e6, "a weight")(value)


def add_parser(sub):
    from ..editing import EditParams

    d = EditParams()
    p = sub.add_parser("edit", help="a director cuts the shot's cameras into one film (OTIO timeline, CutCam, MP4)",
                       description="Choose, frame by frame, which camera of the shot is on air: events ranked by "
                                   "importance (unique before repetitive, new before long-running, larger before "
                                   "smaller, your weights), each camera scored by how many of the event's people it "
                                   "shows unhidden and how large, shots held --hold seconds, no cut that breaks the "
                                   "30-degree or 180-degree rule. Writes DIR/cut.otio (one clip per shot), "
                                   "DIR/onair.csv (per frame: camera, event, why), DIR/cut.mp4 and DIR/cut_sheet.png, "
                                   "and adds CutCam to the shot's cameras.usda: a camera that plays the cut.")
    p.add_argument("shot", help="the shot stage (shot.usda)")
    p.add_argument("-o", "--output", required=True, help="output folder for the timeline, the record and the video")
    p.add_argument("--cameras", nargs="+", metavar="CAMERA",
                   help="cameras to cut between, prim paths or names (default: every camera of the shot)")
    p.add_argument("--weight", type=weight, action="append", default=[], metavar="KIND=W",
                   help="importance of an event kind (arrival, groupMotion, interaction, dialogue, explosion, "
                        "eruption) or of one event (its prim path or name); default 1, 0 ignores it; repeatable")
    p.add_argument("--hold", nargs=2, type=finite_float(0.1, 3600.0, "seconds"), default=(d.min_hold, d.max_hold),
                   metavar=("MIN", "MAX"), help=f"seconds a shot lasts (default {d.min_hold:g} {d.max_hold:g})")
    p.add_argument("--cut-cost", type=finite_float(0.0, 60.0, "seconds"), default=d.cut_cost, metavar="S",
                   help="a cut must gain at least this many seconds of the shot's mean coverage "
                        f"(default {d.cut_cost:g})")
    p.add_argument("--fatigue", type=finite_float(0.0, 3600.0, "seconds"), default=d.fatigue_seconds, metavar="S",
                   help="screen time wears an event out: at S seconds already on air it counts half (0: never; "
                        f"default {d.fatigue_seconds:g})")
    p.add_argument("--no-video", dest="video", action="store_false",
                   help="no cut.mp4 and cut_sheet.png (they need the preview extra)")
    add_resolution(p)
    add_limits(p)
    add_force(p)
    add_progress(p)
    p.set_defaults(run=run, inputs=("shot",), output_folders=("output",))


def run(args) -> int:
    from pathlib import Path

    from .. import guard
    from ..core import model
    from ..core.errors import UsdcrowdError
    from ..editing import EditParams
    from ..jobs.editing import edit_shot
    from ..usd.cameras import CAMERAS
    from ..usd.shot import find_shot

    lo, hi = args.hold
    if hi < 2 * lo:
        raise UsdcrowdError(f"--hold {lo:g} {hi:g}: the longest shot must be at least twice the shortest "
                            "(else some lengths of film cannot be cut into shots)")
    kinds, events = {}, {}
    for name, w in args.weight:
        (kinds if name in model.EVENT_KINDS else events)[name] = w
    params = EditParams(min_hold=lo, max_hold=hi, cut_cost=args.cut_cost, fatigue_seconds=args.fatigue,
                        kind_weights=kinds, event_weights=events)
    shot = find_shot(args.shot)
    guard.edit_in_place(Path(shot).parent / CAMERAS)
    r = edit_shot(args.shot, args.output, cameras=args.cameras, params=params, video=args.video,
                  resolution=args.resolution or (640, 360), progress=args.progress, limits=limits_of(args))
    unknown = sorted(set(events) - {p for p in r.events} - {p.rsplit("/", 1)[-1] for p in r.events})
    cut = r.cut
    lengths = [s.frames for s in cut.shots]
    shots = f"{len(cut.shots)} shot" + ("s" if len(cut.shots) != 1 else "")
    used = len(set(cut.camera.tolist()))
    print(f"wrote {args.output}: {shots} from {used} of {len(r.cameras)} camera{'s' if len(r.cameras) != 1 else ''} "
          f"over {len(r.times)} frames (shots of {min(lengths)} to {max(lengths)} frames)")
    for k, (s, why) in enumerate(zip(cut.shots, r.reasons), 1):
        print(f"  {k:>3} {r.times[s.start]:>6g}-{r.times[s.end - 1]:<6g} {r.cameras[s.camera].rsplit('/', 1)[-1]:<16} "
              f"{why}")
    if cut.refused:
        print("  refused cuts: " + ", ".join(f"{n} by the {rule}" for rule, n in sorted(cut.refused.items())))
    print(f"  camera   {r.paths['cut_camera']} in {r.paths['cameras']}")
    print(f"  timeline {r.paths['otio']}")
    print(f"  record   {r.paths['csv']}")
    if "mp4" in r.paths:
        print(f"  video    {r.paths['mp4']}, {r.paths['sheet']}")
    for name in unknown:
        print(f"usdcrowd edit: warning: --weight {name}: no event or kind of that name in the shot")
    return 0
