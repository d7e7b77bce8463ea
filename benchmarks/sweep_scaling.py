"""Episodes per second of ``mrmt sweep`` against workers, for the process and Ray backends.

Workload: a chip sweep of the paper's set-up (10x10, 3 robots, 10 targets): ``--specs`` chip
specs (j_range x n_spins) of the Ising pipeline on ``--worlds`` worlds each, plus the strong
pipeline once per world (default 4 x 500 + 500 = 2,500 episodes).  Each (backend, workers)
run is timed end to end, pool or Ray start-up and per-worker warm-up included, and its rows
are checked equal to the first run's (route cost, chip calls: the backends must agree).
Parallel efficiency at k workers = (episodes/s at k) / (k x episodes/s at 1).

Run one benchmark at a time (the machine has 2 cores)::

    flock /tmp/mrmt-bench.lock python benchmarks/sweep_scaling.py --write-results

``--write-results`` replaces the "Sweep scaling" section of ``benchmarks/RESULTS.md``.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

from agents.runner import RunConfig
from agents.sweep import SweepConfig, parse_axes, run_sweep

try:
    from _common import cpu_name, finish  # run as a script: python benchmarks/<name>.py
except ImportError:  # imported as benchmarks.sweep_scaling
    from benchmarks._common import cpu_name, finish

SECTION = "## Sweep scaling (issue 12)"
KEYS = ("spec_id", "controller", "world_seed", "route_cost", "chip_calls", "logical_calls", "error")


def measure(config: SweepConfig, backend: str, jobs: int) -> tuple[float, list]:
    t0 = time.perf_counter()
    result = run_sweep(config, RunConfig(backend=backend, jobs=jobs, progress=False))
    return time.perf_counter() - t0, [[r.get(k) for k in KEYS] for r in result.rows]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", type=int, default=500)
    ap.add_argument("--backends", default="process,ray")
    ap.add_argument("--workers", default="1,2")
    ap.add_argument("--write-results", action="store_true")
    args = ap.parse_args()
    axes = parse_axes(["j_range=7,15", "n_spins=45,64"])
    config = SweepConfig(axes=axes, controllers=("ising", "strong"), n_worlds=args.worlds)
    n_episodes = (4 + 1) * args.worlds
    workers = [int(w) for w in args.workers.split(",")]
    table, reference = [], None
    for backend in args.backends.split(","):
        rates = {}
        for k in workers:
            wall, rows = measure(config, backend, k)
            if reference is None:
                reference = rows
            same = rows == reference
            rates[k] = n_episodes / wall
            eff = rates[k] / (k * rates[workers[0]]) if k != workers[0] else 1.0
            table.append((backend, k, wall, rates[k], eff, same))
            print(f"{backend:8s} workers={k}  {wall:7.1f} s  {rates[k]:7.1f} episodes/s  efficiency {eff:.2f}  "
                  f"rows {'identical' if same else 'DIFFER'}", flush=True)
    lines = [
        SECTION,
        "",
        f"Machine: {cpu_name()}, {os.cpu_count()} cores, Python {platform.python_version()}.",
        f"Workload: `mrmt sweep` of 4 chip specs (j_range 7, 15 x n_spins 45, 64) x {args.worlds} paper-setup "
        f"worlds for the Ising pipeline, plus the strong pipeline once per world: {n_episodes} episodes per run, "
        "timed end to end (pool or Ray start-up and per-worker warm-up included).",
        "",
        "| backend | workers | wall (s) | episodes/s | parallel efficiency | rows equal to the first run |",
        "|---|---|---|---|---|---|",
    ]
    for backend, k, wall, rate, eff, same in table:
        lines.append(f"| {backend} | {k} | {wall:.1f} | {rate:.1f} | {eff:.2f} | {'yes' if same else 'NO'} |")
    lines += ["", "Command: `flock /tmp/mrmt-bench.lock python benchmarks/sweep_scaling.py --write-results`."]
    finish(SECTION, lines, args.write_results)


if __name__ == "__main__":
    main()
