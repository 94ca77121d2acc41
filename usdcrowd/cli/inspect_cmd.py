"""usdcrowd inspect STAGE [--json] [--agents]"""

from __future__ import annotations

import json

from .args import add_limits, limits_of


def add_parser(sub):
    p = sub.add_parser("inspect", help="summarise a stage: layers, groups, agents, layers, cameras, lights",
                       description="Print a readable summary of a scenario or shot stage, or with --agents "
                                   "every agent's name, prim path, id, group, visibility and role.")
    p.add_argument("stage", help="a .usda/.usdc/.usd stage")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.add_argument("--agents", action="store_true",
                   help="list every agent instead (one line each: name, path, id, group, visible, role): the "
                        "names --targets, features and --like-targets take")
    add_limits(p)
    p.set_defaults(run=run, inputs=("stage",))


def run(args) -> int:
    from ..summary import agent_list, format_agents, format_summary, summarize

    if args.agents:
        agents = agent_list(args.stage, limits=limits_of(args))
        if args.json:           # a JSON array, one agent a line
            print("[" + ",\n ".join(json.dumps(a) for a in agents) + "]")
        else:
            print(format_agents(agents))
        return 0
    s = summarize(args.stage, limits=limits_of(args))
    print(json.dumps(s, indent=2, default=str) if args.json else format_summary(s))
    return 0
