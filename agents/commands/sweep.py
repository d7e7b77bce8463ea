"""``mrmt sweep``: a grid of chip specs x worlds x controllers, Pareto figures and a summary.

    mrmt sweep --chip n_spins=32,45,64 --chip j_range=3,7,15 --worlds 100 --controllers ising,strong --out sw
    mrmt sweep ... --backend ray                       # a local Ray instance (127.0.0.1 only)
    mrmt sweep ... --address 10.0.0.5:6379             # an existing Ray cluster

Axes and files: docs/design/sweep.md#the-command-line.
"""

from __future__ import annotations

import sys

from agents.commands.options import (add_chip_argument, add_runner_arguments, add_world_arguments, chip_from_args, check_positive,
                                     check_seed, runner_from_args)

NAME = "sweep"
HELP = "sweep chip specs (a grid of ChipSpec values) over worlds and controllers; Pareto figures and a summary"


def add_arguments(parser) -> None:
    parser.add_argument("--chip", action="append", default=[], metavar="KEY=V1,V2,...", required=True,
                        help="a sweep axis: a ChipSpec field (or n_cores, coef_range) and its values, e.g. n_spins=32,45,64 "
                             "or j_range=3,7,15 (m means (-m, m); lo..hi for another range); repeatable, the "
                             "grid is the product")
    parser.add_argument("--base-chip", action="append", default=[], metavar="KEY=VALUE|FILE.json",
                        help="fixed ChipSpec fields under the grid (as --chip of mrmt plan); repeatable")
    add_chip_argument(parser, "the chip controllers (each spec of the grid)", chip=False)
    parser.add_argument("--controllers", default="ising,strong",
                        help="comma-separated controllers (as mrmt compare); those with an Ising layer run once "
                             "per spec, the others once (default ising,strong)")
    parser.add_argument("--reference", default=None,
                        help="chip-free controller the gaps are measured against (default: strong when it is "
                             "among --controllers; none for none)")
    parser.add_argument("--worlds", type=int, default=20, help="worlds per spec and controller (default 20)")
    parser.add_argument("--seed", type=int, default=0, help="first world seed (default 0)")
    parser.add_argument("--seeds", type=int, default=1, help="controller seeds per world: 0..K-1 (default 1)")
    add_world_arguments(parser, density=False)
    parser.add_argument("--max-steps", type=int, default=None, help="episode step limit (default as mrmt compare)")
    add_runner_arguments(parser)
    parser.add_argument("--out", required=True, help="output directory")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")


def run(args) -> int:
    def fail(msg: str) -> int:
        print(f"mrmt sweep: error: {msg}", file=sys.stderr)
        return 2

    problem = check_positive(args, ("worlds", "seeds", "robots", "targets", "height", "width", "max-steps"))
    problem = problem or check_seed("--seed", args.seed, args.worlds)
    if problem:
        return fail(problem)
    import gymnasium as gym

    import mrmt_env  # noqa: F401  (registers the ids)
    from agents.errors import ControllerError
    from agents.sweep import SweepConfig, checked_grid, parse_axes, run_sweep
    from agents.sweep_report import write_report

    if args.env_id not in gym.registry:
        known = ", ".join(sorted(k for k in gym.registry if k.startswith("mrmt_env/")))
        return fail(f"unknown env id {args.env_id!r}; registered: {known}")
    given = {"n_robots": args.robots, "n_targets": args.targets, "height": args.height, "width": args.width,
             "placement": args.placement, "layout": args.layout}
    try:
        run_cfg = runner_from_args(args)
        base = chip_from_args(args, key="base_chip")
        config = SweepConfig(axes=parse_axes(args.chip), controllers=tuple(args.controllers.split(",")),
                             n_worlds=args.worlds, world_seed=args.seed, seeds=tuple(range(args.seeds)),
                             env_id=args.env_id, env_kwargs={k: v for k, v in given.items() if v is not None},
                             max_steps=args.max_steps)
        reference = args.reference
        if reference is None:
            reference = "strong" if "strong" in config.controllers else None
        elif reference.lower() == "none":
            reference = None
        if reference is not None and reference not in config.controllers:
            return fail(f"--reference {reference!r} is not among --controllers {args.controllers!r}")
        checked_grid(config, base)  # a bad axis value is named before anything compiles
        if not args.address:  # compile once, in parallel, before the workers need it (agents/warmup.py)
            from agents.warmup import warm

            warm(config.controllers, jobs=args.jobs, progress=not args.no_progress, world_kwargs=config.env_kwargs)
        result = run_sweep(config, run_cfg, base_chip=base)
    except (ControllerError, ValueError) as exc:
        return fail(str(exc).splitlines()[0])
    files = write_report(result, args.out, reference)
    from pathlib import Path

    print(Path(args.out, "summary.md").read_text())
    print(f"wrote {len(files)} files to {args.out}", file=sys.stderr)
    return 0
