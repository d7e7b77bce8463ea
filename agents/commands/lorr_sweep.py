"""``mrmt lorr sweep``: a scheduler and planner over a grid of Ising machines on League instances, each machine
beside its host-rule twin.

    mrmt lorr sweep RANDOM-04.json --planner epibt-ising --planner-option lns=0 --planner-option rounds=4096 \\
        --scheduler strong --replan --chip n_spins=16,32,45,64 --steps 200 --step-limit rules --out DIR

``--chip KEY=V1,V2,...`` is a sweep axis as in ``mrmt sweep`` (repeatable; the grid is the product);
``--base-chip`` the fields that do not vary; ``--sampler`` a dimod sampler behind every spec.  Writes ``sweep.csv``,
``sweep.json``, ``summary.md`` and ``sweep.png`` (:mod:`agents.lorr.sweep`).  Bad input: one line, exit 2.
"""

from __future__ import annotations

import sys


def add_parser(sub) -> None:
    from agents.commands.lorr_args import add_clock_arguments, add_plan_arguments
    from agents.commands.options import add_chip_argument, add_runner_arguments

    p = sub.add_parser("sweep", help="run a scheduler and planner over a grid of Ising machines, each beside its "
                                     "host-rule twin")
    add_plan_arguments(p)
    p.add_argument("--chip", action="append", default=[], metavar="KEY=V1,V2,...",
                   help="a sweep axis: a ChipSpec field (or n_cores, coef_range) and its values, e.g. "
                        "n_spins=16,32,45,64; repeatable, the grid is the product (with --budget: default the "
                        "paper's chip alone)")
    p.add_argument("--budget", default=None, metavar="S1,S2,...",
                   help="the host's front: step budgets in seconds (the clock per step, e.g. 0.05,0.2,1); each "
                        "--host-planner at each, the --planner on every --chip spec at the largest and on the first "
                        "spec at each, beside its host-rule twin; writes front.csv, front.json, front.md, front.png")
    p.add_argument("--host-planner", default=None, metavar="NAME[,NAME]",
                   help="with --budget: the host planners of the front (default epibt,epibt-chain), with --guidance "
                        "if given, else their own options")
    p.add_argument("--resume", action="store_true",
                   help="with --budget: keep the runs already in OUT/front.csv (same instance, kind, planner, spec, "
                        "budget, seed, steps)")
    p.add_argument("--base-chip", action="append", default=[], metavar="KEY=VALUE|FILE.json",
                   help="fixed ChipSpec fields under the grid; repeatable")
    add_chip_argument(p, "every machine of the grid", chip=False)
    add_clock_arguments(p, "default: none (work-bounded, deterministic)")
    p.add_argument("--out", required=True, help="directory for sweep.csv, sweep.json, summary.md, sweep.png")
    add_runner_arguments(p)
    p.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    p.set_defaults(entry=None)


def run(args) -> int:
    if args.budget is not None or args.host_planner is not None or args.resume:
        from agents.commands.lorr_front import run_front

        return run_front(args)
    from agents.commands.lorr_args import bad_counts, best_row, fail, plans_from_args, steps_for, warm_parts
    from agents.commands.options import chip_from_args, runner_from_args
    from agents.lorr.sweep import DECIDERS, sweep_rows, sweep_task, write_sweep
    from agents.runner import run_tasks
    from agents.sweep import chip_grid, parse_axes
    from mrmt_env.lorr.instance import LoRRFormatError, read_instance

    bad = bad_counts(args, "--steps", "--seeds")
    if bad:
        return fail(bad)
    if not args.chip:
        return fail("--chip: give at least one sweep axis (e.g. --chip n_spins=16,45,64), or --budget for the host's "
                    "front")
    if args.scheduler and "," in args.scheduler:
        return fail(f"--scheduler {args.scheduler}: a sweep runs one scheduler (its axes are the machines); give one")
    try:
        grid = chip_grid(parse_axes(args.chip), chip_from_args(args, key="base_chip"))
        # names and options checked, and that a machine decides something
        plans, limit = plans_from_args(args, grid[0][1])
        steps = {}
        for path, _, planner in plans:  # its steps (as run's), and whether the planner takes its team
            inst = read_instance(path)
            steps[path] = steps_for(path, inst, args.steps, best_row(inst))
            planner.check_team(inst.grid, inst.team_size)
        run_cfg = runner_from_args(args)
        if limit is not None and run_cfg.backend != "inline" and args.jobs > 1:
            raise ValueError(f"--step-limit with --jobs {args.jobs}: runs under a clock want the cores to themselves; "
                             f"give --jobs 1")
    except (LoRRFormatError, ValueError, OSError) as exc:
        return fail(str(exc))
    labels, tasks = [], []
    for inst, s, ex in plans:
        for spec_id, (axis, chip) in enumerate(grid):
            name = ",".join(f"{k}={v}" for k, v in axis.items())
            for seed in range(args.seed, args.seed + args.seeds):
                for decider in DECIDERS:
                    labels.append((spec_id, name, decider))
                    tasks.append((inst, s, ex, steps[inst], seed, chip, decider, limit))
    if not args.address:
        warm_parts([(s.name, ex.name) for _, s, ex in plans], not args.no_progress)
    try:
        records = run_tasks(sweep_task, tasks, run_cfg, desc="lorr sweep", unit="run")
    except ValueError as exc:  # a spec of the grid the planner refuses (e.g. fewer spins than a group needs)
        return fail(str(exc))
    title = f"{plans[0][1].name} + {plans[0][2].name} over {len(grid)} machine(s)"
    summary = write_sweep(sweep_rows(records, labels), args.out, title)
    for s in summary:
        ratio = "-" if s["ratio"] is None else f"{s['ratio']:.3f}"
        print(f"{s['instance']:<12} {s['spec']:<24} tasks {s['machine_tasks']:>7} host rule {s['host_rule_tasks']:>7} "
              f"ratio {ratio}")
    print(f"wrote sweep.csv, sweep.json, summary.md and sweep.png in {args.out}", file=sys.stderr)
    return 0
