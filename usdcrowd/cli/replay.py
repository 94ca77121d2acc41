"""usdcrowd replay TRAJ -o OUT/ [--format F] [--fps F] [--shot-fps F] [--scenery S | --scenario STAGE]
[--height-from H] [--cameras N] [--seed S]"""

from __future__ import annotations

from .args import add_force, add_limits, add_progress, add_seed, finite_float, int_at_least, limits_of


def add_parser(sub):
    from ..exchange.recorded_tracks import FORMATS
    from ..jobs.replay import HEIGHT_SOURCES

    p = sub.add_parser("replay", help="write a shot whose people walk a trajectory file (JuPedSim, PedPy, ETH/UCY)",
                       description="Turn recorded or simulated walking paths into a shot: the same layers as "
                                   "simulate writes (skinned, animated people; events; camera agents), so preview, "
                                   "render, ground truth and export work on it. Reads JuPedSim's trajectory "
                                   "database (.sqlite), PedPy's text (ID FR X Y Z, frame rate and unit in the "
                                   "header) and the ETH/UCY 'frame id x y' files. The people's scenario is "
                                   "written beside the shot as replay.usda.")
    p.add_argument("trajectories", help="the trajectory file")
    p.add_argument("-o", "--output", required=True, help="output folder for the shot")
    p.add_argument("--format", dest="fmt", choices=FORMATS,
                   help="the file's layout (default: from its extension and first line)")
    p.add_argument("--fps", type=finite_float(lo=1e-3, what="a frame rate"),
                   help="frames per second the file's frame numbers count, where the file does not say "
                        "(ETH/UCY: default from the 0.4 s annotation step)")
    p.add_argument("--shot-fps", type=finite_float(lo=1.0, hi=240.0, what="a frame rate"),
                   help="frames per second of the shot (default: the file's, if 10 to 60, else 25)")
    p.add_argument("--scenery", help="a USD file from a DCC tool to walk in (default: a flat ground)")
    p.add_argument("--scenario", dest="companion", metavar="STAGE",
                   help="a companion scenario (Z up, metres): its scenery, lights, camera agents and events, and "
                        "the attributes of the people whose crowd:agentId is a track id; its clones and other "
                        "agents are switched off")
    p.add_argument("--height-from", choices=HEIGHT_SOURCES, default="auto",
                   help="body heights from the file's Z column (head heights), drawn from the seed, or "
                        "(auto) the file's where every Z is a plausible height")
    p.add_argument("--cameras", type=int_at_least(0),
                   help="camera agents scouting and tracking the shot's events (default: the companion "
                        "scenario's, else 4)")
    p.add_argument("--max-gap", type=finite_float(lo=0.0, what="seconds"), default=2.0,
                   help="longest gap in a person's rows filled in, seconds (longer: they leave and come back)")
    p.add_argument("--no-events", dest="events", action="store_false", help="do not detect events")
    add_seed(p)
    add_limits(p)
    add_force(p)
    add_progress(p)
    p.set_defaults(run=run, inputs=("trajectories", "scenery", "companion"), output_folders=("output",))


def run(args) -> int:
    from ..jobs.replay import replay_shot

    done = replay_shot(args.trajectories, args.output, fmt=args.fmt, fps=args.fps, shot_fps=args.shot_fps,
                       scenery=args.scenery, height_from=args.height_from, seed=args.seed or 0,
                       cameras=args.cameras, max_gap_s=args.max_gap, events=args.events, progress=args.progress,
                       limits=limits_of(args), companion=args.companion)
    r = done.shot
    print(f"read {args.trajectories}: {done.fmt}, {done.rows:,} rows at {done.file_fps:g} frames per second"
          + (f"; ids shifted by +{done.id_offset} (usdcrowd's and MOT's ids start at 1)" if done.id_offset else ""))
    print(f"wrote {r.shot}: {r.n_agents} people x {r.n_frames} frames, {r.n_events} events")
    print(f"  crowd   {r.crowd}")
    print(f"  cameras {r.cameras}")
    print(f"  picture {r.plot}")
    return 0
