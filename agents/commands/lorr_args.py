"""What the ``mrmt lorr`` commands share: the arguments of a run (instances, scheduler, planner, options, steps,
seeds, clock), their checks, the steps an instance runs and how a run's share of the best-known is reported.

``run``, ``round`` and ``sweep`` import this module; none of them imports another.  The steps of an instance:
``--steps``, else its simulation time (``simulation_time.json`` beside it or one folder up), else its best-known
row's steps; with none of them the command stops (one line, exit 2).  A run shorter than that is a prefix: its share
is of the best-known pro rata, ``tasks / (best x steps / full)``, as :func:`agents.lorr.round.round_task` scores it.
"""

from __future__ import annotations

import sys

STEPS_HELP = ("steps (default: the instance's simulation time: its simulation_time.json, else its best-known row's "
              "steps; fewer steps are a prefix, scored against the best-known pro rata)")

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
                          "choosing neighbourhood groups of its plan), epibt-ising (epibt with the chip choosing "
                          "neighbourhood groups), pibt-ising (pibt with the chip's joint moves), or a planner of your "
                          "own as package.module:Class (agents.lorr.roles)")
    run.add_argument("--executor", default=None, help="deprecated: the old name of --planner")
    run.add_argument("--guidance", type=int, default=None, metavar="N",
                     help="the planner option guidance: extra cost of a move against its lane (crisscross guidance, "
                          "0..16; 0 = off; default: the planner's own, pibt 2, the others 0)")
    run.add_argument("--scheduler-option", action="append", default=[], metavar="KEY=VALUE",
                     help="an option of the scheduler's own, repeatable (e.g. lorr-weighted's weight=1, reassign=false; "
                          "values as --planner-option's)")
    run.add_argument("--planner-option", action="append", default=[], metavar="KEY=VALUE",
                     help="an option of the planner's own, repeatable (e.g. epibt's weight_power=2, lns=0, "
                          "op_len=4; values: numbers, true / false, null (JSON), else text; mrmt lorr options "
                          "lists each planner's)")
    run.add_argument("--executor-option", action="append", default=[], metavar="KEY=VALUE",
                     help="deprecated: the old name of --planner-option")
    run.add_argument("--steps", type=int, default=None, help=STEPS_HELP)
    run.add_argument("--seed", type=int, default=0, help="first seed (default 0)")
    run.add_argument("--seeds", type=int, default=1, help="seeds per instance and scheduler (default 1)")
    run.add_argument("--replan", action="store_true",
                     help="pipeline schedulers re-plan robots whose task is not opened yet when a task finishes")
    run.add_argument("--no-keep", action="store_true",
                     help="with --replan: re-plan from scratch (by default a re-planned robot keeps its task unless "
                          "given one of smaller makespan or its task goes to another robot)")


def add_clock_arguments(parser, default: str) -> None:
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


def planner_options(planner: str, items: list[str]) -> dict:
    """``--planner-option`` items (:func:`~agents.keyvalues.key_values`) as a dict (checked by the spec)."""
    from agents.keyvalues import key_values

    return key_values(items, "--planner-option", "weight_power=2") if items else {}


def check_entry(entry, chip=None) -> None:
    """Every rule of ``entry`` buildable: its scheduler (built once) and its planner on the example map;
    ``ValueError`` naming the entry's file and rule."""
    from mrmt_env.lorr.instance import example_instance_path, read_instance

    grid = read_instance(example_instance_path()).grid
    for rule in entry.rules:
        c = rule.choice
        try:
            c.scheduler.build(0, chip)
            c.planner.build(grid)
        except ValueError as exc:
            raise ValueError(f"{entry.source} rule {c.rule}: {exc}") from None


def plans_from_args(args, chip) -> tuple[list[tuple], object]:
    """``[(instance, SchedulerSpec, PlannerSpec)]`` the flags or the entry ask for, every name and option checked
    (:mod:`agents.lorr.spec`), and the clock; ``ValueError`` naming what is wrong."""
    from agents.lorr.run import check_chip_use
    from agents.lorr.spec import PlannerSpec, SchedulerSpec
    from mrmt_env.lorr.instance import read_instance

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
        plans = [(path, c.scheduler, c.planner) for path, inst in insts.items() for c in [entry.choose(inst)]]
        if chip is not None:  # the machine runs under each instance's rule
            for _path, s, planner in plans:
                check_chip_use(chip, s.build(0, chip), s.name, planner)
        return plans, clock_from_args(args, "rules")
    schedulers = [s.strip() for s in (args.scheduler or "lorr-greedy").split(",") if s.strip()]
    if not schedulers:
        raise ValueError("--scheduler names no scheduler")
    options: dict = {"replan": True} if args.replan else {}
    if args.no_keep:
        if not args.replan:
            raise ValueError("--no-keep acts on --replan: add --replan")
        options["keep"] = False
    if args.scheduler_option:
        from agents.keyvalues import key_values

        options.update(key_values(args.scheduler_option, "--scheduler-option", "weight=1"))
    own = planner_options(args.planner or "pibt", args.planner_option)
    if args.guidance is not None:
        if "guidance" in own:
            raise ValueError("guidance given twice (--guidance and --planner-option guidance=...): give it once")
        own["guidance"] = args.guidance
    name = args.planner or "pibt"
    PlannerSpec.of(name)  # the name first: its own error
    if args.guidance is not None:
        try:
            PlannerSpec.of(name, {"guidance": args.guidance})
        except ValueError as exc:
            raise ValueError(f"--guidance: {exc}") from None
    try:
        planner = PlannerSpec.of(name, own)
    except ValueError as exc:
        raise ValueError(f"--planner-option {exc}") from None
    specs = []
    for name in schedulers:  # names, model files and options checked before anything starts
        spec = SchedulerSpec.of(name, options, chip)
        check_chip_use(chip, spec.build(0, chip), name, planner)
        specs.append(spec)
    return [(path, s, planner) for path in insts for s in specs], clock_from_args(args, None)


def bad_counts(args, *flags) -> str | None:
    """The error of the first of ``flags`` given below 1, or of a negative ``--seed``; ``None`` when all fit."""
    for flag in flags:
        value = getattr(args, flag[2:].replace("-", "_"))
        if value is not None and value < 1:
            return f"{flag} must be >= 1, got {value}"
    return f"--seed must be >= 0, got {args.seed}" if args.seed < 0 else None


def warm_parts(pairs, progress: bool) -> None:
    """Compile the kernels of ``(scheduler, planner)`` name pairs now, on the cores, with one notice
    (agents/warmup.py); a user's own ``package.module:Class`` compiles nothing of ours."""
    import os

    from agents.warmup import warm

    from agents.lorr.spec import is_class_path

    parts = ({f"lorr:{ex}" for _, ex in pairs if not is_class_path(ex)}
             | {s for s, _ in pairs if s != "lorr-greedy" and not s.startswith("ppo:") and not is_class_path(s)})
    warm(sorted(parts), jobs=min(2, os.cpu_count() or 1), progress=progress)


def fail(message: str) -> int:
    print(f"mrmt lorr: error: {message}", file=sys.stderr)
    return 2



def best_row(inst, table: dict | None = None):
    """The best-known row (``agents, steps, tasks``) of ``inst``: from ``table`` when given (a round's), else as
    :func:`agents.lorr.run.best_known` finds it (a ``best_known.json`` in its folder or up to three above, else the
    package's table); ``None`` without one."""
    from agents.lorr.round import best_known_table

    if table is not None:
        return table.get(inst.name)
    folder = inst.path.parent
    for d in [folder, *list(folder.parents)[:3]]:
        if (d / "best_known.json").is_file():
            try:
                row = best_known_table(d / "best_known.json").get(inst.name)
            except ValueError:
                continue
            if row is not None:
                return row
    return best_known_table().get(inst.name)


def full_steps(inst, row) -> int | None:
    """The instance's full simulation time: its own (``simulation_time.json``), else its best-known ``row``'s."""
    return inst.steps or (int(row[1]) if row is not None else None)


def steps_for(path, inst, given: int | None, row) -> int:
    """The steps a run of ``inst`` takes: ``given`` (``--steps``), else :func:`full_steps`; ``ValueError`` (the
    round's own words) when neither is known."""
    if given is not None:
        return int(given)
    full = full_steps(inst, row)
    if full is None:
        raise ValueError(f"{path}: no simulation time (no simulation_time.json beside it, no best-known row): "
                         f"give --steps")
    return full


def score_prefix(record: dict, full: int | None) -> dict:
    """``record`` (a run's) with the round's keys: ``full_steps``, ``prefix``, ``best_known_pro_rata`` and
    ``share_of_best`` = tasks / (best-known x min(steps, full) / full)."""
    n, best = record["steps"], record["best_known"]
    target = None if best is None or full is None else best * min(n, full) / full
    return {**record, "full_steps": full, "prefix": full is None or n < full, "best_known_pro_rata": target,
            "share_of_best": (record["tasks_finished"] / target) if target else None}


def steps_cell(r: dict) -> str:
    """``30`` or, for a prefix, ``30 of 40`` (as the round's summary writes it)."""
    return f"{r['steps']}" + (f" of {r['full_steps']}" if r.get("prefix") and r.get("full_steps") else "")


def share_cell(r: dict) -> str:
    """``45.0%``, ``45.0% (pro rata)`` for a prefix, ``-`` without a best-known (as the round's summary)."""
    share = r.get("share_of_best")
    text = "-" if share is None else format(share, ".1%")
    if r.get("prefix") and share is not None:
        text += " (pro rata)"
    if r.get("preprocess_timeout"):
        text += " (preprocessing late)"
    return text
