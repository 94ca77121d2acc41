"""usdcrowd place SHOT --into SET.usda -o out.usda [--at X Y Z] [--rotate DEG] [--name NAME]"""

from __future__ import annotations

from .args import add_force, finite_float


# usdcrowd.usd.place.DEFAULT_NAME, spelled out: importing usdcrowd.usd would load numba for every command.
DEFAULT_NAME = "Shot"


def add_parser(sub):
    p = sub.add_parser("place", help="place a shot in a set: a new stage over the set that references the shot",
                       description="Write a stage that sublayers SET (never rewritten) and references SHOT under "
                                   "the set's default prim, moved to --at and turned by --rotate, with the shot's "
                                   "axes and units converted to the set's. Crowd, cameras and events follow the "
                                   "placement; the stage plays the shot's frames and carries the fallback prim "
                                   "types Blender needs to keep the crowd's groups.")
    p.add_argument("shot", help="the shot stage (shot.usda)")
    p.add_argument("--into", required=True, metavar="SET", help="the set stage (any up axis and units)")
    p.add_argument("-o", "--output", required=True, help="the stage to write (.usda)")
    coordinate = finite_float(-1e12, 1e12, "a coordinate")
    p.add_argument("--at", nargs=3, type=coordinate, default=(0.0, 0.0, 0.0), metavar=("X", "Y", "Z"),
                   help="where the shot's origin goes, in the set's units and axes (default 0 0 0)")
    p.add_argument("--rotate", type=finite_float(-36000, 36000, "degrees"), default=0.0, metavar="DEG",
                   help="degrees about the set's up axis, counter-clockwise seen from above (default 0)")
    p.add_argument("--name", help=f"name of the shot's prim in the set (default {DEFAULT_NAME})")
    add_force(p)
    p.set_defaults(run=run, inputs=("shot", "into"), outputs=("output",))


def run(args) -> int:
    import os

    from pxr import Tf

    from ..core.errors import UsdcrowdError
    from ..usd.place import place_shot

    if args.name is not None and (not args.name or Tf.MakeValidIdentifier(args.name) != args.name):
        raise UsdcrowdError(f"{args.name!r} is not a prim name (letters, digits and _, not starting with a digit)",
                            attribute="--name")
    if os.path.splitext(args.output)[1].lower() not in (".usda", ".usd", ".usdc"):
        raise UsdcrowdError("place writes a USD stage: name it .usda, .usd or .usdc", file=args.output)
    path, prim, offset = place_shot(args.shot, args.into, args.output, at=args.at, rotate=args.rotate,
                                    name=args.name)
    print(f"wrote {path}: {args.shot} placed in {args.into} as {prim} at {' '.join(f'{v:g}' for v in args.at)}, "
          f"turned {args.rotate:g} degrees")
    if offset:
        print(f"  ids     moved by {offset:+d}: the set already holds agents with the shot's ids (ground truth "
              f"tracks stay one per person)")
    return 0
