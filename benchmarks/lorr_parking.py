"""Parking at density: the default entry's RANDOM configuration with at most a share of the team busy (issue 57).

On the dense 2024 instances (RANDOM-04: 700 robots, RANDOM-05: 800 on 819 free cells), ``strong --replan`` +
``epibt`` (``weight_power=2``, ``op_len=auto``) with the scheduler option ``busy`` the only difference: ``1``
(every robot may hold a task; today's) against shares below (robots given a new task beyond the share wait where
they stand, the nearest new assignments kept).  Work-bounded (the same search a step for every row, one plan a
step), the first ``--steps`` steps, seed 0.  Run nothing else beside it.

    python benchmarks/lorr_parking.py --steps 300 --write
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import cpu_name, finish, lorr_run_json  # noqa: E402

SECTION = "## Parking at density: at most a share of the team busy (issue 57)"
ROOT = Path(__file__).resolve().parents[2] / "shared" / "lorr" / "2024-main" / "random.domain"


def run(name: str, busy: float, steps: int, portfolio: int) -> dict:
    return lorr_run_json(ROOT / f"{name}.json", "--scheduler", "strong", "--replan", "--scheduler-option",
                         f"busy={busy}", "--planner", "epibt", "--planner-option", "weight_power=2", "--planner-option",
                         "op_len=auto", "--planner-option", f"portfolio={portfolio}", "--steps", str(steps))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--instances", default="RANDOM-03,RANDOM-04,RANDOM-05")
    parser.add_argument("--shares", default="1,0.6,0.4", help="busy shares; 1 = every robot (today's)")
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--portfolio", type=int, default=1)
    parser.add_argument("--write", action="store_true")
    args = parser.parse_args(argv)
    names = [n.strip() for n in args.instances.split(",") if n.strip()]
    shares = [float(a) for a in args.shares.split(",")]
    rows = []
    for name in names:
        for busy in shares:
            r = run(name, busy, args.steps, args.portfolio)
            rows.append((name, busy, r["tasks_finished"], r["step_p99_s"]))
            print(f"{name} busy={busy}: {r['tasks_finished']} tasks", file=sys.stderr)
    lines = [SECTION, "",
             f"`python benchmarks/lorr_parking.py --steps {args.steps} --portfolio {args.portfolio} --shares "
             f"{args.shares}` ({cpu_name()}; work-bounded: the same search a step for every row; `strong --replan` + "
             f"`epibt` weight_power=2 op_len=auto, portfolio {args.portfolio}; the first {args.steps} steps, seed 0).",
             "", "| instance | busy | tasks | x every robot | step p99 s (host) |", "|---|---:|---:|---:|---:|"]
    base = {}
    for name, busy, tasks, p99 in rows:
        base.setdefault(name, tasks)
        lines.append(f"| {name} | {busy:g} | {tasks:,} | {tasks / max(base[name], 1):.3f} | {p99:.3f} |")
    finish(SECTION, lines, args.write)


if __name__ == "__main__":
    main()
