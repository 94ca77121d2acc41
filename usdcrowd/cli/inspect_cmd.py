"""usdcrowd inspect STAGE [--json]"""

from __future__ import annotations

import json

from .args import add_limits, limits_of


def add_parser(sub):
    p = sub.add_parser("inspect", help="summarise a stage: layers, groups, agents, layers, cameras, lights",
                       description="Print a readable summary of a scenario or shot stage.")
    p.add_argument("stage", help="a .usda/.usdc/.usd stage")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    add_limits(p)
    p.set_defaults(run=run)


def run(args) -> int:
    from ..summary import format_summary, summarize

    s = summarize(args.stage, limits=limits_of(args))
    print(json.dumps(s, indent=2, default=str) if args.json else format_summary(s))
    return 0
