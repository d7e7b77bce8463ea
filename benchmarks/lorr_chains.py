"""EPIBT by push chains against the entry's EPIBT and the record holder's own planner, at density (issue 57).

Per instance, the first ``--steps`` steps under the rules' 1 s clock, seed 0:

* ``entry``: the package's default entry (its rule for the instance);
* ``epibt-chain``: ``lorr-greedy`` + ``epibt-chain`` with ``--active`` of the team at work (ranked by the task
  still to go), ``--portfolio`` plans on the cores;
* ``record holder`` (with ``--record-holder BIN``): the 2024 winner's own start-kit binary (``lifelong``, built from
  its public repository by the user) on the same instance and steps, ``-t 1000``; its tasks from its output.

Run nothing else beside it.

    flock /tmp/mrmt-bench.lock python benchmarks/lorr_chains.py --instances RANDOM-04 --steps 300 --write
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import cpu_name, finish, lorr_run_json  # noqa: E402

SECTION = "## EPIBT by push chains at density, against the record holder's planner (issue 57)"
ROOT = Path(__file__).resolve().parents[2] / "shared" / "lorr" / "2024-main" / "random.domain"


def record_holder(binary: str, instance: Path, steps: int) -> dict:
    """Tasks and timeouts of the start kit binary ``binary`` on ``instance`` for ``steps`` steps (1 s a step)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "output.json"
        subprocess.run([binary, "-i", str(instance), "-o", str(out), "-s", str(steps), "-t", "1000", "-p", "1800000",
                        "-c", "3", "-l", str(Path(tmp) / "log")], check=True, capture_output=True,
                       cwd=Path(binary).resolve().parent.parent)
        rec = json.loads(out.read_text())
    return {"tasks_finished": rec["numTaskFinished"], "timeouts": rec["numEntryTimeouts"], "step_p99_s": None}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--instances", default="RANDOM-04,RANDOM-05")
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--active", type=float, default=0.57, help="share of the team at work (epibt-chain rows)")
    parser.add_argument("--portfolio", type=int, default=2)
    parser.add_argument("--record-holder", default=None, help="the winner's start-kit binary (optional)")
    parser.add_argument("--write", action="store_true")
    args = parser.parse_args(argv)
    chain = ("--scheduler", "lorr-greedy", "--planner", "epibt-chain", "--planner-option", f"active={args.active}",
             "--planner-option", "active_by=task", "--planner-option", f"portfolio={args.portfolio}")
    table = []
    for name in [n.strip() for n in args.instances.split(",") if n.strip()]:
        inst = ROOT / f"{name}.json"
        runs = {"entry": lorr_run_json(inst, "--entry", "default", "--steps", str(args.steps)),
                "epibt-chain": lorr_run_json(inst, *chain, "--steps", str(args.steps), "--step-limit", "rules")}
        if args.record_holder:
            runs["record holder"] = record_holder(args.record_holder, inst, args.steps)
        for row, rec in runs.items():
            p99 = rec["step_p99_s"]
            table.append((name, row, rec["tasks_finished"], rec["timeouts"], "" if p99 is None else f"{p99:.3f}"))
            print(f"{name} {row}: {rec['tasks_finished']} tasks", file=sys.stderr)
    lines = [SECTION, "",
             f"`python benchmarks/lorr_chains.py --instances {args.instances} --steps {args.steps} --active "
             f"{args.active} --portfolio {args.portfolio}" + (" --record-holder BIN" if args.record_holder else "")
             + f"` ({cpu_name()}; first {args.steps} steps, 1 s clock, seed 0)", "",
             "| instance | planner | tasks | timeouts | step p99 s |", "|---|---|---:|---:|---:|"]
    lines += [f"| {a} | {b} | {c:,} | {d} | {e} |" for a, b, c, d, e in table]
    finish(SECTION, lines, args.write)


if __name__ == "__main__":
    main()
