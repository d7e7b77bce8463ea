"""The chip design-space sweep of the docs: which chip should a robotics team build or buy?

Grid: n_spins {16, 32, 45, 64, 100, 128} x coefficient range {3, 7, 15, 31} (h and j both
(-m, m)) x cores {1, 8, 32}
(72 specs), on 100 worlds of the paper's set-up (10x10, 3 robots, 10 targets) and 20 worlds of
32x32 (3 robots, 10 targets), Ising pipeline per spec and the strong pipeline once per world
(the reference of the gaps).  Writes per world family ``specs.csv``, ``summary.md`` and
``pareto.png`` into ``--out`` (default ``docs/sweep``), with the full per-episode rows in
``sweep.csv`` there unless ``--no-rows``.  Equivalent to ``mrmt sweep`` once per family::

    mrmt sweep --chip n_spins=16,32,45,64,100,128 --chip coef_range=3,7,15,31 --chip n_cores=1,8,32 \\
        --worlds 100 --out DIR

    flock /tmp/mrmt-bench.lock python benchmarks/chip_sweep.py --write-results
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from agents.evaluation import write_csv
from agents.runner import RunConfig
from agents.sweep import SweepConfig, SweepResult, parse_axes, run_sweep
from agents.sweep_report import pareto_front, plot_pareto, spec_stats, write_summary

try:
    from _common import finish  # run as a script: python benchmarks/<name>.py
except ImportError:  # imported as benchmarks.chip_sweep
    from benchmarks._common import finish

SECTION = "## Chip sweep (issue 12)"
FAMILIES = {"paper": ({}, 100), "32x32": ({"height": 32, "width": 32}, 20)}


def sweep(env_kwargs: dict, n_worlds: int, spins: str, ranges: str, cores: str, jobs: int,
          controller: str = "ising") -> SweepResult:
    axes = parse_axes([f"n_spins={spins}", f"coef_range={ranges}", f"n_cores={cores}"])
    config = SweepConfig(axes=axes, controllers=(controller, "strong"), n_worlds=n_worlds, env_kwargs=env_kwargs)
    return run_sweep(config, RunConfig(backend="process", jobs=jobs, progress=True))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spins", default="16,32,45,64,100,128")
    ap.add_argument("--ranges", default="3,7,15,31")
    ap.add_argument("--cores", default="1,8,32")
    ap.add_argument("--families", default="paper,32x32")
    ap.add_argument("--worlds", type=int, default=None, help="worlds per family (default 100 paper, 20 32x32)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default="docs/sweep")
    ap.add_argument("--controller", default="ising", help="the Ising preset swept (ising or ising-paper)")
    ap.add_argument("--no-rows", action="store_true", help="do not write the per-episode sweep.csv")
    ap.add_argument("--write-results", action="store_true")
    args = ap.parse_args()
    lines = [SECTION, ""]
    for family in args.families.split(","):
        env_kwargs, n = FAMILIES[family]
        n = args.worlds or n
        t0 = time.perf_counter()
        result = sweep(env_kwargs, n, args.spins, args.ranges, args.cores, args.jobs, args.controller)
        wall = time.perf_counter() - t0
        out = Path(args.out) / family
        stats = spec_stats(result)
        write_csv(stats, out / "specs.csv")
        if not args.no_rows:
            result.to_csv(out / "sweep.csv")
        plot_pareto(stats, out / "pareto.png", title=f"chip sweep, {family} worlds ({n}): filled = every world "
                                                        "solved, hollow = some failed; gap to the strong pipeline")
        write_summary(result, stats, out / "summary.md")
        ok = [s for s in stats if s["spec_id"] >= 0 and s["success_rate"] == 1.0]
        lines.append(f"### {family} worlds ({n}), `{args.controller}`, {len(result.specs)} specs, "
                     f"{len(result.rows)} episodes, {wall:.0f} s on 2 workers")
        lines.append("")
        lines.append(f"Specs solving every world: {len(ok)} of {len(result.specs)}.")
        for x, label in (("accelerator_energy_j", "accelerator energy"), ("latency_parallel_s", "latency")):
            front = pareto_front(stats, x)
            lines.append(f"Pareto front, gap vs {label}: " + "; ".join(
                f"`{s['spec']}` ({s['mean_gap_pct']:.2f} %, {s[x]:.3g})" for s in front))
        lines.append("")
        print("\n".join(lines[-6:]), flush=True)
    lines.append(f"Files: `{args.out}/<family>/summary.md`, `specs.csv`, `pareto.png`. "
                 "Command: `flock /tmp/mrmt-bench.lock python benchmarks/chip_sweep.py --write-results`.")
    finish(SECTION, lines, args.write_results)


if __name__ == "__main__":
    main()
