"""usdcrowd simulate STAGE -o OUT/ [--seed S] [--frames 1:240]"""

from __future__ import annotations

from .args import add_force, add_frames, add_limits, add_progress, add_seed, limits_of


def add_parser(sub):
    p = sub.add_parser("simulate", help="simulate a scenario and write a shot (shot.usda, crowd.usdc, cameras.usda)",
                       description="Simulate a scenario stage and author the crowd as UsdSkel animation in a shot "
                                   "folder. The scenario is referred to, never rewritten.")
    p.add_argument("stage", help="the scenario stage")
    p.add_argument("-o", "--output", required=True, help="output folder for the shot")
    p.add_argument("--no-events", dest="events", action="store_false",
                   help="do not detect events (faster for large crowds; camera agents then only scout, "
                        "or track the scenario's own events)")
    add_seed(p)
    add_frames(p)
    add_limits(p)
    add_force(p)
    add_progress(p)
    p.set_defaults(run=run, inputs=("stage",), output_folders=("output",))


def run(args) -> int:
    import numpy as np

    from ..core.errors import UsdcrowdError
    from ..jobs.pipeline import simulate_shot
    from ..usd.cameras import cameras_in

    frames = None
    if args.frames is not None:
        # One meaning everywhere: the frames named are the frames made. A simulation steps every frame,
        # so a stride would be silently dropped, and one frame is no motion.
        if len(args.frames) < 2 or not np.allclose(np.diff(args.frames), 1.0):
            raise UsdcrowdError("simulate makes every frame from START to END: give --frames START:END with "
                                "END > START and no stride", attribute="--frames")
        frames = (float(args.frames[0]), float(args.frames[-1]))
    r = simulate_shot(args.stage, args.output, seed=args.seed, frames=frames, progress=args.progress,
                      events=args.events, limits=limits_of(args))
    print(f"wrote {r.shot}: {r.n_agents} agents x {r.n_frames} frames, seed {r.seed}")
    print(f"  crowd   {r.crowd}")
    print(f"  cameras {r.cameras}")
    kept = [p for p in cameras_in(r.cameras) if p not in set(r.camera_paths)]
    if kept:        # `frame`'s cameras are the user's work: kept, framing the crowd as it was
        print(f"  kept    {len(kept)} camera(s) made by frame ({', '.join(p.rsplit('/', 1)[-1] for p in kept[:3])}"
              f"{'...' if len(kept) > 3 else ''}): they frame the earlier crowd; run frame again to reframe")
    print(f"  picture {r.plot}")
    return 0
