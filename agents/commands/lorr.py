"""``mrmt lorr``: League of Robot Runners instances -- run a scheduler and an executor, a whole round, or check a file.

    mrmt lorr run RANDOM-01.json --scheduler ising --planner pibt [--steps N] --out DIR
    mrmt lorr round ROUND_DIR --entry default --out DIR [--steps N] [--resume]
    mrmt lorr generate family:warehouse:64x64 --agents 100 --seed 0 --out DIR/WH-01.json
    mrmt lorr check RANDOM-01.json OUTPUT.json [--json]

More forms, what each reports and writes: docs/design/cli.md#mrmt-lorr.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from agents.commands import lorr_generate, lorr_info, lorr_sweep
from agents.commands.lorr_args import (STEPS_HELP, add_clock_arguments, add_plan_arguments, bad_counts, best_row,
                                       check_entry, clock_from_args, fail, full_steps,
                                       plans_from_args, score_prefix, share_cell, steps_cell, steps_for, warm_parts)

NAME = "lorr"
HELP = ("League of Robot Runners instances: run a scheduler + executor or a round, generate an instance, or check an "
        "output file")


def add_arguments(parser) -> None:
    from agents.commands.options import add_chip_argument, add_decision_arguments, add_runner_arguments

    sub = parser.add_subparsers(dest="lorr_command", required=True,
                                metavar="{run,round,sweep,generate,check,startkit,options}")
    run = sub.add_parser("run", help="run instances with a scheduler and an executor (or an entry)")
    add_plan_arguments(run)
    run.add_argument("--entry", default=None, metavar="NAME|FILE",
                     help="an entry (default: the package's; or a .toml / .json file) chooses the scheduler, the "
                          "planner and their options per instance; runs under the rules' clock unless --step-limit "
                          "says otherwise")
    add_clock_arguments(run, "default: none (work-bounded, deterministic); with --entry: rules")
    run.add_argument("--out", default=None, help="directory for output.json (start kit format) and runs.json")
    run.add_argument("--json", action="store_true", help="print the runs as JSON lines instead of a table")
    add_decision_arguments(run, "inline backend only")
    add_runner_arguments(run)
    add_chip_argument(run, who="the ising scheduler and the chip planners (epibt-ising, pibt-ising)")
    lorr_sweep.add_parser(sub)
    rnd = sub.add_parser("round", help="run an entry on every instance of a round folder, scored as the League scores")
    rnd.add_argument("folder", metavar="ROUND_DIR", help="a round folder of the archive (e.g. '2024 Competition/Main "
                                                         "Round Evaluation Instances'): <domain>/<NAME>.json")
    rnd.add_argument("--entry", default="default", metavar="NAME|FILE", help="the entry (default: the package's)")
    rnd.add_argument("--out", required=True,
                     help="directory: <NAME>/output.json and run.json, summary.json, summary.md")
    rnd.add_argument("--steps", type=int, default=None, help=STEPS_HELP)
    rnd.add_argument("--seed", type=int, default=0, help="seed (default 0)")
    rnd.add_argument("--best-known", default=None, metavar="FILE",
                     help="a best-known table ({round: {NAME: [agents, steps, tasks]}}); default: the package's "
                          "table of "
                          "the archive's published scores")
    rnd.add_argument("--resume", action="store_true",
                     help="keep instances already run by the same entry, steps, clock, seed")
    add_clock_arguments(rnd, "default: rules")
    rnd.add_argument("--jobs", type=int, default=1,
                     help="instances at once (default 1: under the clock each instance wants the cores to itself)")
    rnd.add_argument("--backend", default="local", choices=("local", "ray"),
                     help="local: each instance in a fresh process here (default); ray: Ray tasks (--address)")
    rnd.add_argument("--address", default=None, help="a running Ray cluster's address (implies --backend ray)")
    rnd.add_argument("--no-progress", action="store_true", help="print nothing while instances run")
    lorr_generate.add_parser(sub)
    lorr_info.add_parsers(sub)


def lorr_task(instance: str, scheduler, planner, steps, seed: int, chip, out: str | None, out_name: str | None,
              limit=None, full: int | None = None, progress: bool = False) -> dict:
    """One run (module level, for the task runner; ``progress``: a bar over its steps, for a run in this process);
    writes its output file when ``out`` is given; ``full``: the instance's full steps, for its share
    (:func:`~agents.commands.lorr_args.score_prefix`)."""
    from mrmt_env.lorr.output import write_output
    from agents.lorr.run import run_lorr

    record, sim, step_s = run_lorr(instance, scheduler, planner, steps=steps, seed=seed, chip=chip, limit=limit,
                                   progress=progress)
    if out:
        write_output(sim, Path(out) / out_name, planner_times=step_s)
        record["output"] = str(Path(out) / out_name)
    return score_prefix(record, full)


def _table(rows: list[dict]) -> str:
    """The runs as a table: steps (``N of FULL`` for a prefix), share (``(pro rata)`` for a prefix), timeouts, as the
    round's summary reports them; the clock above."""
    def cell(x):
        return "-" if x is None else str(x)

    clocks = sorted({r["clock"] for r in rows})
    head = (f"{'instance':<12} {'scheduler':<12} {'planner':<12} {'seed':>4} {'robots':>6} {'steps':>11} "
            f"{'tasks':>6} {'best':>6} {'share':<17} {'timeouts':>8} {'p50 s':>8} {'p99 s':>8} {'errors':>6} "
            f"{'sched.err':>9}")
    lines = [f"clock: {', '.join(clocks)}", head]
    for r in rows:
        lines.append(f"{r['instance']:<12} {r['scheduler']:<12} {r['executor']:<12} {r['seed']:>4} {r['robots']:>6} "
                     f"{steps_cell(r):>11} {r['tasks_finished']:>6} {cell(r['best_known']):>6} {share_cell(r):<17} "
                     f"{r['timeouts']:>8} {r['step_p50_s']:>8.4f} {r['step_p99_s']:>8.4f} {r['errors']:>6} "
                     f"{r['schedule_errors']:>9}")
    return "\n".join(lines)


def _run(args) -> int:
    from agents.commands.options import chip_from_args, runner_from_args
    from agents.runner import run_tasks
    from mrmt_env.lorr.instance import LoRRFormatError, read_instance

    bad = bad_counts(args, "--steps", "--seeds")
    if bad:
        return fail(bad)
    try:
        chip = chip_from_args(args)
        plans, limit = plans_from_args(args, chip)
        steps = {}
        for path, _, planner in plans:  # its steps, and whether the planner takes the instance's team
            inst = read_instance(path)
            row = best_row(inst)
            steps[path] = (steps_for(path, inst, args.steps, row), full_steps(inst, row))
            planner.check_team(inst.grid, inst.team_size)
        run = runner_from_args(args)
    except (LoRRFormatError, ValueError, OSError) as exc:
        return fail(str(exc))
    if args.audit and Path(args.audit).exists() and not Path(args.audit).is_dir():
        return fail(f"--audit {args.audit}: exists and is not a directory")
    jobs = [(*plan, seed) for plan in plans for seed in range(args.seed, args.seed + args.seeds)]
    single = len(jobs) == 1
    here = run.backend == "inline" or (single and run.backend != "ray")  # the runs in this process
    for flag, given, what in (("--audit", args.audit, "records"), ("--host-rule", args.host_rule, "acts on")):
        if given and not here:
            return fail(f"{flag} {what} the decisions made in this process: use --backend inline, not {run.backend}")
    from agents.commands.options import host_rule_from_args

    try:
        host_rule = host_rule_from_args(args)
    except ValueError as exc:
        return fail(f"--host-rule: {exc}")
    tasks = [(inst, s, ex, steps[inst][0], seed, chip, args.out,
              "output.json" if single else f"{Path(inst).stem}-{s.name.replace(':', '_').replace('/', '_')}-{seed}.json",
              limit, steps[inst][1])
             for inst, s, ex, seed in jobs]
    progress = not args.no_progress
    if not args.address:  # one notice and a parallel compile on a new install (agents/warmup.py)
        warm_parts([(s.name, ex.name) for _, s, ex in plans], progress)
    from contextlib import nullcontext

    from ising_backend.audit.record import Audit

    with Audit(args.audit) if args.audit else nullcontext(), host_rule:
        if single and run.backend != "ray":
            rows = [lorr_task(*tasks[0], progress=progress)]
        else:
            rows = run_tasks(lorr_task, tasks, run)
    if args.json:
        for r in rows:
            print(json.dumps(r))
    else:
        print(_table(rows))
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "runs.json").write_text(json.dumps(rows, indent=1))
        print(f"wrote {out / 'runs.json'} and {len(rows)} output file(s) in {out}", file=sys.stderr)
    return 0


def _round(args) -> int:
    from agents.lorr.entry import load_entry
    from agents.lorr.round import best_known_table, round_instances, run_round, summary_table
    from mrmt_env.lorr.instance import LoRRFormatError, read_instance

    bad = bad_counts(args, "--steps", "--jobs")
    if bad:
        return fail(bad)
    try:
        entry = load_entry(args.entry)
        check_entry(entry)
        limit = clock_from_args(args, "rules")
        best = best_known_table(args.best_known)
        paths = round_instances(args.folder)
        pairs = set()
        for path in paths:  # every instance readable, and its planner able to take its team
            inst = read_instance(path)
            steps_for(path, inst, args.steps, best_row(inst, best))  # the round's steps known
            c = entry.choose(inst)
            c.planner.check_team(inst.grid, inst.team_size)
            pairs.add((c.scheduler.name, c.planner.name))
        backend = "ray" if args.address else args.backend
        if backend == "ray":
            from agents.runner import _ray

            _ray(local=not args.address)
    except (LoRRFormatError, ValueError, OSError) as exc:
        return fail(str(exc))
    progress = not args.no_progress
    if not args.address:
        warm_parts(sorted(pairs), progress)
    summary = run_round(args.folder, entry, args.out, steps=args.steps, seed=args.seed, limit=limit, best=best,
                        resume=args.resume, jobs=args.jobs, backend=backend, address=args.address, progress=progress)
    print(summary_table(summary))
    print(f"wrote {Path(args.out) / 'summary.json'}, summary.md and {summary.instances} output file(s)",
          file=sys.stderr)
    return 0


def run(args) -> int:
    return {"run": _run, "round": _round, "sweep": lorr_sweep.run, "generate": lorr_generate.run,
            "check": lorr_info.check, "startkit": lorr_info.startkit,
            "options": lorr_info.options}[args.lorr_command](args)
