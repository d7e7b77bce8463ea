"""EPIBT by push chains against the entry's EPIBT and the record holder's own planner, at density (issue 57).

Per instance, the first ``--steps`` steps under the rules' 1 s clock, seed ``--seed`` (0):

* ``entry``: the package's default entry (its rule for the instance);
* ``epibt-chain (SCHEDULER)``: each of ``--schedulers`` + ``epibt-chain`` on crisscross lanes (``--guidance``) with
  ``--active`` of the team at work (ranked by the task still to go), ``--portfolio`` plans on the cores; the
  pipeline schedulers (every one but ``lorr-*``) re-plan unopened tasks (``--replan``), ``ising@host`` is ``ising``
  with the host rule in the chip's place (``--host-rule all``, its twin); the first is the reference of the ``x``
  column;
* ``chip annealer`` (``--chip-rows on``, with the first scheduler): ``epibt-chain-ising``, the same construction
  with no host search, its plan changed by rounds of neighbourhood programs (``lns_groups``) on the emulated chip
  until the deadline (host seconds plus the machine's own; the emulation's are not the step's), ``--reads`` reads
  a program;
* ``host-rule twin``: the same rounds with the host rule (the search's greedy) in the chip's place;
* ``host chains + chip`` (not with ``--chip-rows twins``): the host search for half the time, then the chip's rounds;
* ``record holder`` (with ``--record-holder BIN``): the 2024 winner's own start-kit binary (``lifelong``, built from
  its public repository by the user) on the same instance and steps, ``-t 1000``; its tasks from its output.

Host and machine energy per task apart (host CPU seconds x 15 W; 0.45 uJ per chip call).

The rows of the work set on the chip (``--work-rows``, the planner ``epibt-chain-work``) are gone with that planner;
their measured numbers stay in RESULTS.md ("Who stays at work, on the chip") and history/2026-11-28-lorr-density.md.

Run nothing else beside it.

    flock /tmp/mrmt-bench.lock python benchmarks/lorr_chains.py --instances RANDOM-04 --steps 300 --write
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import cpu_name, finish, lorr_run_json  # noqa: E402
from record_holder import play  # noqa: E402

SECTION = "## EPIBT by push chains at density: the entry, the host annealer, the chip annealer (issue 57)"
ROOT = Path(__file__).resolve().parents[2] / "shared" / "lorr" / "2024-main" / "random.domain"


def record_holder(binary: str, instance: Path, steps: int) -> dict:
    """Tasks and timeouts of the start kit binary ``binary`` on ``instance`` for ``steps`` steps (1 s a step)."""
    r = play(Path(binary), instance, steps)
    return {"tasks_finished": r["tasks"], "timeouts": r["timeouts"], "step_p99_s": None, "host_energy_per_task_j": None}


def scheduler_args(name: str) -> tuple[str, ...]:
    """The ``mrmt lorr run`` arguments of scheduler row ``name`` (``ising@host``: ``ising``'s host-rule twin)."""
    base = name.split("@")[0]
    args = ("--scheduler", base) + (() if base.startswith("lorr-") else ("--replan",))  # pipelines re-plan
    return args + (("--host-rule", "all") if name.endswith("@host") else ())


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--instances", default="RANDOM-04,RANDOM-05")
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--seed", type=int, default=0, help="every row's seed (the record holder's code: its own)")
    parser.add_argument("--active", type=float, default=0.57, help="share of the team at work (epibt-chain rows)")
    parser.add_argument("--portfolio", type=int, default=2)
    parser.add_argument("--guidance", type=int, default=2, help="crisscross lanes' cost (epibt-chain rows)")
    parser.add_argument("--schedulers", default="strong",
                        help="comma-separated schedulers of the epibt-chain rows: lorr-greedy, strong, ising, "
                        "ising@host")
    parser.add_argument("--chip-rows", choices=("on", "twins", "none"), default="none",
                        help="the chip annealer, its host-rule twin and host chains + chip (twins: the first two)")
    parser.add_argument("--reads", type=int, default=16, help="reads per chip program")
    parser.add_argument("--entry-row", choices=("on", "none"), default="on", help="the default entry's row")
    parser.add_argument("--record-holder", default=None, help="the winner's start-kit binary (optional)")
    parser.add_argument("--write", action="store_true")
    args = parser.parse_args(argv)
    scheds = [n.strip() for n in args.schedulers.split(",") if n.strip()]
    chain = ("--planner", "epibt-chain", "--guidance", str(args.guidance), "--planner-option", f"active={args.active}",
             "--planner-option", "active_by=task", "--planner-option", f"portfolio={args.portfolio}")
    ref_row = f"epibt-chain ({scheds[0]})"
    table = []
    for name in [n.strip() for n in args.instances.split(",") if n.strip()]:
        inst = ROOT / f"{name}.json"
        clock = ("--steps", str(args.steps), "--step-limit", "rules", "--seed", str(args.seed))
        runs = {"entry": lorr_run_json(inst, "--entry", "default", "--steps", str(args.steps), "--seed",
                                       str(args.seed))} \
            if args.entry_row == "on" else {}
        for sched in scheds:
            runs[f"epibt-chain ({sched})"] = lorr_run_json(inst, *scheduler_args(sched), *chain, *clock)
        if args.chip_rows != "none":
            chip = (*scheduler_args(scheds[0]), chain[0], "epibt-chain-ising", *chain[2:], "--planner-option",
                    f"num_reads={args.reads}")
            runs["chip annealer"] = lorr_run_json(inst, *chip, *clock)
            runs["host-rule twin"] = lorr_run_json(inst, *chip, "--planner-option", "decider=host", *clock)
            if args.chip_rows == "on":
                runs["host chains + chip"] = lorr_run_json(inst, *chip, "--planner-option", "lns=null", *clock)
        if args.record_holder:
            runs["record holder"] = record_holder(args.record_holder, inst, args.steps)
        for row, rec in runs.items():
            table.append((name, row, rec))
            print(f"{name} {row}: {rec['tasks_finished']} tasks", file=sys.stderr)
    lines = [SECTION, "",
             f"`python benchmarks/lorr_chains.py --instances {args.instances} --steps {args.steps} --active "
             f"{args.active} --portfolio {args.portfolio} --guidance {args.guidance} --schedulers {args.schedulers}"
             + (f" --seed {args.seed}" if args.seed else "")
             + (" --record-holder BIN" if args.record_holder else "")
             + (f" --chip-rows {args.chip_rows} --reads {args.reads}" if args.chip_rows != "none" else "")
             + (" --entry-row none" if args.entry_row == "none" else "")
             + f"` ({cpu_name()}; first {args.steps} steps, 1 s clock, seed {args.seed}; step time: host seconds plus the "
             "machine's own)", "",
             "| instance | planner | tasks | x first | timeouts | step p99 s | chip calls / step | host J / task | "
             "machine J / task |", "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for name, row, rec in table:
        tasks, host = rec["tasks_finished"], rec.get("host_energy_per_task_j")
        ref = next(r for n, w, r in table if n == name and w == ref_row)["tasks_finished"]
        cells = [f"{rec['step_p99_s']:.3f}" if rec["step_p99_s"] is not None else "",
                 f"{rec['chip_calls'] / max(rec['decisions'], 1):,.0f}" if "chip_calls" in rec else "",
                 f"{host:.2f}" if host is not None else "",
                 f"{rec['machine_energy_per_task_j']:.2e}" if "machine_energy_per_task_j" in rec else ""]
        lines.append(f"| {name} | {row} | {tasks:,} | {tasks / max(ref, 1):.3f} | {rec['timeouts']} | "
                     + " | ".join(cells) + " |")
    finish(SECTION, lines, args.write)


if __name__ == "__main__":
    main()
