"""usdcrowd render SHOT -o OUT/ [--camera CAM] [--frames 1:240x2] [--preset groundtruth] [--spp N] ..."""

from __future__ import annotations

from .args import (MAX_SEED, add_camera, add_executor, add_force, add_frames, add_progress, add_resolution,
                   finite_float, int_in)


# The most samples per pixel asked for (the dataset spec's bound too): 1080p at this many is days a frame.
MAX_SPP = 65536


def add_parser(sub):
    p = sub.add_parser("render", help="render final frames with Mitsuba, with exact ground truth (EXR, MOT, COCO)",
                       description="Path-trace a shot through one camera: per frame a multi-channel EXR (beauty, "
                                   "depth, normals, position, albedo, uint32 ids), an sRGB PNG and a JSON of "
                                   "annotations; then MOTChallenge, COCO and a contact sheet for the sequence. "
                                   "A re-run renders only frames whose outputs are missing or damaged.")
    p.add_argument("shot", help="the shot stage (shot.usda from `usdcrowd simulate`)")
    p.add_argument("-o", "--output", required=True, help="output folder")
    add_camera(p)
    add_frames(p)
    add_resolution(p)
    p.add_argument("--preset", default="groundtruth", help="preset in render/presets.toml: preview, groundtruth "
                                                            "(default), final")
    p.add_argument("--spp", type=int_in(1, MAX_SPP, "samples per pixel"),
                   help="beauty samples per pixel (overrides the preset)")
    p.add_argument("--people-spp", type=int_in(0, MAX_SPP, "samples per pixel"), metavar="N",
                   help="N more samples on each pixel that sees a person, where the denoiser leaves noise "
                        "(overrides the preset; 0: none)")
    p.add_argument("--max-depth", type=int_in(1, 1000, "a path length"), help="longest light path (overrides the preset)")
    p.add_argument("--no-ground-truth", dest="ground_truth", action="store_const", const=False, default=None,
                   help="beauty only: no ground-truth passes or annotations")
    p.add_argument("--exposure", type=finite_float(-64, 64, "stops"), help="display exposure in stops (PNG, sheet, MP4)")
    p.add_argument("--working-space", choices=("sRGB", "ACEScg"), help="linear RGB space of the EXR beauty")
    p.add_argument("--variant", default="auto", help="Mitsuba variant (default: auto: cuda_ad_rgb, llvm_ad_rgb, "
                                                     "scalar_rgb, the first that works)")
    # 0 workers: render in this process, as --executor inline.
    add_executor(p, "worker processes or Ray actors (default 1: Mitsuba already uses every core)",
                 "Ray cluster address (default: start a local Ray instance)", min_workers=0)
    p.add_argument("--mp4", action="store_true", help="also write render.mp4 (needs imageio-ffmpeg)")
    p.add_argument("--seed", type=int_in(0, MAX_SEED, "a seed"), default=0, help="sampler seed of the beauty pass")
    p.add_argument("--sampler", choices=("independent", "stratified", "multijitter", "orthogonal", "ldsampler"),
                   help="Mitsuba sampler of the beauty (default: the preset's, multijitter)")
    p.add_argument("--motion-blur", dest="shutter", type=finite_float(0, 1, "a shutter in frames"), metavar="SHUTTER",
                   help="open the shutter for SHUTTER frames around each frame (0.5: a 180-degree shutter); the "
                        "scene is posed at --subframes times in that interval (the ground truth stays at the frame)")
    p.add_argument("--subframes", type=int_in(2, 1024, "sub-frames"), metavar="N",
                   help="with --motion-blur: times the shutter interval is sampled at (default 8)")
    denoise = p.add_mutually_exclusive_group()
    denoise.add_argument("--denoise", dest="denoise", action="store_const", const=True, default=None,
                         help="denoise the beauty with Intel Open Image Denoise (EXR R, G, B; the path-traced "
                              "beauty as raw.R, raw.G, raw.B)")
    denoise.add_argument("--no-denoise", dest="denoise", action="store_const", const=False,
                         help="keep the path-traced beauty as it is (every preset denoises)")
    add_force(p)
    add_progress(p)
    p.set_defaults(run=run, inputs=("shot",), output_folders=("output",))


def run(args) -> int:
    from ..render.final.variant import describe
    from ..render.sequence import render_sequence, resolve_variant
    from ..render.settings import settings_from_preset

    settings = settings_from_preset(args.preset, resolution=args.resolution, spp=args.spp,
                                    max_depth=args.max_depth, ground_truth=args.ground_truth,
                                    exposure=args.exposure, working_space=args.working_space, seed=args.seed,
                                    sampler=args.sampler, denoise=args.denoise, shutter=args.shutter,
                                    subframes=args.subframes, people_spp=args.people_spp)
    settings.variant = args.variant
    asked = settings.people_spp
    resolve_variant(settings)
    print(describe(settings.variant))
    if settings.people_spp != asked:
        print(f"the {settings.variant} variant takes no people's samples: rendering without the {asked} asked for")
    r = render_sequence(args.shot, args.output, camera=args.camera, frames=args.frames, settings=settings,
                        executor=args.executor, workers=args.workers, address=args.address,
                        progress=args.progress, mp4=args.mp4)
    rate = f", {r.seconds_per_frame:.2f} s/frame" if r.seconds_per_frame else ""
    print(f"rendered {len(r.rendered)} frame(s), {len(r.skipped)} already done{rate} "
          f"({settings.resolution[0]}x{settings.resolution[1]}, {settings.spp} spp"
          f"{f' + {settings.people_spp} on the people' if settings.people_spp else ''}, camera {r.camera})")
    for kind, path in r.outputs.items():
        print(f"  {kind:<14}{path}")
    return 0
