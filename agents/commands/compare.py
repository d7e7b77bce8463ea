"""``mrmt compare``: planners and learned agents on the same worlds, one table.

    mrmt compare --worlds 20 --robots 3 --targets 10 --controllers fast,strong,ising,ppo:model.zip

Runs the evaluation (:mod:`agents.evaluation`) on the task runner and prints the summary table (medians);
``--out DIR`` writes one row per episode. Design notes: docs/design/cli.md#mrmt-compare.
"""

from __future__ import annotations

import sys

from agents.commands.options import (add_chip_argument, add_decision_arguments, chip_from_args, host_rule_from_args, add_runner_arguments, check_positive, check_seed,
                                     add_world_arguments, runner_from_args)

NAME = "compare"
HELP = "compare planners and learned agents episode by episode on the same worlds"


def add_arguments(parser) -> None:
    parser.add_argument("--worlds", type=int, default=20, help="worlds (episodes) per controller and seed (default 20)")
    add_world_arguments(parser)
    parser.add_argument(
        "--controllers",
        default="fast,strong,ising",
        help="comma-separated: fast, strong, ising, ising-paper, exact, pyvrp, ortools, ising-fleet, sharing+tour+path (e.g. ssa+brute+astar), ppo:MODEL.zip",
    )
    parser.add_argument("--seed", type=int, default=0, help="first world seed (default 0)")
    parser.add_argument("--seeds", type=int, default=1, help="controller seeds per world: 0..K-1 (default 1)")
    parser.add_argument("--max-steps", type=int, default=None,
                        help="episode step limit (default: the env id's, 200 on 10x10, scaled up with the "
                             "grid's height + width and the target count)")
    add_runner_arguments(parser)
    add_chip_argument(parser)
    parser.add_argument("--out", default=None, help="directory for episodes.csv and episodes.json")
    add_decision_arguments(parser, "--jobs 1, inline only")


def _error(message: str) -> int:
    print(f"mrmt compare: error: {message}", file=sys.stderr)
    return 2


def run(args) -> int:
    from contextlib import nullcontext
    from pathlib import Path

    from ising_backend.audit.record import Audit

    elsewhere = (args.backend not in (None, "inline")) or args.address or (args.jobs or 1) > 1
    for flag, given, what in (("--audit", args.audit, "records"), ("--host-rule", args.host_rule, "acts on")):
        if given and elsewhere:
            return _error(f"{flag} {what} the decisions made in this process: use --jobs 1 and the inline backend")
    if args.audit and Path(args.audit).exists() and not Path(args.audit).is_dir():
        return _error(f"--audit {args.audit}: exists and is not a directory")
    try:
        host_rule = host_rule_from_args(args)
    except ValueError as exc:
        return _error(f"--host-rule: {exc}")
    with Audit(args.audit) if args.audit else nullcontext(), host_rule:
        return _run(args)


def _run(args) -> int:
    from agents.env_ids import check_env_id, check_worlds
    from agents.lifelong.evaluation import is_lifelong_id, run_compare

    try:  # the env id first: the controllers it takes depend on it
        check_env_id(args.env_id)
    except ValueError as exc:
        print(f"mrmt compare: error: {exc}", file=sys.stderr)
        return 2
    if is_lifelong_id(args.env_id):  # tasks keep arriving: greedy / pipelines through PIBT (agents.lifelong.controllers)
        return run_compare(args)
    from agents.evaluation import ControllerError, check_chip_use, evaluate, parse_controllers

    try:
        specs = parse_controllers(args.controllers)
    except ControllerError as exc:
        print(f"mrmt compare: error: {exc}", file=sys.stderr)
        return 2
    problem = check_positive(args, ("worlds", "robots", "targets", "height", "width", "jobs", "seeds",
                                    "max-steps"))
    problem = problem or check_seed("--seed", args.seed, args.worlds)
    if problem:
        print(f"mrmt compare: error: {problem}", file=sys.stderr)
        return 2
    given = {
        "n_robots": args.robots,
        "n_targets": args.targets,
        "height": args.height,
        "width": args.width,
        "obstacle_density": args.density,
        "placement": args.placement,
        "layout": args.layout,
    }
    env_kwargs = {k: v for k, v in given.items() if v is not None}
    try:
        run = runner_from_args(args)
        chip = chip_from_args(args)
        check_worlds(args.env_id, env_kwargs, range(args.seed, args.seed + args.worlds))  # before any pool or bar
        check_chip_use(specs, chip)  # before the compile notice
        if not args.address:  # compile once, in parallel, before the workers need it (agents/warmup.py)
            from agents.warmup import warm

            warm(specs, jobs=args.jobs, progress=not args.no_progress, world_kwargs=env_kwargs)
        result = evaluate(
            specs,
            n_worlds=args.worlds,
            seeds=range(args.seeds),
            world_seed=args.seed,
            env_id=args.env_id,
            env_kwargs=env_kwargs,
            chip=chip,
            max_steps=args.max_steps,
            run=run,
        )
    except (ControllerError, ValueError) as exc:
        print(f"mrmt compare: error: {exc}", file=sys.stderr)
        return 2
    print(result.format_summary())
    if args.out:
        from pathlib import Path

        out = Path(args.out)
        result.to_csv(out / "episodes.csv")
        result.to_json(out / "episodes.json")
        print(f"wrote {out / 'episodes.csv'} and {out / 'episodes.json'}", file=sys.stderr)
    return 0
