"""The chip planners' host side per program (issue 81, item 2): host microseconds per group decision.

Each run: the strong scheduler (re-planning) on a League instance for ``--steps`` steps, work-bounded (no clock, so
every run does the same work), a chip planner deciding its neighbourhood groups on the emulated chip; or the chip
scheduler ``lorr-ising`` (its task groups) with the start kit's PIBT.  A program's
host time is the group rounds' host seconds (choosing the groups, the host rule beside the chip, building the
programs, the machine session's own Python, reading the answers back, applying them; the emulation's seconds are
not the host's) over the programs posed, the rounds' own count (``stats``), checked against the ledger's programs.

    flock /tmp/mrmt-bench.lock python benchmarks/chip_host.py --steps 10 [--write]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import cpu_name, finish  # noqa: E402

SECTION = "## The chip's host side per program (issue 81)"
ROOT = Path(__file__).resolve().parents[2] / "shared" / "lorr" / "2024-main" / "random.domain"
PLANNERS = {"epibt-chain-ising": {"guidance": 2}, "epibt-ising": {"rounds": 16, "lns": 0}}
#: The chip scheduler, with the start kit's PIBT planner: its task groups' programs (decision class task_groups).
SCHEDULERS = ("lorr-ising",)


def run(instance: str, planner: str, steps: int, seed: int = 0) -> dict:
    from agents.lorr.schedulers import make_scheduler
    from mrmt_env.lorr.instance import read_instance
    from mrmt_env.lorr.loop import StepLoop
    from mrmt_env.lorr.sim import LoRRSimulator
    from planners.mapf import make_turning_planner

    inst = read_instance(ROOT / f"{instance}.json")
    chip_scheduler = planner in SCHEDULERS
    sched = make_scheduler(planner, seed=seed) if chip_scheduler else make_scheduler("strong", seed=seed, replan=True)
    loop = StepLoop(LoRRSimulator(inst, record=False), sched)
    ex = make_turning_planner("pibt" if chip_scheduler else planner, inst.grid, seed=seed,
                              **({} if chip_scheduler else PLANNERS[planner]))
    sim = loop.sim
    wall = emul = 0.0
    for _ in range(steps):
        t0 = time.perf_counter()
        loop.propose()
        act = ex.actions(sim.pos, sim.orient, loop.goal_cells())
        wall += time.perf_counter() - t0
        emul += float(ex.last_compute.emulation_s) + float(getattr(sched, "last_compute", ex.last_compute).emulation_s
                                                          if chip_scheduler else 0.0)
        loop.advance(act)
    stats, ledger = (sched.stats, sched.ledger) if chip_scheduler else (ex.machine_step.stats, ex.machine_step.ledger)
    return {"instance": instance, "planner": planner, "tasks": sim.finished, "programs": stats["decisions"],
            "rounds": stats.get("rounds", steps), "chip_calls": int(ledger.physical_calls), "host_s": stats["host_s"],
            "step_host_s": wall - emul, "us_per_program": 1e6 * stats["host_s"] / max(stats["decisions"], 1)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--instances", default="RANDOM-04,RANDOM-05")
    ap.add_argument("--planners", default=",".join((*PLANNERS, *SCHEDULERS)), help="chip planners and schedulers")
    ap.add_argument("--write", action="store_true", help="replace the section in RESULTS.md")
    args = ap.parse_args(argv)
    for name in args.planners.split(","):  # warm: compile and load every kernel untimed
        run(args.instances.split(",")[0], name, 2)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    rows = [run(i, p, args.steps) for i in args.instances.split(",") for p in args.planners.split(",")]
    lines = [f"`python benchmarks/chip_host.py --steps {args.steps}` at {commit} on {cpu_name()}: strong scheduler "
             f"(re-planning), seed 0, work-bounded.", "",
             "| instance | planner (or chip scheduler) | programs | rounds | chip calls | tasks | host us per program | "
             "rounds' host s | step host s (scheduler + planner) |", "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['instance']} | `{r['planner']}` | {r['programs']:,} | {r['rounds']:,} | {r['chip_calls']:,} | {r['tasks']} | "
                     f"{r['us_per_program']:.1f} | {r['host_s']:.2f} | {r['step_host_s']:.2f} |")
    finish(SECTION, lines, args.write)
    return 0


if __name__ == "__main__":
    sys.exit(main())
