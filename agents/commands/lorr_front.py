"""``mrmt lorr sweep --budget``: the host's front over step budgets against a chip planner's points.

    mrmt lorr sweep RANDOM-04.json --scheduler strong --replan --planner epibt-chain-ising --guidance 2 \\
        --budget 0.05,0.2,1 --host-planner epibt,epibt-chain --chip n_spins=45,256 --chip solve_time_s=5e-5,5e-6 \\
        --steps 200 --seeds 2 --out DIR [--resume]

Every run in a fresh process, one at a time (each under its clock wants the cores); ``DIR/front.csv`` is written
after each, so ``--resume`` picks a stopped sweep up at the same commit (a row of another commit runs again;
:mod:`agents.lorr.front`).  Bad input: one line, exit 2.
"""

from __future__ import annotations

import sys

MAX_BUDGET_S = 60.0


def parse_budgets(text: str) -> list[float]:
    """``"0.05,0.2,1"`` -> ``[0.05, 0.2, 1.0]``; ``ValueError`` naming a value that is not a number in
    ``(0, MAX_BUDGET_S]`` or given twice."""
    out = []
    for item in (text or "").split(","):
        try:
            b = float(item)
        except ValueError:
            raise ValueError(f"--budget: {item.strip()!r} is not a number of seconds") from None
        if not 0 < b <= MAX_BUDGET_S:
            raise ValueError(f"--budget: {b:g} s must be in (0, {MAX_BUDGET_S:g}]")
        if b in out:
            raise ValueError(f"--budget: {b:g} s given twice")
        out.append(b)
    return out


def host_planners(text: str | None, guidance: int | None) -> list:
    """The ``--host-planner`` specs (default ``epibt,epibt-chain``), each with ``guidance`` when given; ``ValueError``
    for an unknown name or a chip planner."""
    from agents.lorr.spec import PlannerSpec
    from planners.mapf import MACHINE_PLANNERS

    specs = []
    for name in [n.strip() for n in (text or "epibt,epibt-chain").split(",") if n.strip()]:
        if name in MACHINE_PLANNERS:
            raise ValueError(f"--host-planner {name}: a chip planner; the front's host planners make no machine call "
                             f"(give it as --planner)")
        specs.append(PlannerSpec.of(name, {} if guidance is None else {"guidance": guidance}))
    if not specs:
        raise ValueError("--host-planner names no planner")
    return specs


def run_front(args) -> int:
    from pathlib import Path

    from agents.commands.lorr_args import bad_counts, best_row, fail, plans_from_args, steps_for, warm_parts
    from agents.commands.options import chip_from_args
    from agents.lorr.front import front_points, front_row, front_task, read_rows, row_key, write_front
    from agents.lorr.round import code_version
    from agents.runner import RunConfig, run_tasks
    from agents.sweep import chip_grid, parse_axes
    from ising_backend import ChipSpec
    from mrmt_env.lorr.instance import LoRRFormatError, read_instance
    from planners.mapf import MACHINE_PLANNERS

    bad = bad_counts(args, "--steps", "--seeds")
    if bad:
        return fail(bad)
    try:
        if args.budget is None:
            raise ValueError("--host-planner and --resume draw the host's front: add --budget S1,S2,...")
        if args.step_limit is not None:
            raise ValueError("--budget is the front's clock (seconds per step): drop --step-limit")
        if args.backend not in (None, "process") or args.address:
            raise ValueError("--budget runs each run in a fresh local process, one at a time (each under its clock "
                             "wants the cores): drop --backend / --address")
        if args.sampler:
            raise ValueError("--budget: the front's chip points are emulated chips (--chip axes); drop --sampler")
        if args.planner not in MACHINE_PLANNERS:
            raise ValueError(f"--budget draws the host's front against a chip planner: give --planner one of "
                             f"{', '.join(MACHINE_PLANNERS)}")
        if args.scheduler and "," in args.scheduler:
            raise ValueError(f"--scheduler {args.scheduler}: a front runs one scheduler; give one")
        budgets = parse_budgets(args.budget)
        base = chip_from_args(args, key="base_chip") or ChipSpec()
        grid = chip_grid(parse_axes(args.chip), base) if args.chip else [({}, base)]
        specs = [spec for _, spec in grid]
        hosts = host_planners(args.host_planner, args.guidance)
        plans, _ = plans_from_args(args, specs[0])
        steps = {}
        for path, _, planner in plans:
            inst = read_instance(path)
            steps[path] = steps_for(path, inst, args.steps, best_row(inst))
            planner.check_team(inst.grid, inst.team_size)
    except (LoRRFormatError, ValueError, OSError) as exc:
        return fail(str(exc))
    seeds = range(args.seed, args.seed + args.seeds)
    points = front_points([h.name for h in hosts], args.planner, specs, budgets, seeds)
    by_name = {h.name: h for h in hosts}
    out = Path(args.out)
    code = code_version()
    rows = read_rows(out / "front.csv") if args.resume else []
    stale = [r for r in rows if r["code"] != code]  # a front is one commit's: another's rows run again
    if stale:
        print(f"mrmt lorr sweep: {len(stale)} row(s) of front.csv ran at another commit than {code}: run again",
              file=sys.stderr)
        rows = [r for r in rows if r["code"] == code]
    done = {row_key(r) for r in rows}
    todo = []
    for path, sched, chip_planner in plans:
        name = read_instance(path).name
        for p in points:
            spec = specs[max(p.spec_id, 0)]
            key = (name, p.kind, p.planner, "" if p.kind == "host" else int(spec.n_spins),
                   "" if p.kind == "host" else float(spec.solve_time_s), float(p.budget_s), p.seed, steps[path])
            if key not in done:
                todo.append((path, sched, by_name.get(p.planner, chip_planner), p, spec))
    if not args.address:
        warm_parts([(plans[0][1].name, h.name) for h in hosts] + [(plans[0][1].name, args.planner)],
                   not args.no_progress)
    title = f"The host's front and {args.planner}'s points ({plans[0][1].name})"
    one = RunConfig(backend="process", jobs=1, progress=False)  # each run in a fresh process, one at a time
    from tqdm.auto import tqdm

    for path, sched, planner, p, spec in tqdm(todo, desc="lorr front", unit="run", disable=args.no_progress,
                                              file=sys.stderr):
        try:
            (record,) = run_tasks(front_task, [(path, sched, planner, steps[path], p.seed, spec, p.kind, p.budget_s)],
                                  one)
        except ValueError as exc:  # a spec the planner refuses (e.g. fewer spins than a group needs)
            return fail(str(exc))
        rows.append(front_row(p, record, spec, code))
        write_front(rows, out, title)
    summary = write_front(rows, out, title)
    for inst, s in summary.items():
        paying = [c for c in s["chips"] if c["pays"]]
        beyond = [c for c in s["chips"] if c["beyond"]]
        best = s["best_host"]
        print(f"{inst}: best host point {best['planner']} at {best['budget_s']:g} s: {best['tasks']:,.1f} tasks, "
              f"{best['j_per_task']:.3f} J/task" if best else f"{inst}: no host point")
        for c in s["chips"]:
            print(f"  chip n_spins={c['n_spins']} solve_time_s={c['solve_time_s']:g} budget {c['budget_s']:g} s: "
                  f"{c['tasks']:,.1f} tasks, {c['j_per_task']:.3f} J/task, beyond the front: "
                  f"{'yes' if c['beyond'] else 'no'}, pays (>= 1.05x the best host's tasks at no more J/task): "
                  f"{'yes' if c['pays'] else 'no'}")
        print(f"  {len(beyond)} chip point(s) beyond the host's front, {len(paying)} that pay"
              + (": " + "; ".join(f"n_spins={c['n_spins']} solve_time_s={c['solve_time_s']:g}" for c in paying)
                 if paying else ""))
    print(f"wrote front.csv, front.json, front.md and front.png in {out}", file=sys.stderr)
    return 0
