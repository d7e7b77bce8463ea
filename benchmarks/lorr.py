"""The League of Robot Runners 2024 main round: tasks finished against the best-known, step time, energy.

Every RANDOM instance in full (100-800 robots on random-32-32-20, 600-2,000 steps), each
scheduler x executor (``--schedulers``, default the start kit's greedy, ``strong`` and ``ising``,
PIBT with turning); the large instances (CITY 1,500 / 3,000 robots, GAME 6,500, WAREHOUSE and
SORTATION 10,000) with ``lorr-greedy`` + PIBT for ``--scale-steps`` steps (default 500) with
tasks per step and peak memory (``ru_maxrss`` of the run's own process).  Step time = the
decision's host seconds (scheduler + executor, chip emulation excluded) + the chip's parallel
time, p50 / p99 over steps, one core.  The best-known is the archive's record over the full
simulation time.  ``--seeds 0,1,2`` runs each RANDOM row once per seed (single runs differ by up to ~4 %
at 700 robots); the summary and the place among the 2024 main round's teams
(:data:`LEADERBOARD`) take each instance's mean over its seeds.  Writes the RESULTS.md section
(``--write``).

    flock /tmp/mrmt-bench.lock python benchmarks/lorr.py --write
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from _common import cpu_name, finish  # noqa: E402

SECTION = "## League of Robot Runners 2024 (issue 32)"
ROOT = Path(__file__).resolve().parents[2] / "shared" / "lorr" / "2024-main"
RANDOM = [f"RANDOM-0{i}" for i in range(1, 6)]
SCALE = ["CITY-01", "CITY-02", "GAME", "WAREHOUSE", "SORTATION"]
ORDER = ["pibt", "pibt-flow", "epibt", "pibt-ising"]  # executors in the table
LEADERBOARD = Path(__file__).resolve().parent / "data" / "lorr2024_main_round.json"


def place(instance: str, tasks: int, board: dict) -> tuple[int, int] | None:
    """``(place, teams)``: 1 + the 2024 main round's teams that finished more than ``tasks`` on ``instance``
    (their Combined entries, ``board`` as :data:`LEADERBOARD`), and how many teams there were."""
    if instance not in board["columns"]:
        return None
    k = board["columns"].index(instance)
    scores = [row[k] for row in board["teams"].values()]
    return 1 + sum(s > tasks for s in scores), len(scores)


def _path(name: str) -> Path:
    return next(ROOT.glob(f"*/{name}.json"))


def _executor_spec(spec: str, name: str) -> tuple[str, dict]:
    """``NAME[:KEY=VALUE[:KEY=VALUE...]]`` (e.g. ``epibt:weight_power=2``) as the executor and its own options,
    parsed as ``mrmt lorr run --planner-option KEY=VALUE`` does and checked (the planner's spec, then the planner
    built once on instance ``name``'s map); ``ValueError`` naming a bad option."""
    from agents.commands.lorr_args import planner_options
    from agents.lorr.spec import PlannerSpec
    from mrmt_env.lorr.instance import read_instance

    executor, *items = spec.split(":")
    own = planner_options(executor, items)
    if own:
        try:
            PlannerSpec.of(executor, own).build(read_instance(_path(name)).grid)
        except ValueError as exc:
            raise ValueError(f"--planner-option {exc}") from None
    return executor, own


def _one(name: str, scheduler: str, spec: str, steps: int | None, options: dict, seed: int = 0) -> dict:
    """One run with ``seed`` in a fresh process (peak memory is the run's own); the row's executor is ``spec``."""
    executor, own = _executor_spec(spec, name)
    if own:
        options = {**options, "planner_options": own}
    code = ("import json, resource, sys; from agents.lorr.run import run_lorr; "
            f"r, sim, s = run_lorr({str(_path(name))!r}, {scheduler!r}, {executor!r}, steps={steps!r}, seed={seed!r}, "
            f"options={options!r}); r['peak_rss_mb'] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024; "
            "print(json.dumps(r))")
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=Path(__file__).resolve().parents[1])
    if proc.returncode != 0:
        raise RuntimeError(f"{name} {scheduler}: {proc.stderr.strip().splitlines()[-1:]}")
    row = json.loads(proc.stdout.strip().splitlines()[-1])
    row["executor"] = spec
    row["seed"] = seed
    row["wall_s"] = time.perf_counter() - t0
    return row


def _key(r: dict) -> tuple:
    return r["instance"], r["scheduler"], r["executor"], r.get("seed", 0)


def summary(rows: list[dict]) -> dict:
    """Per (scheduler, executor): each instance's mean share of the best-known and mean tasks over its seeds."""
    out: dict = {}
    for r in rows:
        if r["share_of_best"] is None:
            continue
        cell = out.setdefault((r["scheduler"], r["executor"]), {}).setdefault(r["instance"], [])
        cell.append((r["share_of_best"], r["tasks_finished"]))
    return {k: {i: (sum(x for x, _ in v) / len(v), sum(t for _, t in v) / len(v), len(v)) for i, v in d.items()}
            for k, d in out.items()}


def _rank(spec: str) -> tuple:
    name = spec.split(":")[0]
    return (ORDER.index(name) if name in ORDER else 9, spec)


def _fmt_row(r: dict) -> str:
    share = "-" if r["share_of_best"] is None else f"{100 * r['share_of_best']:.1f} %"
    return (f"| {r['instance']} | {r['robots']} | {r['scheduler']} | {r['executor']} | {r.get('seed', 0)} | {r['steps']} | "
            f"{r['tasks_finished']} | {r['best_known']} | {share} | {1e3 * r['step_p50_s']:.1f} | "
            f"{1e3 * r['step_p99_s']:.1f} | {r['errors']} | {1e3 * r['paper_energy_per_task_j']:.3g} | "
            f"{1e3 * r['total_energy_per_task_j']:.3g} | {r['peak_rss_mb']:.0f} |")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--schedulers", default="lorr-greedy,strong,ising")
    parser.add_argument("--executors", default="pibt,pibt-flow,epibt",
                        help="each runs every scheduler; NAME:KEY=VALUE passes the executor an option of its own "
                             "(e.g. epibt:weight_power=2)")
    parser.add_argument("--instances", default=",".join(RANDOM))
    parser.add_argument("--scale", default=",".join(SCALE), help="large instances run for --scale-steps ('' = none)")
    parser.add_argument("--scale-steps", type=int, default=500)
    parser.add_argument("--scale-executor", default="pibt", help="the executor of the large instances")
    parser.add_argument("--steps", type=int, default=None, help="steps of the RANDOM runs (default: in full)")
    parser.add_argument("--seeds", default="0", help="seeds of the RANDOM runs, comma separated: each row runs once per seed; "
                        "the summary takes each instance's mean over them")
    parser.add_argument("--replan", action="store_true", help="pipeline schedulers with replan=True as well")
    parser.add_argument("--replan-only", action="store_true", help="pipeline schedulers with replan=True only")
    parser.add_argument("--write", action="store_true")
    parser.add_argument("--json", default=None, help="also write every run's record to this JSON file")
    parser.add_argument("--merge-json", default=None,
                        help="records of an earlier run (its --json) kept for the runs this one does not repeat")
    args = parser.parse_args(argv)
    schedulers = [s for s in args.schedulers.split(",") if s]
    seeds = [int(x) for x in args.seeds.split(",") if x.strip()]
    rows = []
    head = ("| instance | robots | scheduler | executor | seed | steps | tasks | best-known | share | step p50 ms | "
            "step p99 ms | errors | paper mJ/task | total mJ/task | peak MB |")
    sep = "|" + "---|" * 15
    executors = [e for e in args.executors.split(",") if e]
    for name in [n for n in args.instances.split(",") if n]:
        for ex in executors:
            for s in schedulers:
                variants = [{}] + ([{"replan": True}] if args.replan and s != "lorr-greedy" else [])
                if args.replan_only:
                    variants = [{"replan": True}] if s != "lorr-greedy" else []
                for options in variants:
                    for seed in seeds:
                        r = _one(name, s, ex, args.steps, options, seed)
                        if options:
                            r["scheduler"] += "+replan"
                        rows.append(r)
                        print(_fmt_row(r), flush=True)
    scale_rows = []
    for name in [n for n in args.scale.split(",") if n]:
        r = _one(name, "lorr-greedy", args.scale_executor, args.scale_steps, {})
        r["tasks_per_step"] = r["tasks_finished"] / r["steps"]
        scale_rows.append(r)
        print(_fmt_row(r), f"tasks/step {r['tasks_per_step']:.2f}", flush=True)
    if args.merge_json:  # an earlier run's records, where this run did not repeat them
        old = json.loads(Path(args.merge_json).read_text())
        done = {_key(r) for r in rows + scale_rows}
        keep = [r for r in old if _key(r) not in done]
        rows = [r for r in keep if "tasks_per_step" not in r] + rows
        scale_rows = [r for r in keep if "tasks_per_step" in r] + scale_rows
        rows.sort(key=lambda r: (r["instance"], _rank(r["executor"]), r.get("seed", 0)))
    lines = [SECTION, "", f"`python benchmarks/lorr.py --write` on {cpu_name()} (one core per run, runs in turn). "
             "Step = scheduler + executor host seconds (chip emulation excluded) + chip parallel seconds; "
             "best-known: the archive's record over the instance's full simulation time.", "", head, sep]
    lines += [_fmt_row(r) for r in rows]
    means = summary(rows)
    first = "pibt" if ("lorr-greedy", "pibt") in means else (executors[0] if executors else "")
    lines += ["", "Each instance's mean over its seeds, then over the instances:", "",
              "| scheduler | executor | seeds | mean share of best-known (RANDOM) | min share | tasks vs lorr-greedy + "
              f"{first} |", "|---|---|---|---|---|---|"]
    base = {i: m[1] for i, m in means.get(("lorr-greedy", first), {}).items()}
    for (s, ex), per in means.items():
        shares = [m[0] for m in per.values()]
        gain = [m[1] / base[i] - 1 for i, m in per.items() if base.get(i)]
        n = sorted({m[2] for m in per.values()})
        lines.append(f"| {s} | {ex} | {'/'.join(map(str, n))} | {100 * sum(shares) / len(shares):.1f} % | "
                     f"{100 * min(shares):.1f} % | " + (f"{100 * sum(gain) / len(gain):+.1f} % |" if gain else "- |"))
    board = json.loads(LEADERBOARD.read_text())
    ranked = [(key, {i: place(i, round(m[1]), board) for i, m in per.items()}) for key, per in means.items()]
    cols = [c for c in board["columns"] if any(c in p for _, p in ranked)]
    if cols:
        lines += ["", f"Place among the {len(board['teams'])} teams of the 2024 main round at the mean tasks finished "
                  "above (1 + the teams whose Combined entry finished more; `benchmarks/data/lorr2024_main_round.json`):",
                  "", "| scheduler | executor | " + " | ".join(cols) + " |", "|---|---|" + "---|" * len(cols)]
        for (s, ex), p in ranked:
            lines.append(f"| {s} | {ex} | " + " | ".join(str(p[c][0]) if p.get(c) else "-" for c in cols) + " |")
    if scale_rows:
        lines += ["", f"Large instances, lorr-greedy + {args.scale_executor}, first {args.scale_steps} steps:", "",
                  "| instance | robots | tasks | tasks / step | step p50 ms | step p99 ms | step max ms | errors | "
                  "peak MB |", "|---|---|---|---|---|---|---|---|---|"]
        for r in scale_rows:
            lines.append(f"| {r['instance']} | {r['robots']} | {r['tasks_finished']} | {r['tasks_per_step']:.2f} | "
                         f"{1e3 * r['step_p50_s']:.1f} | {1e3 * r['step_p99_s']:.1f} | {1e3 * r['step_max_s']:.1f} | "
                         f"{r['errors']} | {r['peak_rss_mb']:.0f} |")
    if args.json:
        Path(args.json).write_text(json.dumps(rows + scale_rows, indent=1))
    finish(SECTION, lines, args.write)


if __name__ == "__main__":
    main()
