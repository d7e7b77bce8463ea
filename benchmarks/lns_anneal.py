"""EPIBT's search at density: its descent, a host annealer, and the chip as the annealer (issue 57).

On the dense 2024 instances (RANDOM-04: 700 robots, RANDOM-05: 800 on 819 free cells), the default entry's
scheduler and planner settings (``strong --replan`` + ``weight_power=2``, ``op_len=auto``, ``--portfolio`` plans) with
the search the only difference, under the rules' clock (the same step budget for every row):

* ``descent``: ``epibt``'s search as today (a neighbourhood's new choice kept only when its cost falls);
* ``host annealer``: ``epibt anneal=T`` per ``--anneals`` (worse choices kept with a cooling temperature, the
  best plan met kept);
* ``chip annealer``: ``epibt-ising lns=0 rounds=N``: rounds of neighbourhood programs solved on the emulated chip
  until the deadline (host seconds plus the machine's own; the emulation's are not the step's);
* ``host-rule twin``: the same rounds with the host rule (the search's greedy) in the chip's place.

Tasks summed over seeds ``0..--seeds-1``, the first ``--steps`` steps; host and machine energy per task apart
(host CPU seconds x 15 W; 0.45 uJ per chip call).  Run nothing else beside it.

    flock /tmp/mrmt-bench.lock python benchmarks/lns_anneal.py --steps 200 --write
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import cpu_name, finish, lorr_run_json  # noqa: E402

SECTION = "## EPIBT's search at density: descent, host annealer, the chip as annealer (issue 57)"
ROOT = Path(__file__).resolve().parents[2] / "shared" / "lorr" / "2024-main" / "random.domain"
BASE = ("--scheduler", "strong", "--replan", "--planner-option", "weight_power=2", "--planner-option", "op_len=auto")


def rows(anneals: list[float], chip_rows: bool, rounds: int, reads: int) -> dict[str, tuple[str, ...]]:
    """Each row's planner and options (module docstring): a host row per temperature (0: the descent), then the
    chip annealer and its host-rule twin."""
    out = {("descent" if a == 0 else f"host annealer (anneal {a:g})"):
           ("--planner", "epibt", "--planner-option", f"anneal={a}") for a in anneals}
    if chip_rows:
        chip = ("--planner", "epibt-ising", "--planner-option", "lns=0", "--planner-option", f"rounds={rounds}",
                "--planner-option", f"num_reads={reads}")
        out["chip annealer"] = chip
        out["host-rule twin"] = chip + ("--planner-option", "decider=host")
    return out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--instances", default="RANDOM-04,RANDOM-05")
    parser.add_argument("--anneals", default="0,0.02", help="host rows' starting temperatures; 0 = the descent")
    parser.add_argument("--chip-rows", choices=("on", "none"), default="on", help="the chip annealer and its twin")
    parser.add_argument("--portfolio", type=int, default=1, help="plans a step (every row)")
    parser.add_argument("--rounds", type=int, default=4096, help="the chip's rounds a step at most (the clock cuts)")
    parser.add_argument("--reads", type=int, default=16, help="reads per chip program")
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--seeds", type=int, default=1)
    parser.add_argument("--step-limit", default="rules", help="as mrmt lorr run's (rules: 1 s; none: work-bounded)")
    parser.add_argument("--write", action="store_true")
    args = parser.parse_args(argv)
    names = [n.strip() for n in args.instances.split(",") if n.strip()]
    table = []
    for name in names:
        for row, opts in rows([float(a) for a in args.anneals.split(",")], args.chip_rows == "on", args.rounds,
                              args.reads).items():
            common = ("--planner-option", f"portfolio={args.portfolio}", "--steps", str(args.steps),
                      "--step-limit", args.step_limit)
            recs = [lorr_run_json(ROOT / f"{name}.json", *BASE, *opts, *common, "--seed", str(s))
                    for s in range(args.seeds)]
            tasks = sum(r["tasks_finished"] for r in recs)
            host_j = sum(r["host_energy_per_task_j"] * max(r["tasks_finished"], 1) for r in recs)
            machine_j = sum(r["machine_energy_per_task_j"] * max(r["tasks_finished"], 1) for r in recs)
            table.append((name, row, tasks, sum(r["timeouts"] for r in recs), max(r["step_p99_s"] for r in recs),
                          sum(r["chip_calls"] for r in recs) / sum(r["decisions"] for r in recs),
                          host_j / max(tasks, 1), machine_j / max(tasks, 1)))
            print(f"{name} {row}: {tasks} tasks", file=sys.stderr)
    lines = [SECTION, "",
             f"`python benchmarks/lns_anneal.py --instances {args.instances} --steps {args.steps} --seeds {args.seeds} "
             f"--anneals {args.anneals} "
             f"--chip-rows {args.chip_rows} --rounds {args.rounds} --reads {args.reads} --portfolio {args.portfolio} "
             f"--step-limit {args.step_limit}` ({cpu_name()}; `strong --replan`, weight_power=2 op_len=auto, "
             f"{args.portfolio} plan(s) a step; the first {args.steps} steps, tasks "
             f"summed over seeds 0..{args.seeds - 1}; step time: host seconds plus the machine's own).", "",
             "| instance | search | tasks | x descent | timeouts | step p99 s | chip calls / step | host J / task | "
             "machine J / task |", "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    base = {}
    for name, row, tasks, late, p99, calls, hj, mj in table:
        base.setdefault(name, tasks)
        lines.append(f"| {name} | {row} | {tasks:,} | {tasks / max(base[name], 1):.3f} | {late} | {p99:.3f} | "
                     f"{calls:,.0f} | {hj:.2f} | {mj:.2e} |")
    finish(SECTION, lines, args.write)


if __name__ == "__main__":
    main()
