"""usdcrowd features SHOT A B -o DIR [--camera CAM] [--frames 1:240] [--resolution WxH]"""

from __future__ import annotations

from .args import add_camera, add_force, add_frames, add_progress, add_resolution


def add_parser(sub):
    p = sub.add_parser("features", help="seed 002's cinematic features of a camera filming two characters",
                       description="Per frame: the two heads' screen positions (NDC), the camera's toric "
                                   "angles (theta, phi), the characters' distance (m) and shoulder orientations, "
                                   "and the main character; written as features.csv and features.json, each "
                                   "column named with its unit (pA_x_ndc, theta_deg, dAB_m, sA_deg...): angles "
                                   "in degrees, like the USD attributes and the renderer's JSON.")
    p.add_argument("shot", help="the shot stage (shot.usda)")
    p.add_argument("a", metavar="A", help="first character: prim path, or its name when unique")
    p.add_argument("b", metavar="B", help="second character")
    p.add_argument("-o", "--output", required=True, help="output folder")
    add_camera(p)
    add_frames(p)
    add_resolution(p)
    add_force(p)
    add_progress(p)         # accepted as by every command; the features are computed in one pass
    p.set_defaults(run=run, inputs=("shot",), output_folders=("output",))


def run(args) -> int:
    from pathlib import Path

    import numpy as np

    from ..atomic import output_dir
    from ..cameras.features import write_features
    from ..jobs.toric_filming import shot_features

    width, height = args.resolution or (1920, 1080)
    features, about = shot_features(args.shot, args.camera, args.a, args.b, args.frames, width, height)
    out = output_dir(args.output, "features")
    written = write_features(features, Path(out) / "features.csv", Path(out) / "features.json", **about)
    framed = int(np.isfinite(features.theta).sum())
    print(f"wrote {written[0]} and {written[1]}: {len(features.times)} frames ({framed} with both heads in front "
          f"of the camera), main character {'AB'[features.main]} ({about['A' if features.main == 0 else 'B']})")
    return 0
