"""usdcrowd dataset SPEC.toml -o DATASET/: many randomized sequences, merged into one MOT/COCO dataset."""

from __future__ import annotations

from .args import add_executor, add_force, add_progress, int_list


def add_parser(sub):
    p = sub.add_parser(
        "dataset", help="make a dataset of many randomized sequences (MOT, COCO), locally or on Ray",
        description="Draw every sequence's scene, crowd, time of day, clothes and cameras from the spec's seed, "
                    "simulate and film them, render every camera with ground truth and merge the results "
                    "into MOTChallenge folders, COCO files per split and a dataset card. Run it again with "
                    "the same command to finish what a killed run left.")
    p.add_argument("spec", help="the dataset spec (TOML; see the README's \"make a dataset\")")
    p.add_argument("-o", "--output", required=True, help="dataset folder")
    add_executor(p, "processes, or concurrent tasks on a Ray instance started here (default 1)",
                 "a running Ray cluster's address (with --executor ray); the dataset folder must then be on "
                 "a file system every node mounts at the same path")
    add_force(p, "; and accept a changed spec: sequences whose plan changed are made again, the rest kept")
    p.add_argument("--sequences", metavar="LIST", type=int_list(0, "sequence numbers like 3 or 0,5,7"),
                   help="make only these sequences, e.g. 3 or 0,5,7 (to re-make one alone)")
    add_progress(p)
    p.set_defaults(run=run, inputs=("spec",), output_folders=("output",))


def run(args) -> int:
    from ..dataset.run import make_dataset

    r = make_dataset(args.spec, args.output, executor=args.executor, workers=args.workers, address=args.address,
                     progress=args.progress, force=args.force, only=args.sequences)
    rate = r.rendered / r.seconds * 3600 if r.rendered else 0.0
    print(f"dataset {r.out_dir}: {r.sequences} sequences, {r.videos} videos, {r.frames} frames "
          f"({r.prepared} sequences filmed and {r.rendered} frames rendered by this run in {r.seconds:.0f} s"
          + (f", {rate:,.0f} frames/hour" if r.rendered else "") + ")")
    for note in r.notes:
        print(f"  note  {note}")
    for name, path in r.outputs.items():
        print(f"  {name:<12} {path}")
    return 0
