"""``mrmt lorr``: League of Robot Runners instances -- run a scheduler and an executor, a whole round, or check a file.

    mrmt lorr run RANDOM-01.json --scheduler ising --planner pibt [--steps N] --out DIR
    mrmt lorr run A.json B.json --scheduler lorr-greedy,strong --seeds 2 --backend ray --out DIR
    mrmt lorr run RANDOM-01.json --entry default [--step-limit rules] --out DIR
    mrmt lorr round ROUND_DIR --entry default --out DIR [--steps N] [--resume]
    mrmt lorr sweep RANDOM-04.json --planner epibt-ising --chip n_spins=16,32,45,64 --out DIR
    mrmt lorr check RANDOM-01.json OUTPUT.json [--json]

``run`` prints, per instance x scheduler x seed, the tasks finished, the best-known and the
share, step-time p50/p99 (scheduler + executor, host + chip) and errors; with ``--out`` it
writes ``DIR/output.json`` (one run; ``DIR/<instance>-<scheduler>-<seed>.json`` for several) in
the start kit's output format and ``DIR/runs.json``.  Several runs go through the task runner
(``--backend inline|process|ray``, results identical to inline).  ``check`` re-simulates an
output file as the start kit's evaluation does.  ``--entry`` takes the scheduler, the planner and their options
from an entry (:mod:`agents.lorr.entry`) and runs under the rules' clock unless ``--step-limit`` says otherwise;
``round`` runs an entry on every instance of a round folder (:mod:`agents.lorr.round`).  Bad input: one line, exit 2.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

NAME = "lorr"
HELP = "League of Robot Runners instances: run a scheduler + executor, or check an output file"


def add_arguments(parser) -> None:
    from agents.commands.options import add_chip_argument, add_decision_arguments, add_runner_arguments

    from agents.commands import lorr_info, lorr_sweep

    sub = parser.add_subparsers(dest="lorr_command", required=True,
                                metavar="{run,round,sweep,check,startkit,options}")
    run = sub.add_parser("run", help="run instances with a scheduler and an executor (or an entry)")
    add_plan_arguments(run)
    run.add_argument("--entry", default=None, metavar="NAME|FILE",
                     help="an entry (default: the package's; or a .toml / .json file) chooses the scheduler, the "
                          "planner and their options per instance; runs under the rules' clock unless --step-limit "
                          "says otherwise")
    _add_clock_arguments(run, "default: none (work-bounded, deterministic); with --entry: rules")
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
    rnd.add_argument("--steps", type=int, default=None,
                     help="run the first N steps of each instance (a prefix: its share against the best-known "
                          "pro rata)")
    rnd.add_argument("--seed", type=int, default=0, help="seed (default 0)")
    rnd.add_argument("--best-known", default=None, metavar="FILE",
                     help="a best-known table ({round: {NAME: [agents, steps, tasks]}}); default: the package's "
                          "table of "
                          "the archive's published scores")
    rnd.add_argument("--resume", action="store_true",
                     help="keep instances already run by the same entry, steps, clock, seed")
    _add_clock_arguments(rnd, "default: rules")
    rnd.add_argument("--jobs", type=int, default=1,
                     help="instances at once (default 1: under the clock each instance wants the cores to itself)")
    rnd.add_argument("--backend", default="local", choices=("local", "ray"),
                     help="local: each instance in a fresh process here (default); ray: Ray tasks (--address)")
    rnd.add_argument("--address", default=None, help="a running Ray cluster's address (implies --backend ray)")
    rnd.add_argument("--no-progress", action="store_true", help="print nothing while instances run")
    lorr_info.add_parsers(sub)


def add_plan_arguments(run) -> None:
    """The arguments of what a run plays: instances, scheduler, planner, their options, steps and seeds (``run`` and
    ``sweep``)."""
    run.add_argument("instances", nargs="+", metavar="INSTANCE.json", help="LoRR instance files")
    run.add_argument("--scheduler", default=None,
                     help="comma-separated: lorr-greedy (the start kit's default), lorr-weighted (the 2024 winner's "
                          "measure), strong, ising, fast, ising-paper, a sharing+tour pair, ppo:MODEL.zip "
                          "(default lorr-greedy)")
    run.add_argument("--planner", default=None,
                     help="the one-step planner (the start kit's MAPFPlanner): pibt (PIBT with turning; default), "
                          "pibt-flow (PIBT along traffic-flow guide paths, the start kit's default planner), epibt (PIBT "
                          "over 3-action operations with large-neighbourhood search), epibt-chain (EPIBT by push chains, "
                          "the 2024 winner's plan: the best at density), epibt-chain-ising (epibt-chain with the chip "
                          "choosing neighbourhood groups of its plan), epibt-chain-work (epibt-chain "
                          "with the chip choosing who of the robots at work stay), epibt-ising (epibt with the chip choosing "
                          "neighbourhood groups), windowed, pibt-ising")
    run.add_argument("--executor", default=None, help="deprecated: the old name of --planner")
    run.add_argument("--guidance", type=int, default=None, metavar="N",
                     help="extra cost of a move against its lane (crisscross guidance, 0..16; 0 = off; "
                          "default: the executor's own, pibt 2, the others 0)")
    run.add_argument("--scheduler-option", action="append", default=[], metavar="KEY=VALUE",
                     help="an option of the scheduler's own, repeatable (e.g. lorr-weighted's weight=1, reassign=false; "
                          "values as --planner-option's)")
    run.add_argument("--planner-option", action="append", default=[], metavar="KEY=VALUE",
                     help="an option of the planner's own, repeatable (e.g. epibt's weight_power=2, lns=0, "
                          "op_len=4; values: numbers, true / false, null (JSON), else text; mrmt lorr options "
                          "lists each planner's)")
    run.add_argument("--executor-option", action="append", default=[], metavar="KEY=VALUE",
                     help="deprecated: the old name of --planner-option")
    run.add_argument("--steps", type=int, default=None, help="steps (default: the instance's simulation time)")
    run.add_argument("--seed", type=int, default=0, help="first seed (default 0)")
    run.add_argument("--seeds", type=int, default=1, help="seeds per instance and scheduler (default 1)")
    run.add_argument("--replan", action="store_true",
                     help="pipeline schedulers re-plan robots whose task is not opened yet when a task finishes")
    run.add_argument("--no-keep", action="store_true",
                     help="with --replan: re-plan from scratch (by default a re-planned robot keeps its task unless "
                          "given one of smaller makespan or its task goes to another robot)")


def _add_clock_arguments(parser, default: str) -> None:
    parser.add_argument("--step-limit", default=None, metavar="S|rules|none",
                        help=f"the start kit's clock: seconds per step for scheduler and planner together, "
                             f"rules (1 s), "
                             f"or none; a late decision makes every robot wait, counted as timeouts ({default})")
    parser.add_argument("--preprocess-limit", type=float, default=None, metavar="S",
                        help="seconds for preprocessing under the clock (default 30, the start kit's)")


def clock_from_args(args, default: str | None):
    """The :class:`~mrmt_env.lorr.clock.StepLimit` of ``--step-limit`` / ``--preprocess-limit`` (``default`` when
    ``--step-limit`` is not given), or ``None``; ``ValueError`` naming a bad value."""
    from mrmt_env.lorr.clock import RULES_PREPROCESS_S, step_limit

    text = args.step_limit if args.step_limit is not None else default
    prep = RULES_PREPROCESS_S if args.preprocess_limit is None else args.preprocess_limit
    if text is None or str(text).strip().lower() == "none":
        if args.preprocess_limit is not None:
            raise ValueError("--preprocess-limit acts under a clock: add --step-limit")
        return None
    try:
        return step_limit(text, prep)
    except ValueError as exc:
        raise ValueError(f"--step-limit / --preprocess-limit: {exc}") from None


def planner_aliases(args) -> None:
    """Fold the deprecated ``--executor`` / ``--executor-option`` into ``--planner`` / ``--planner-option`` (one
    warning line each); ``ValueError`` when both names are given."""
    for old, new, value in (("--executor", "--planner", "planner"), ("--executor-option", "--planner-option",
                                                                     "planner_option")):
        given = getattr(args, old[2:].replace("-", "_"))
        if not given:
            continue
        if getattr(args, value):
            raise ValueError(f"{old} is the old name of {new}: give {new} only")
        print(f"mrmt lorr: warning: {old} is deprecated; use {new}", file=sys.stderr)
        setattr(args, value, given)


def executor_options(executor: str, items: list[str], grid) -> dict:
    """``--planner-option`` items (:func:`~agents.keyvalues.key_values`) checked by :func:`check_executor_options`."""
    from agents.keyvalues import key_values

    return check_executor_options(executor, key_values(items, "--planner-option", "weight_power=2"), grid)


def check_executor_options(executor: str, options: dict, grid) -> dict:
    """``options`` when ``executor`` takes them all (its typed options record, then built once on ``grid``);
    ``ValueError`` naming an option the executor does not take (and those it takes) or a value it refuses."""
    from planners.mapf import TURNING_EXECUTORS

    cls = TURNING_EXECUTORS[executor]
    try:
        cls.Options.from_dict(options, executor)
        cls(grid, **options)
    except ValueError as exc:
        raise ValueError(f"--planner-option {exc}") from None
    return dict(options)


def _scheduler_own(options: dict) -> dict:
    """The scheduler's part of an entry rule's ``options``."""
    return {k: v for k, v in options.items() if k in ("replan", "keep", "scheduler_options")}


def check_entry(entry, chip=None) -> None:
    """Every rule of ``entry`` buildable: its scheduler by name, its planner and options on the example map;
    ``ValueError`` naming the entry's file and rule."""
    from agents.lorr.run import split_options
    from agents.lorr.schedulers import make_scheduler
    from mrmt_env.lorr.instance import example_instance_path, read_instance
    from planners.mapf import TURNING_EXECUTORS

    grid = read_instance(example_instance_path()).grid
    for rule in entry.rules:
        c = rule.choice
        where = f"{entry.source} rule {c.rule}"
        try:
            if c.planner not in TURNING_EXECUTORS:
                raise ValueError(f"unknown planner {c.planner!r}; known: {', '.join(TURNING_EXECUTORS)}")
            make_scheduler(c.scheduler, chip=chip, **_scheduler_own(c.options))
            check_executor_options(c.planner, split_options(c.options)[1], grid)  # guidance there too
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None


def lorr_task(instance: str, scheduler: str, executor: str, steps, seed: int, chip, options: dict, out: str | None,
              out_name: str | None, limit=None, progress: bool = False) -> dict:
    """One run (module level, for the task runner; ``progress``: a bar over its steps, for a run in this process);
    writes its output file when ``out`` is given."""
    from mrmt_env.lorr.output import write_output
    from agents.lorr.run import run_lorr

    record, sim, step_s = run_lorr(instance, scheduler, executor, steps=steps, seed=seed, chip=chip, options=options,
                                   limit=limit, progress=progress)
    if out:
        write_output(sim, Path(out) / out_name, planner_times=step_s)
        record["output"] = str(Path(out) / out_name)
    return record


def _fmt(x, spec: str) -> str:
    return "-" if x is None else format(x, spec)


def _table(rows: list[dict]) -> str:
    head = (f"{'instance':<12} {'scheduler':<12} {'seed':>4} {'robots':>6} {'steps':>5} {'tasks':>6} {'best':>6} "
            f"{'share':>6} {'p50 s':>8} {'p99 s':>8} {'errors':>6} {'sched.err':>9}")
    lines = [head]
    for r in rows:
        lines.append(f"{r['instance']:<12} {r['scheduler']:<12} {r['seed']:>4} {r['robots']:>6} {r['steps']:>5} "
                     f"{r['tasks_finished']:>6} {_fmt(r['best_known'], '>6')} {_fmt(r['share_of_best'], '>6.1%')} "
                     f"{r['step_p50_s']:>8.4f} {r['step_p99_s']:>8.4f} {r['errors']:>6} {r['schedule_errors']:>9}")
    return "\n".join(lines)


def _memory(options: dict) -> dict:
    """The planner's own memory bound among a run's ``options`` (``field_bytes``, and EPIBT's ``flow``), for its
    ``check_team``."""
    own = options.get("executor_options") or {}
    return {key: own[key] for key in ("field_bytes", "flow") if key in own}


def _plans(args, chip) -> tuple[list[tuple], object]:
    """``[(instance, scheduler, executor, options)]`` the flags or the entry ask for, every name and option checked,
    and the clock; ``ValueError`` naming what is wrong."""
    from agents.lorr.run import check_chip_use
    from agents.lorr.schedulers import make_scheduler
    from mrmt_env.lorr.instance import read_instance
    from planners.mapf import TURNING_EXECUTORS

    planner_aliases(args)
    insts = {path: read_instance(path) for path in args.instances}
    if args.entry is not None:
        from agents.lorr.entry import load_entry

        given = [f for f, v in (("--scheduler", args.scheduler), ("--planner", args.planner),
                                ("--guidance", args.guidance), ("--planner-option", args.planner_option),
                                ("--scheduler-option", args.scheduler_option),
                                ("--replan", args.replan), ("--no-keep", args.no_keep)) if v]
        if given:
            raise ValueError(f"--entry decides the scheduler, the planner and their options: drop {', '.join(given)}")
        entry = load_entry(args.entry)
        check_entry(entry, chip)
        plans = [(path, c.scheduler, c.planner, dict(c.options)) for path, inst in insts.items()
                 for c in [entry.choose(inst)]]
        if chip is not None:  # the machine runs under each instance's rule
            for path, s, planner, opts in plans:
                check_chip_use(chip, make_scheduler(s, chip=chip, **_scheduler_own(opts)), s, planner)
        return plans, clock_from_args(args, "rules")
    schedulers = [s.strip() for s in (args.scheduler or "lorr-greedy").split(",") if s.strip()]
    if not schedulers:
        raise ValueError("--scheduler names no scheduler")
    executor = args.planner or "pibt"
    if executor not in TURNING_EXECUTORS:
        raise ValueError(f"unknown planner {executor!r}; known: {', '.join(TURNING_EXECUTORS)}")
    options = {"replan": True} if args.replan else {}
    if args.no_keep:
        if not args.replan:
            raise ValueError("--no-keep acts on --replan: add --replan")
        options["keep"] = False
    if args.scheduler_option:
        from agents.keyvalues import key_values

        options["scheduler_options"] = key_values(args.scheduler_option, "--scheduler-option", "weight=1")
    for s in schedulers:  # names, model files and options checked before anything starts
        try:
            check_chip_use(chip, make_scheduler(s, chip=chip, **options), s, executor)
        except TypeError as exc:
            raise ValueError(f"--scheduler-option: {exc}") from None
    if args.guidance is not None:
        from planners.mapf import TURNING_EXECUTORS

        try:  # the planner's own record checks it, as every planner option
            options["guidance"] = TURNING_EXECUTORS[executor].Options(guidance=args.guidance).guidance
        except ValueError as exc:
            raise ValueError(f"--guidance: {exc}") from None
    if args.planner_option:
        grid = next(iter(insts.values())).grid
        options["executor_options"] = executor_options(executor, args.planner_option, grid)
    return [(path, s, executor, options) for path in insts for s in schedulers], clock_from_args(args, None)


def _bad_counts(args, *flags) -> str | None:
    """The error of the first of ``flags`` given below 1, or of a negative ``--seed``; ``None`` when all fit."""
    for flag in flags:
        value = getattr(args, flag[2:].replace("-", "_"))
        if value is not None and value < 1:
            return f"{flag} must be >= 1, got {value}"
    return f"--seed must be >= 0, got {args.seed}" if args.seed < 0 else None


def _run(args) -> int:
    from agents.commands.options import chip_from_args, runner_from_args
    from agents.runner import run_tasks
    from mrmt_env.lorr.instance import LoRRFormatError, read_instance
    from planners.mapf import TURNING_EXECUTORS

    bad = _bad_counts(args, "--steps", "--seeds")
    if bad:
        return _fail(bad)
    try:
        chip = chip_from_args(args)
        plans, limit = _plans(args, chip)
        for path, _, executor, options in plans:  # whether the executor takes the instance's team
            inst = read_instance(path)
            TURNING_EXECUTORS[executor].check_team(inst.grid, inst.team_size, **_memory(options))
        run = runner_from_args(args)
    except (LoRRFormatError, ValueError, OSError) as exc:
        return _fail(str(exc))
    if args.audit and Path(args.audit).exists() and not Path(args.audit).is_dir():
        return _fail(f"--audit {args.audit}: exists and is not a directory")
    jobs = [(*plan, seed) for plan in plans for seed in range(args.seed, args.seed + args.seeds)]
    single = len(jobs) == 1
    here = run.backend == "inline" or (single and run.backend != "ray")  # the runs in this process
    for flag, given, what in (("--audit", args.audit, "records"), ("--host-rule", args.host_rule, "acts on")):
        if given and not here:
            return _fail(f"{flag} {what} the decisions made in this process: use --backend inline, not {run.backend}")
    from agents.commands.options import host_rule_from_args

    try:
        host_rule = host_rule_from_args(args)
    except ValueError as exc:
        return _fail(f"--host-rule: {exc}")
    tasks = [(inst, s, ex, args.steps, seed, chip, options, args.out,
              "output.json" if single else f"{Path(inst).stem}-{s.replace(':', '_').replace('/', '_')}-{seed}.json",
              limit)
             for inst, s, ex, options, seed in jobs]
    progress = not args.no_progress
    if not args.address:  # one notice and a parallel compile on a new install (agents/warmup.py)
        _warm_parts([(s, ex) for _, s, ex, _ in plans], progress)
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


def _warm_parts(pairs, progress: bool) -> None:
    """Compile the kernels of ``(scheduler, executor)`` pairs now, on the cores, with one notice (agents/warmup.py)."""
    import os

    from agents.warmup import warm

    parts = {f"lorr:{ex}" for _, ex in pairs} | {s for s, _ in pairs if s != "lorr-greedy" and not s.startswith("ppo:")}
    warm(sorted(parts), jobs=min(2, os.cpu_count() or 1), progress=progress)


def _round(args) -> int:
    from agents.lorr.entry import load_entry
    from agents.lorr.round import best_known_table, round_instances, run_round, summary_table
    from mrmt_env.lorr.instance import LoRRFormatError, read_instance
    from planners.mapf import TURNING_EXECUTORS

    bad = _bad_counts(args, "--steps", "--jobs")
    if bad:
        return _fail(bad)
    try:
        entry = load_entry(args.entry)
        check_entry(entry)
        limit = clock_from_args(args, "rules")
        best = best_known_table(args.best_known)
        paths = round_instances(args.folder)
        pairs = set()
        for path in paths:  # every instance readable, and its planner able to take its team
            inst = read_instance(path)
            if args.steps is None and inst.steps is None and inst.name not in best:
                raise ValueError(f"{path}: no simulation time (no simulation_time.json beside it, no best-known row): "
                                 f"give --steps")
            c = entry.choose(inst)
            TURNING_EXECUTORS[c.planner].check_team(inst.grid, inst.team_size, **_memory(c.options))
            pairs.add((c.scheduler, c.planner))
        backend = "ray" if args.address else args.backend
        if backend == "ray":
            from agents.runner import _ray

            _ray(local=not args.address)
    except (LoRRFormatError, ValueError, OSError) as exc:
        return _fail(str(exc))
    progress = not args.no_progress
    if not args.address:
        _warm_parts(sorted(pairs), progress)
    summary = run_round(args.folder, entry, args.out, steps=args.steps, seed=args.seed, limit=limit, best=best,
                        resume=args.resume, jobs=args.jobs, backend=backend, address=args.address, progress=progress)
    print(summary_table(summary))
    print(f"wrote {Path(args.out) / 'summary.json'}, summary.md and {summary.instances} output file(s)",
          file=sys.stderr)
    return 0


def _fail(message: str) -> int:
    print(f"mrmt lorr: error: {message}", file=sys.stderr)
    return 2


def run(args) -> int:
    from agents.commands import lorr_info, lorr_sweep

    return {"run": _run, "round": _round, "sweep": lorr_sweep.run, "check": lorr_info.check,
            "startkit": lorr_info.startkit, "options": lorr_info.options}[args.lorr_command](args)
