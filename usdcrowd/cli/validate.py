"""usdcrowd validate STAGE"""

from __future__ import annotations

from .args import add_limits, limits_of


def add_parser(sub):
    p = sub.add_parser("validate", help="check a stage with USD's validators and the crowd schema rules",
                       description="Run pxr.UsdValidation's validators and usdcrowd's schema checks. "
                                   "Exit 0 when no error is found, 1 otherwise.")
    p.add_argument("stage", help="a .usda/.usdc/.usd stage")
    p.add_argument("--strict", action="store_true", help="count warnings as errors")
    add_limits(p)
    p.set_defaults(run=run, inputs=("stage",))


def run(args) -> int:
    from ..jobs.validation import validate

    problems = validate(args.stage, limits=limits_of(args))
    for p in problems:
        print(p)
    errors = [p for p in problems if p.severity == "error" or (args.strict and p.severity == "warning")]
    warnings = sum(p.severity == "warning" for p in problems)
    print(f"{args.stage}: {len(errors)} error(s), {warnings} warning(s)")
    return 1 if errors else 0
