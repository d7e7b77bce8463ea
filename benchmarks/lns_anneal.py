"""EPIBT's large-neighbourhood search as an annealer on the host, against its descent (issue 57, item 1).

On the dense 2024 instances (RANDOM-04: 700 robots, RANDOM-05: 800 on 819 free cells), the default entry's
configuration (``strong --replan`` + ``epibt`` with ``weight_power=2``, ``op_len=auto``) with the search's
acceptance the only difference: ``anneal=0`` (descent: a neighbourhood's new choice kept only when its cost
falls; today's) against ``anneal=T`` (worse choices kept with probability ``exp(-d / (T x cost))``, ``T``
falling to 0 over the step's iterations, the best plan met kept).  Same iterations per step (work-bounded,
deterministic), ``--portfolio`` plans a step, the first ``--steps`` steps, seeds ``0..--seeds-1``.  Run
nothing else beside it.

    flock /tmp/mrmt-bench.lock python benchmarks/lns_anneal.py --steps 300 --write
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import cpu_name, finish, lorr_run_json  # noqa: E402

SECTION = "## EPIBT's search as a host annealer against its descent (issue 57)"
ROOT = Path(__file__).resolve().parents[2] / "shared" / "lorr" / "2024-main" / "random.domain"


def run(name: str, anneal: float, steps: int, seed: int, portfolio: int) -> dict:
    return lorr_run_json(ROOT / f"{name}.json", "--scheduler", "strong", "--replan", "--planner", "epibt",
                         "--planner-option", "weight_power=2", "--planner-option", "op_len=auto", "--planner-option",
                         f"portfolio={portfolio}", "--planner-option", f"anneal={anneal}", "--steps", str(steps),
                         "--seed", str(seed))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--instances", default="RANDOM-04,RANDOM-05")
    parser.add_argument("--anneals", default="0,0.02,0.1", help="starting temperatures; 0 = today's descent")
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--seeds", type=int, default=1)
    parser.add_argument("--portfolio", type=int, default=1)
    parser.add_argument("--write", action="store_true")
    args = parser.parse_args(argv)
    names = [n.strip() for n in args.instances.split(",") if n.strip()]
    anneals = [float(a) for a in args.anneals.split(",")]
    rows = []
    for name in names:
        for a in anneals:
            recs = [run(name, a, args.steps, s, args.portfolio) for s in range(args.seeds)]
            tasks = sum(r["tasks_finished"] for r in recs)
            rows.append((name, a, tasks, max(r["step_p99_s"] for r in recs)))
            print(f"{name} anneal={a}: {tasks} tasks", file=sys.stderr)
    lines = [SECTION, "",
             f"`python benchmarks/lns_anneal.py --steps {args.steps} --seeds {args.seeds} --portfolio {args.portfolio} "
             f"--anneals {args.anneals}` ({cpu_name()}; work-bounded: the same search iterations a step for every "
             f"row; `strong --replan` + `epibt` weight_power=2 op_len=auto, portfolio {args.portfolio}; the first "
             f"{args.steps} steps, tasks summed over seeds 0..{args.seeds - 1}).", "",
             "| instance | anneal | tasks | x descent | step p99 s (host) |", "|---|---:|---:|---:|---:|"]
    base = {}
    for name, a, tasks, p99 in rows:
        base.setdefault(name, tasks)
        lines.append(f"| {name} | {a:g} | {tasks:,} | {tasks / max(base[name], 1):.3f} | {p99:.3f} |")
    finish(SECTION, lines, args.write)


if __name__ == "__main__":
    main()
