"""usdcrowd metrics SHOT -o DIR [--counts 4,8] [--seed S]"""

from __future__ import annotations

from .args import add_force, add_limits, add_progress, add_seed, int_list, limits_of


def add_parser(sub):
    from ..jobs.filming import MAX_CAMERAS

    p = sub.add_parser("metrics", help="seed 000's evaluation: autonomous vs static cameras on a shot",
                       description="Film the shot with N autonomous camera agents and N static cameras for "
                                   "each N, and measure the activity metric (Algorithm 7) and the share of "
                                   "active characters viewed; writes CSVs and plots like seed 000's "
                                   "Figures 12 to 15.")
    p.add_argument("shot", help="the shot stage (shot.usda)")
    p.add_argument("-o", "--output", required=True, help="output folder for CSVs and plots")
    p.add_argument("--counts", type=int_list(1, "camera counts like 4,8"), default=(4, 8), metavar="N,M",
                   help=f"camera counts: N autonomous and N static for each (default 4,8; at most {MAX_CAMERAS})")
    add_seed(p)
    add_limits(p)
    add_force(p)
    add_progress(p)
    p.set_defaults(run=run, inputs=("shot",), output_folders=("output",))


def run(args) -> int:
    from ..jobs.filming import evaluate_shot

    results = evaluate_shot(args.shot, args.output, counts=args.counts, seed=args.seed, progress=args.progress,
                            limits=limits_of(args))
    print(f"wrote {args.output}: summary.csv, activity_N / viewed_N .csv and .png, tracking_N.csv")
    print(f"  {'cameras':>7} {'kind':<12} {'active share':>12} {'active/idle':>11} {'viewed share':>12}")
    print("  (static: placed knowing where the crowd goes over the whole shot; static_start: on its first frame)")
    counts = list(results)
    for n in counts:
        for kind in ("autonomous", "static", "static_start"):
            s = results[n][kind]
            print(f"  {n:>7} {kind:<12} {s['mean_active_share']:>12.3f} {s['mean_active_idle_ratio']:>11.3f} "
                  f"{s['mean_viewed_share']:>12.3f}")
    print("  tracking cameras (2 s after taking an event): frames with half its people or more visible, "
          "with none, with only scenery or ground (none in the picture unhidden by it), seconds to frame it "
          "(median)")
    for n in counts:
        q = results[n]["tracking"]
        print(f"  {n:>7} autonomous  framed {q['framed']:6.1%}  blank {q['blank']:6.1%}  "
              f"walled {q['walled']:6.1%}  "
              f"{q['median_seconds_to_frame']:.2f} s over {q['takes']} takes")
    gallery = results[counts[0]].get("gallery")
    if gallery:
        print(f"  gallery {gallery}")
    return 0
