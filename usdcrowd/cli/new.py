"""usdcrowd new TEMPLATE -o scenario.usda [--agents N] [--seed S] [--scenery DCC.usda]"""

from __future__ import annotations

from .args import add_force, add_limits, add_seed, int_at_least, limits_of


def add_parser(sub):
    from ..jobs.templates import list_templates

    p = sub.add_parser("new", help="write a scenario stage from an example template",
                       description="Write a scenario stage from one of the example scenes in stages/.")
    p.add_argument("template", help=f"one of: {', '.join(list_templates())}")
    p.add_argument("-o", "--output", required=True, help="the new stage (.usda, .usdc or .usd)")
    p.add_argument("--agents", type=int_at_least(1), help="total number of agents (clones are rescaled per group)")
    p.add_argument("--scenery", metavar="USD", help="a DCC tool's scenery (any up axis and units) in place of the "
                                                   "template's: each of its root prims referenced with the "
                                                   "transform it needs")
    add_seed(p)
    add_limits(p)
    add_force(p)
    p.set_defaults(run=run, inputs=("scenery",), outputs=("output",))


def run(args) -> int:
    from ..core.errors import UsdcrowdError
    from ..jobs.templates import new_scenario

    limit = limits_of(args).max_agents
    if args.agents is not None and args.agents > limit:
        raise UsdcrowdError(f"{args.agents:,} agents: more than the {limit:,} accepted (raise it with --max-agents)",
                            attribute="--agents")
    info = new_scenario(args.template, args.output, args.agents, args.seed, scenery=args.scenery)
    print(f"wrote {info['path']}: template {args.template}, {info['agents']} agents, seed {info['seed']}")
    if info["scenery_roots"]:
        print(f"  scenery {args.scenery}: {', '.join(info['scenery_roots'])}")
    for asset in info["assets"]:
        print(f"  asset {asset}")
    return 0
