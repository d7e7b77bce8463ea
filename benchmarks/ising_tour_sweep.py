"""Clustered Ising tour (planners.ising.tour): quality vs calls for its open choices.

Paper 6.2.2 setup: ``generate_world(seed, n_robots=1, n_targets=10)`` (10x10,
20 obstacles, uniform placement, BFS distances), gap to the exact Held-Karp
tour (``BruteTour``).  Each variant of :class:`IsingTour` runs on the same
worlds with ``rng = default_rng(seed)``.  Reports median / mean gap, how many
worlds are not optimal, median projected logical calls and host seconds per
solve (shared 2-core machine: indicative).  Then the physical-chip option:
valid-permutation rate of the one-hot programs per quantization rule.

    flock /tmp/mrmt-bench.lock python benchmarks/ising_tour_sweep.py [--n 100] [--seed0 0]

(The paper-figure comparison with the classical baselines is in
``benchmarks/quality_ising.py``.)
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from ising_backend import QUANTIZE_RULES, ChipSpec, EmulatedChip
from mrmt_env.generation import generate_world
from planners.ising.tour import IsingTour
from planners.tours_classical import BruteTour

VARIANTS = {
    "default (6-target patches x 4 starts, min linkage)": {},
    "1 start": {"n_starts": 1},
    "paper-like: 7-target patches, 1 start": {"patch_size": 7, "n_starts": 1},
    "7-target patches x 2 starts": {"patch_size": 7, "n_starts": 2},
    "mean linkage": {"cluster_distance": "mean"},
    "shared clustering over starts": {"share_clusters": True},
    "accept equal-cost patches": {"accept_equal": True},
    "tabu max_tenure 20 (solver default)": {"solver_options": {"max_tenure": 20}},
}


def run_variant(options: dict, worlds, optima) -> dict:
    solver = IsingTour(**options)
    gaps, calls, secs, fails = [], [], [], 0
    for seed, dist in worlds:
        t0 = time.perf_counter()
        res = solver.solve(dist, np.random.default_rng(seed))
        secs.append(time.perf_counter() - t0)
        if not res.success:
            fails += 1
            continue
        gaps.append(100.0 * (res.cost - optima[seed]) / optima[seed])
        calls.append(res.compute.logical_calls)
    g = np.asarray(gaps)
    return {"median gap %": float(np.median(g)), "mean gap %": float(g.mean()), "not optimal": int((g > 1e-9).sum()),
            "failures": fails, "median calls": float(np.median(calls)), "host s / solve": float(np.median(secs))}


def chip_rates(n_worlds: int, n_targets: int) -> dict:
    out = {}
    for rule in QUANTIZE_RULES:
        solver = IsingTour(backend="chip", chip_quantize=rule, chip=EmulatedChip(ChipSpec(), seed=0))
        prog = valid = ok = 0
        for seed in range(n_worlds):
            dist = generate_world(seed, n_robots=1, n_targets=n_targets).distance_matrix
            res = solver.solve(dist, np.random.default_rng(seed))
            prog += sum(v["programs"] for v in res.stats["mapping"]["tour"].values())
            valid += res.stats["valid_programs"]
            ok += res.success
        out[rule] = (prog, valid, ok)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100, help="worlds (default 100)")
    ap.add_argument("--seed0", type=int, default=0, help="first world seed")
    ap.add_argument("--chip-worlds", type=int, default=20)
    args = ap.parse_args()
    worlds = [(s, generate_world(s, n_robots=1, n_targets=10).distance_matrix)
              for s in range(args.seed0, args.seed0 + args.n)]
    brute = BruteTour()
    optima = {s: brute.solve(d).cost for s, d in worlds}
    print(f"{args.n} worlds (seeds {args.seed0}..{args.seed0 + args.n - 1}), 1 robot x 10 targets\n")
    print("| variant | median gap | mean gap | not optimal | median logical calls | host s/solve |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, opts in VARIANTS.items():
        r = run_variant(opts, worlds, optima)
        fail = f" ({r['failures']} failed)" if r["failures"] else ""
        print(f"| {name}{fail} | {r['median gap %']:.2f} % | {r['mean gap %']:.2f} % | {r['not optimal']} | "
              f"{r['median calls']:.0f} | {r['host s / solve']:.3f} |", flush=True)
    print(f"\nbackend='chip' ({args.chip_worlds} worlds each): one-hot programs valid / run, tours completed")
    print("| targets | " + " | ".join(QUANTIZE_RULES) + " |")
    print("|---|" + "---:|" * len(QUANTIZE_RULES))
    for nt in (3, 5, 10):
        rates = chip_rates(args.chip_worlds, nt)
        cells = [f"{v}/{p} valid, {ok} tours" for p, v, ok in rates.values()]
        print(f"| {nt} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
