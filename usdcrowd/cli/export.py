"""usdcrowd export SHOT [--flatten OUT.usdc] [--usdz OUT.usdz] [--gltf OUT.glb] [--trajectories OUT.txt|OUT.sqlite]
[--frames SPEC]"""

from __future__ import annotations

import os

from .args import add_force, add_frames, add_progress

# The outputs, the extensions each accepts, and what it is called in messages.
OUTPUTS = {"flatten": ((".usdc", ".usda", ".usd"), "one USD layer"),
           "usdz": ((".usdz",), "a usdz package"),
           "gltf": ((".glb",), "binary glTF"),
           "trajectories": ((".txt", ".sqlite"), "trajectories (PedPy's text or JuPedSim's SQLite)")}


def add_parser(sub):
    p = sub.add_parser("export", help="write a shot as one flattened USD layer, a usdz package, binary glTF or "
                                      "pedestrian trajectories",
                       description="Write a shot for other tools: --flatten composes it into one self-contained "
                                   "layer (value clips become time samples), --usdz packages that layer with the "
                                   "images it uses, --gltf writes binary glTF 2.0 (skinned characters, cameras, "
                                   "scenery; Y up, metres), --trajectories writes where each person stands, frame "
                                   "by frame, for PedPy (.txt, frame rate and unit in the header) or JuPedSim "
                                   "(.sqlite, with the walkable area). Give one or several.")
    p.add_argument("shot", help="the shot stage (shot.usda from `usdcrowd simulate`)")
    out = p.add_argument_group("outputs (at least one)")
    out.add_argument("--flatten", metavar="OUT.usdc", help="one USD layer (.usdc, or .usda for text)")
    out.add_argument("--usdz", metavar="OUT.usdz", help="a usdz package of the flattened layer")
    out.add_argument("--gltf", metavar="OUT.glb", help="binary glTF 2.0 with the animation sampled at each frame")
    out.add_argument("--trajectories", metavar="OUT.txt|OUT.sqlite",
                     help="ground positions per frame: PedPy's text format (ID FR X Y Z, metres) or JuPedSim's "
                          "trajectory database")
    add_frames(p)
    add_force(p)
    add_progress(p)
    p.set_defaults(run=run, inputs=("shot",), outputs=tuple(OUTPUTS))


def check_outputs(args) -> dict[str, str]:
    """``{option: path}`` of the outputs asked for.

    Raises
    ------
    UsdcrowdError
        None asked for, or an extension the format does not have (so no two outputs share a path).
    """
    from ..core.errors import UsdcrowdError

    named = {name: getattr(args, name) for name in OUTPUTS if getattr(args, name) is not None}
    if not named:
        raise UsdcrowdError("name an output: --flatten OUT.usdc, --usdz OUT.usdz, --gltf OUT.glb or --trajectories "
                            "OUT.txt|OUT.sqlite", file=args.shot)
    for name, path in named.items():
        suffixes, what = OUTPUTS[name]
        if os.path.splitext(path)[1].lower() not in suffixes:
            raise UsdcrowdError(f"--{name} writes {what}: name it {' or '.join('*' + s for s in suffixes)}",
                                file=path)
    return named


def run(args) -> int:
    from ..atomic import export_layer
    from ..exchange.flatten import flatten_shot, write_usdz
    from ..scenario.shot_scene import ShotScene

    named = check_outputs(args)
    scene = ShotScene(args.shot)
    times = args.frames if args.frames is not None else scene.time_codes
    scene.check_times(times)
    frames = f"{len(times)} frame(s), {times[0]:g}-{times[-1]:g}" if len(times) else "no frames"
    if "flatten" in named or "usdz" in named:
        layer = flatten_shot(scene.stage, args.frames, progress=args.progress)
        if "flatten" in named:
            export_layer(layer, named["flatten"])
            print(f"wrote {named['flatten']}: one layer, {frames}")
        if "usdz" in named:
            write_usdz(layer, named["usdz"])
            print(f"wrote {named['usdz']}: usdz package, {frames}")
    if "gltf" in named:
        counts = _write_gltf(scene, times, named["gltf"], args.progress)
        print(f"wrote {named['gltf']}: {counts['crowd']} agent(s), {counts['cameras']} camera(s), "
              f"{counts['scenery']} scenery mesh(es), {frames}")
    if "trajectories" in named:
        from ..exchange.trajectories import read_trajectories, write_trajectories

        traj = read_trajectories(scene, times, args.progress)
        rows = write_trajectories(traj, named["trajectories"], os.path.basename(scene.path))
        print(f"wrote {named['trajectories']}: {rows} position(s) of {len(traj.ids)} person(s), {frames}, "
              f"{traj.fps:g} frames per second")
    return 0


def _write_gltf(scene, times, path: str, progress: bool) -> dict:
    """The GLB, or a one-line error when pygltflib (usdcrowd[preview]) is missing."""
    from ..core.errors import UsdcrowdError

    try:
        import pygltflib  # noqa: F401
    except ImportError:
        raise UsdcrowdError("--gltf needs pygltflib: pip install 'usdcrowd[preview]'", file=path) from None
    from ..exchange.gltf import write_glb

    return write_glb(scene, times, path, progress=progress)
