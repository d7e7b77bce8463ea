"""The Ising pipeline on a faulty chip: route cost, chip calls, retries and fallbacks against the fault rate.

Set-up: the paper's worlds (10x10, 20 obstacles, 3 robots, 10 targets, centre placement,
``generate_world(i, n_robots=3, n_targets=10, placement="centre")``), seeds ``0..N-1``
(default 100).  World ``i`` is planned by the strong pipeline (SSA + 3-opt + A*) and by
``make_pipeline("ising", chip=EmulatedChip(spec))`` with ``spec.seed = i`` (so the faulty
cores and stuck spins differ from world to world) and one fault knob swept at a time
(``readout_flip_prob``, ``dead_cores``, ``stuck_spins``, ``program_error_prob``), plus the
combined target point ``readout_flip_prob=0.01, dead_cores=1, stuck_spins=2``.  A fresh chip
(and pipeline) per world: each chip runs its bring-up health probe, reported apart.

Reported per setting: valid plans, median route cost, the per-world cost ratio Ising / strong
(median and mean) and the ratio of the medians, median accelerator calls per plan (physical +
logical projected) and parallel chip time (per batch over the healthy cores), mean retries and
fallbacks per plan, plans with any fallback, probe calls per chip.

Run one benchmark at a time (the machine has 2 cores)::

    flock /tmp/mrmt-bench.lock python benchmarks/faults.py --write-results [--figure docs/faults/fig_faults.png]

``--write-results`` replaces the "Issue 14: faulty chip" section of ``benchmarks/RESULTS.md``.
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from ising_backend import ChipSpec, EmulatedChip
from mrmt_env.generation import generate_world
from planners.pipeline import make_pipeline

try:
    from _common import cpu_name, write_results_section  # run as a script: python benchmarks/<name>.py
except ImportError:  # imported as benchmarks.faults
    from benchmarks._common import cpu_name, write_results_section

SECTION = "## Issue 14: faulty chip (fault model and graceful degradation)"
TARGET = {"readout_flip_prob": 0.01, "dead_cores": 1, "stuck_spins": 2}
SWEEPS = {
    "readout_flip_prob": (0.0, 0.01, 0.02, 0.05, 0.1),
    "dead_cores": (0, 1, 2, 4, 7, 8),
    "stuck_spins": (0, 1, 2, 4, 8, 16),
    "program_error_prob": (0.0, 0.01, 0.05, 0.1, 0.2, 0.3, 0.5),
}


def measure(worlds, strong_costs, faults: dict, fallback: str) -> dict:
    """Per-world figures of the Ising pipeline on chips with ``faults`` (``spec.seed`` = world seed)."""
    rows = {k: [] for k in ("valid", "cost", "ratio", "calls", "chip_par", "retries", "fallbacks", "probe")}
    for i, w in enumerate(worlds):
        chip = EmulatedChip(ChipSpec(seed=i, **faults))
        probe = chip.ledger.probe_calls
        p = make_pipeline("ising", chip=chip, fallback=fallback).plan(w, seed=i)
        rows["valid"].append(bool(p.success))
        rows["cost"].append(p.route_cost if p.success else np.nan)
        rows["ratio"].append(p.route_cost / strong_costs[i] if p.success else np.nan)
        rows["calls"].append(p.compute.chip_calls + p.compute.logical_calls)
        rows["chip_par"].append(p.compute.chip_time_parallel_s)
        rows["retries"].append(p.compute.retries)
        rows["fallbacks"].append(p.compute.fallbacks)
        rows["probe"].append(probe)
    return {k: np.asarray(v, dtype=float) for k, v in rows.items()}


def summarize(r: dict, strong_costs) -> dict:
    ok = r["valid"] > 0
    return {
        "valid": float(r["valid"].mean()),
        "cost": float(np.median(r["cost"][ok])) if ok.any() else np.nan,
        "ratio": float(np.median(r["ratio"][ok])) if ok.any() else np.nan,
        "mean_ratio": float(np.mean(r["ratio"][ok])) if ok.any() else np.nan,
        "ratio_of_medians": float(np.median(r["cost"][ok]) / np.median(strong_costs)) if ok.any() else np.nan,
        "calls": float(np.median(r["calls"])),
        "chip_par": float(np.median(r["chip_par"])),
        "retries": float(r["retries"].mean()),
        "fallbacks": float(r["fallbacks"].mean()),
        "with_fallback": float((r["fallbacks"] > 0).mean()),
        "probe": float(np.median(r["probe"])),
    }


def table(results: list) -> str:
    lines = ["| fault | value | valid plans | median cost | median cost / strong | mean cost / strong "
             "| ratio of medians | calls / plan "
             "| parallel chip time / plan | retries / plan | fallbacks / plan | plans with a fallback "
             "| probe calls / chip |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for knob, value, m in results:
        lines.append(f"| {knob} | {value} | {m['valid']:.0%} | {m['cost']:.1f} | {m['ratio']:.3f} | {m['mean_ratio']:.3f} "
                     f"| {m['ratio_of_medians']:.3f} | {m['calls']:.0f} | {m['chip_par'] * 1e6:.0f} us | {m['retries']:.2f} "
                     f"| {m['fallbacks']:.2f} "
                     f"| {m['with_fallback']:.0%} | {m['probe']:.0f} |")
    return "\n".join(lines)


def figure(by_mode: dict, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    knobs = list(SWEEPS)
    rows = (("valid", "valid plans"), ("ratio_of_medians", "median cost / strong median"),
            ("calls", "accelerator calls / plan"), ("fallbacks", "fallbacks, retries / plan"))
    fig, axes = plt.subplots(len(rows), len(knobs), figsize=(3.3 * len(knobs), 9.5), sharey="row")
    for mode, results in by_mode.items():
        for col, knob in enumerate(knobs):
            pts = [(float(v), m) for k, v, m in results if k == knob]
            x = [v for v, _ in pts]
            for row, (key, label) in enumerate(rows):
                ax = axes[row, col]
                ax.plot(x, [m[key] for _, m in pts], "o-", label=f"fallbacks, fallback={mode}" if key == "fallbacks"
                        else f"fallback={mode}")
                if key == "fallbacks" and mode == next(iter(by_mode)):
                    ax.plot(x, [m["retries"] for _, m in pts], "s--", color="grey", label="retries")
                if row == len(rows) - 1:
                    ax.set_xlabel(knob)
                if col == 0:
                    ax.set_ylabel(label)
                ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7)
    axes[-1, -1].legend(fontsize=7)
    axes[-1, -1].set_yscale("symlog", linthresh=1.0)
    fig.suptitle("Ising pipeline on a faulty chip: paper setup, centre placement, one fault knob at a time")
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--worlds", type=int, default=100, help="worlds per setting (default 100)")
    ap.add_argument("--target-worlds", type=int, default=300, help="worlds for the target point (default 300)")
    ap.add_argument("--fallback", default="unavailable,failure",
                    help="comma-separated fallback modes of the Ising layers, one table each (default unavailable,failure)")
    ap.add_argument("--write-results", action="store_true", help="replace the section in benchmarks/RESULTS.md")
    ap.add_argument("--figure", default=None, help="write the curves as a PNG to this path")
    args = ap.parse_args()
    if args.worlds < 1 or args.target_worlds < 1:
        ap.error("--worlds and --target-worlds must be >= 1")
    modes = [m.strip() for m in args.fallback.split(",") if m.strip()]
    if not modes or any(m not in ("never", "unavailable", "failure") for m in modes):
        ap.error(f"--fallback must name never, unavailable and/or failure, got {args.fallback!r}")
    t0 = time.perf_counter()
    n_all = max(args.worlds, args.target_worlds)
    worlds = [generate_world(i, n_robots=3, n_targets=10, placement="centre") for i in range(n_all)]
    strong = make_pipeline("strong")
    strong_costs = []
    for i, w in enumerate(worlds):
        s = strong.plan(w, seed=i)
        if not s.success:
            raise RuntimeError(f"world {i}: the strong plan failed ({s.failure})")
        strong_costs.append(s.route_cost)
    strong_costs = np.asarray(strong_costs, dtype=float)
    measure(worlds[:2], strong_costs, TARGET, modes[0])  # compile the kernels outside the measured runs
    by_mode = {}
    for mode in modes:
        results = []
        for knob, values in SWEEPS.items():
            for v in values:
                r = measure(worlds[:args.worlds], strong_costs, {knob: v}, mode)
                results.append((knob, v, summarize(r, strong_costs[:args.worlds])))
                print(mode, table(results[-1:]).splitlines()[-1], flush=True)
        target = measure(worlds[:args.target_worlds], strong_costs, TARGET, mode)
        results.append(("**target**: " + ", ".join(f"{k}={v}" for k, v in TARGET.items()),
                        f"{args.target_worlds} worlds", summarize(target, strong_costs[:args.target_worlds])))
        by_mode[mode] = results
    elapsed = time.perf_counter() - t0
    texts = {mode: table(results) for mode, results in by_mode.items()}
    for mode, text in texts.items():
        print(f"\nfallback={mode}\n{text}")
    print(f"\nstrong median cost {np.median(strong_costs[:args.worlds]):.1f} ({args.worlds} worlds), "
          f"{np.median(strong_costs[:args.target_worlds]):.1f} ({args.target_worlds} worlds); {elapsed:.0f} s")
    if args.figure:
        figure({mode: results[:-1] for mode, results in by_mode.items()}, args.figure)
        print("wrote", args.figure)
    if args.write_results:
        cmd = (f"python benchmarks/faults.py --worlds {args.worlds} --target-worlds {args.target_worlds} "
               f"--fallback {','.join(modes)}" + (f" --figure {args.figure}" if args.figure else "") + " --write-results")
        lines = [
            SECTION,
            "",
            f"`{cmd}` on {cpu_name()} ({platform.python_implementation()} {platform.python_version()}), "
            f"{args.worlds} worlds per setting (the target point: {args.target_worlds}) of the paper setup (10x10, "
            "3 robots, 10 targets, centre placement, seeds 0..N-1). Each world gets a fresh chip with "
            "`ChipSpec(seed=world seed, <fault>)`, so the dead cores and stuck spins move from world to world; "
            "one fault knob at a time, the others at their defaults (`readout_flip_prob` is the existing noise "
            "knob, shown for comparison: it is not handled by the fault machinery). Calls per plan count physical "
            "and projected logical calls, retries included; the bring-up health probe of each chip is charged to "
            "the chip, not to a plan (last column). Cost columns over valid plans: the per-world ratio against "
            "the strong pipeline (median and mean of the ratios) and the ratio of the median costs (strong median "
            f"{np.median(strong_costs[:args.worlds]):.1f} over {args.worlds} worlds, "
            f"{np.median(strong_costs[:args.target_worlds]):.1f} over {args.target_worlds}).",
        ]
        for mode, text in texts.items():
            lines += ["", f"Ising layers' fallback mode `{mode}`:", "", text]
        lines += ["", f"Run took {elapsed:.0f} s."]
        write_results_section(SECTION, "\n".join(lines))
        print("wrote", SECTION)


if __name__ == "__main__":
    main()
