"""usdcrowd demo [-o OUT/]: the README's main job, a small scene end to end."""

from __future__ import annotations

import time
from pathlib import Path

from .args import add_force, add_progress, add_seed, int_at_least
from .cameras import camera_count


def add_parser(sub):
    from ..jobs.filming import MAX_CAMERAS

    p = sub.add_parser("demo", help="run every part that exists on a small scene, end to end",
                       description="New scenario from the museum template, validate it, simulate it, "
                                   "validate the shot, preview it with OpenGL, render frames with ground "
                                   "truth with Mitsuba, and print where everything is.")
    p.add_argument("-o", "--output", default="out/demo", help="output folder (default: out/demo)")
    p.add_argument("--template", default="museum", help="example scene to use (default: museum)")
    p.add_argument("--agents", type=int_at_least(1), default=None, help="number of agents (default: the template's)")
    p.add_argument("--cameras", type=camera_count, default=3,
                   help=f"steering camera agents to run (default 3, at most {MAX_CAMERAS})")
    add_seed(p)
    add_force(p)
    add_progress(p)
    p.set_defaults(run=run, output_folders=("output",))


def _starts(step: int, name: str, what: str) -> None:
    """The line a step prints as it starts (its result follows when it ends)."""
    print(f"[{step}] {name:<9} {what} ...", flush=True)


def run(args) -> int:
    from ..jobs.pipeline import simulate_shot
    from ..jobs.summary import format_summary, summarize
    from ..jobs.templates import new_scenario
    from ..jobs.validation import validate

    from ..atomic import output_dir

    out = output_dir(args.output, "demo")
    t0 = time.perf_counter()
    _starts(1, "scenario", f"from the {args.template} template")
    info = new_scenario(args.template, out / "scenario.usda", args.agents, args.seed)
    print(f"[1] scenario  {info['path']} ({info['agents']} agents, template {args.template})")
    _starts(2, "validate", "scenario")
    errors = [p for p in validate(info["path"]) if p.severity == "error"]
    if errors:
        for p in errors:
            print(p)
        return 1
    print("[2] validate  scenario: 0 errors")
    _starts(3, "simulate", f"{info['agents']} agents with {args.cameras} camera agents into {out / 'shot'}")
    r = simulate_shot(info["path"], out / "shot", seed=args.seed, progress=args.progress,
                      camera_count=args.cameras)
    agents = [p for p in r.camera_paths if "/Agent" in p]
    print(f"[3] simulate  {r.shot} ({r.n_agents} agents x {r.n_frames} frames, {r.n_events} events, "
          f"{len(agents)} camera agents)")
    _starts(4, "validate", "shot")
    errors = [p for p in validate(r.shot) if p.severity == "error"]
    for p in errors:
        print(p)
    if errors:
        return 1
    print("[4] validate  shot: 0 errors")
    toric = _toric(r, args.progress)
    edit = _edit(r, out, args.progress)
    preview = _preview(r, out, args.progress, toric)
    final = _final(r, out, args.progress)
    print()
    print(format_summary(summarize(r.shot)))
    print()
    print(f"done in {time.perf_counter() - t0:.1f} s. Outputs:")
    print(f"  scenario  {info['path']}")
    print(f"  shot      {r.shot}   (open it in usdview, Blender, Houdini...)")
    print(f"  crowd     {r.crowd}")
    print(f"  cameras   {r.cameras}")
    print(f"  picture   {r.plot}   (every trajectory, seen from above)")
    for name, path in {**edit, **preview, **final}.items():
        print(f"  {name:<9} {path}")
    return 0


def _final(r, out: Path, progress: bool) -> dict:
    """Eight path-traced frames across the shot with their ground truth (EXR, MOT, COCO)."""
    import numpy as np

    from ..core.errors import UsdcrowdError

    frames = np.unique(np.linspace(1, r.n_frames, 8).round())
    _starts(8, "render", f"{len(frames)} frames with ground truth (Mitsuba, 480x270, 32 spp)")
    try:
        from ..render.demo import final_outputs
        from ..render.sequence import render_sequence
        from ..render.settings import settings_from_preset

        size, spp = (480, 270), 32
        # The frames first, with the renderer's labelled progress bar; final_outputs then finds them
        # done (the same settings) and writes the ground truth files.
        render_sequence(r.shot, out / "render", camera=r.camera, frames=frames, executor="inline",
                        settings=settings_from_preset("groundtruth", resolution=size, spp=spp), progress=progress,
                        sequence_files=False)
        paths = final_outputs(r.shot, out / "render", camera=r.camera, frames=frames, resolution=size, spp=spp)
    except UsdcrowdError as exc:          # no Mitsuba here: say so, the rest of the demo stands
        print(f"[8] render    skipped: {exc}")
        return {}
    print(f"[8] render    {len(frames)} frames with ground truth, Mitsuba {paths['variant']}")
    return {"frame": paths["frame_png"], "exr": paths["exr"], "render sheet": paths["contact_sheet"],
            "mot": paths["mot"], "coco": paths["coco"]}


def _toric(r, progress: bool) -> str | None:
    """A toric camera (seed 002) orbiting the two characters the scene brings together, smoothed."""
    from ..cameras.behaviors import Behavior
    from ..core.errors import UsdcrowdError
    from ..jobs.toric_filming import frame_shot

    _starts(5, "frame", "a toric camera orbiting the pair the scene brings together")
    try:
        _, track, _, signals = frame_shot(r.shot, Behavior("orbit", "medium"), "auto", smooth=True,
                                          progress=progress)
    except UsdcrowdError as exc:           # no two characters ever near each other: the rest stands
        print(f"[5] frame     skipped: {exc}")
        return None
    pairs = dict.fromkeys(f"{a.rsplit('/', 1)[-1]} & {b.rsplit('/', 1)[-1]}"
                          for a, b in zip(signals.target_a, signals.target_b))
    print(f"[5] frame     {track.path}: orbit, medium shot, smoothed, on {' then '.join(pairs)}")
    return track.path


def _edit(r, out: Path, progress: bool) -> dict:
    """The director's cut of every camera (``usdcrowd edit``): CutCam, the OTIO timeline, the cut's video."""
    from ..core.errors import UsdcrowdError
    from ..jobs.editing import edit_shot

    _starts(6, "edit", "a director cuts the cameras into one film")
    try:
        e = edit_shot(r.shot, out / "cut", progress=progress)
    except UsdcrowdError as exc:          # no OpenTimelineIO or no OpenGL here: say so, the rest stands
        print(f"[6] edit      skipped: {exc}")
        return {}
    used = len(set(e.cut.camera.tolist()))
    print(f"[6] edit      {e.paths['otio']}: {len(e.cut.shots)} shots from {used} of {len(e.cameras)} cameras; "
          f"{e.paths['cut_camera']} plays it")
    return {"cut": e.paths["otio"], "cut video": e.paths["mp4"], "cut sheet": e.paths["sheet"]}


def _preview(r, out: Path, progress: bool, toric: str | None = None) -> dict:
    """The OpenGL preview of the shot, from the crowd camera, every other frame (and the toric camera's)."""
    import numpy as np

    from ..core.errors import UsdcrowdError

    _starts(7, "preview", "OpenGL, every other frame, and a gallery of every camera")
    try:
        from ..render.demo import preview_outputs

        from ..render.preview.output import camera_gallery

        frames = np.arange(1, r.n_frames + 1, 2, dtype=np.float64)
        # The first camera agent, if any: the preview shows what it chose to film.
        camera = next((p for p in r.camera_paths if "/Agent" in p), r.camera)
        paths = preview_outputs(r.shot, out / "preview", camera=camera, frames=frames, progress=progress)
        gallery = camera_gallery(r.shot, out / "preview" / "gallery.png", r.camera_paths,
                                 np.unique(np.linspace(1, r.n_frames, 5).round()), resolution=(320, 180),
                                 progress=progress)
        toric_paths = (preview_outputs(r.shot, out / "preview" / "toric", camera=toric, frames=frames,
                                    progress=progress) if toric else None)
    except UsdcrowdError as exc:          # no OpenGL here: say so, the rest of the demo stands
        print(f"[7] preview   skipped: {exc}")
        return {}
    print(f"[7] preview   {paths['mp4']} ({len(frames)} frames from {camera}); gallery of "
          f"{len(r.camera_paths)} cameras" + (f"; the toric camera in {toric_paths['mp4']}" if toric_paths else ""))
    out_paths = {"preview": paths["mp4"], "sheet": paths["contact_sheet"], "gallery": gallery}
    if toric_paths:
        out_paths.update({"toric": toric_paths["mp4"], "toric sheet": toric_paths["contact_sheet"]})
    return out_paths
