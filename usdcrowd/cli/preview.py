"""usdcrowd preview SHOT [--camera CAM] [--frames 1:240] [-o preview.mp4 | frames/]"""

from __future__ import annotations

from .args import add_camera, add_force, add_frames, add_progress, add_resolution, finite_float, int_at_least

OVERLAYS = ("frusta", "trajectories", "layers", "events", "ids")


def add_parser(sub):
    p = sub.add_parser("preview", help="fast OpenGL preview of a shot: an MP4, PNG frames, or a window",
                       description="Draw a shot with OpenGL (headless through EGL, Mesa's llvmpipe is enough). "
                                   "With -o NAME.mp4 write a video, with -o FOLDER/ write PNG frames and a "
                                   "contact sheet; without -o open an interactive window (needs a display).")
    p.add_argument("stage", help="the shot stage (shot.usda)")
    p.add_argument("-o", "--output", help="NAME.mp4, or a folder for PNG frames (default: open a window)")
    add_camera(p)
    add_frames(p)
    add_resolution(p)
    p.add_argument("--overlays", default="", metavar="LIST",
                   help=f"comma-separated annotations: {', '.join(OVERLAYS)} (or 'all')")
    p.add_argument("--no-lod", dest="lod", action="store_false",
                   help="full mesh for every character (exact silhouettes), no points")
    p.add_argument("--max-meshes", type=int_at_least(0), default=150, metavar="N",
                   help="at most N characters drawn as meshes, the tallest on screen; "
                        "the rest become impostors (default 150; 0: no limit)")
    p.add_argument("--aovs", action="store_true",
                   help="with a frames folder, also write ids (uint32) and depth (metres) per frame as .npz")
    p.add_argument("--sheet", metavar="PNG", help="contact sheet path (default: next to the output)")
    p.add_argument("--exposure", type=finite_float(0, 1e6, "a radiance scale"), default=1.0,
                   help="multiplies linear radiance (default 1)")
    add_force(p)
    add_progress(p)
    p.set_defaults(run=run, inputs=("stage",), outputs=("output", "sheet"))


def parse_overlays(spec: str) -> tuple[str, ...]:
    from ..core.errors import UsdcrowdError

    names = [s.strip() for s in (spec or "").split(",") if s.strip()]
    if names == ["all"]:
        return OVERLAYS
    bad = [n for n in names if n not in OVERLAYS]
    if bad:
        raise UsdcrowdError(f"unknown overlay {bad[0]!r}; choose from {', '.join(OVERLAYS)} or 'all'")
    return tuple(names)


def run(args) -> int:
    from pathlib import Path

    from ..render.preview import LodSettings, PreviewRenderer
    from ..render.preview.output import write_sequence
    from ..scenario.shot_scene import ShotScene

    overlay_names = parse_overlays(args.overlays)
    scene = ShotScene(args.stage)
    times = args.frames if args.frames is not None else scene.time_codes
    camera = args.camera
    scene.check_times(times)
    scene.camera(camera, float(times[0]))              # a wrong camera fails before any work
    width, height = args.resolution or (1280, 720)

    overlays = None
    if overlay_names:
        from ..render.preview.overlays import Overlays

        overlays = Overlays(scene, overlay_names, times=times)
    lod_settings = LodSettings(enabled=args.lod, max_meshes=args.max_meshes or None)

    if args.output is None:
        from ..render.preview.window import run_viewer

        return run_viewer(scene, width, height, times=times, camera=camera, overlays=overlays,
                          lod_settings=lod_settings, exposure=args.exposure)

    out = Path(args.output)
    to_video = out.suffix.lower() in (".mp4", ".m4v", ".mov")
    if not to_video and out.suffix and not out.is_dir():
        from ..core.errors import UsdcrowdError

        raise UsdcrowdError(f"preview writes an MP4 (.mp4, .m4v, .mov) or a folder of PNG frames, not "
                            f"{out.suffix!r}: name a video or a folder", file=args.output)
    sheet_path = Path(args.sheet) if args.sheet else (
        out.with_name(out.stem + "_sheet.png") if to_video else out / "contact_sheet.png")
    r = PreviewRenderer(scene, width, height, lod_settings=lod_settings, overlays=overlays, exposure=args.exposure)
    try:
        write_sequence(r, times, camera, video=out if to_video else None, frames_dir=None if to_video else out,
                       aovs=args.aovs, sheet=sheet_path, progress=args.progress)
    finally:
        r.release()
    what = f"{out}" if to_video else f"{len(times)} frames in {out}/"
    print(f"wrote {what} ({width}x{height}, {len(times)} frames, camera {camera or scene.camera_paths[0]})")
    print(f"  contact sheet {sheet_path}")
    return 0
