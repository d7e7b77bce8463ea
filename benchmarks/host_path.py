"""Host time of the Ising pipeline beside the strong classical pipeline, measured in the same run.

Set-up: the paper's worlds (10x10, 20 obstacles, 3 robots, 10 targets, uniform placement),
seeds ``0..N-1`` (default 100).  For every world the strong pipeline (SSA + 3-opt + A*) and
the Ising pipeline plan one after the other, so both see the same machine load; the world's BFS
distance matrix, which both read, is computed before either plans.  Reported per
plan: the Ising pipeline's host CPU seconds per layer (sharing, tour, path, glue) and end to
end -- ``host_cpu_s`` = measured wall seconds minus the emulator's own run time
(``emulation_s``, the work the chip would do) -- and the strong pipeline's CPU seconds.

Modes: ``reused`` (default; one pipeline object plans every world, as a policy or the
``mrmt`` commands do: per-planner caches of patch programs stay warm) and ``fresh`` (a new
pipeline per world: every cache cold).

Run one benchmark at a time (the machine has 2 cores)::

    flock /tmp/mrmt-bench.lock python benchmarks/host_path.py --write-results

``--write-results`` replaces the "Issue 9: Ising host path" section of ``benchmarks/RESULTS.md``.
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from mrmt_env.generation import generate_world
from planners.pipeline import make_pipeline

try:
    from _common import cpu_name, write_results_section  # run as a script: python benchmarks/<name>.py
except ImportError:  # imported as benchmarks.host_path
    from benchmarks._common import cpu_name, write_results_section

SECTION = "## Issue 9: Ising host path"
LAYERS = ("sharing", "tour", "path")


def measure(n_worlds: int, mode: str, preset: str = "ising", seed0: int = 0) -> dict:
    """Per-world host seconds of both pipelines (see the module docstring)."""
    worlds = [generate_world(seed0 + i, n_robots=3, n_targets=10) for i in range(n_worlds)]
    warm = [generate_world(10**6 + i, n_robots=3, n_targets=10) for i in range(3)]
    pipes = {"ising": make_pipeline(preset), "strong": make_pipeline("strong")}
    for w in warm:  # compile every kernel outside the timed plans (a fresh pipeline keeps them)
        for p in pipes.values():
            p.plan(w, seed=0)
    for w in worlds:  # the world's BFS distances (~25 us), read by both pipelines: computed before either plans
        w.distance_matrix
    rows = {k: [] for k in ("strong", "ising", "emulation", "calls", "cost_ising", "cost_strong", *LAYERS, "glue")}
    for i, w in enumerate(worlds):
        if mode == "fresh":
            pipes = {"ising": make_pipeline(preset), "strong": make_pipeline("strong")}
        s = pipes["strong"].plan(w, seed=i)
        p = pipes["ising"].plan(w, seed=i)
        if not (s.success and p.success):
            raise RuntimeError(f"world {seed0 + i}: a plan failed ({s.failure or p.failure})")
        rows["strong"].append(s.compute.cpu_s)
        rows["ising"].append(p.compute.host_cpu_s)
        rows["emulation"].append(p.compute.emulation_s)
        rows["calls"].append(p.compute.chip_calls + p.compute.logical_calls)
        rows["cost_ising"].append(p.route_cost)
        rows["cost_strong"].append(s.route_cost)
        for layer in LAYERS:
            rows[layer].append(p.stats["layers"][layer].host_cpu_s)
        rows["glue"].append(p.stats["glue_cpu_s"])
    return {k: np.asarray(v, dtype=float) for k, v in rows.items()}


def summarize(r: dict) -> dict:
    med = {k: float(np.median(v)) for k, v in r.items()}
    med["ratio_of_medians"] = med["ising"] / med["strong"]
    med["median_ratio"] = float(np.median(r["ising"] / r["strong"]))
    med["p90_ising"] = float(np.percentile(r["ising"], 90))
    return med


def table(results: dict) -> str:
    lines = [
        "| preset | mode | Ising host (median) | p90 | sharing | tour | path | glue | emulation (excluded) "
        "| strong CPU | Ising / strong | median per-world ratio |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for (preset, mode), m in results.items():
        ms = lambda k: f"{m[k] * 1e3:.2f} ms"  # noqa: E731
        lines.append(f"| {preset} | {mode} | {ms('ising')} | {ms('p90_ising')} | {ms('sharing')} | {ms('tour')} | {ms('path')} "
                     f"| {ms('glue')} | {ms('emulation')} | {ms('strong')} | {m['ratio_of_medians']:.1f}x "
                     f"| {m['median_ratio']:.1f}x |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--worlds", type=int, default=100, help="worlds per mode (default 100)")
    ap.add_argument("--modes", default="reused,fresh", help="comma-separated: reused, fresh")
    ap.add_argument("--presets", default="ising,ising-paper", help="comma-separated Ising presets (default ising,ising-paper)")
    ap.add_argument("--write-results", action="store_true", help="replace the section in benchmarks/RESULTS.md")
    args = ap.parse_args()
    if args.worlds < 1:
        ap.error(f"--worlds must be >= 1, got {args.worlds}")
    modes = [m.strip() for m in args.modes.split(",") if m.strip()]
    bad = [m for m in modes if m not in ("reused", "fresh")]
    if bad or not modes:
        ap.error(f"--modes must name reused and/or fresh, got {args.modes!r}")
    t0 = time.perf_counter()
    presets = [p.strip() for p in args.presets.split(",") if p.strip()]
    if not presets or any(not p.startswith("ising") for p in presets):
        ap.error(f"--presets must name Ising presets (ising, ising-paper), got {args.presets!r}")
    raw = {(p, m): measure(args.worlds, m, p) for p in presets for m in modes}
    results = {k: summarize(r) for k, r in raw.items()}
    elapsed = time.perf_counter() - t0
    first = raw[(presets[0], modes[0])]
    text = table(results)
    print(text)
    print(f"\nroute cost ({presets[0]}): Ising median {np.median(first['cost_ising']):.1f}, strong {np.median(first['cost_strong']):.1f}; "
          f"accelerator calls per Ising plan (median) {np.median(first['calls']):.0f}; {elapsed:.0f} s")
    if args.write_results:
        block = "\n".join([
            SECTION,
            "",
            f"`python benchmarks/host_path.py --worlds {args.worlds} --write-results` on {cpu_name()} "
            f"({platform.python_implementation()} {platform.python_version()}), {args.worlds} worlds of the paper "
            "setup (10x10, 3 robots, 10 targets, uniform placement, seeds 0..N-1); both pipelines plan each world "
            "one after the other, so ratios compare like with like (the world's distance matrix, which both read, "
            "is computed before either plans). Host = measured seconds minus the "
            "emulator's run time (reported apart, charged to the chip as 50 us / 0.45 uJ per call). "
            "`reused`: one pipeline object for all worlds (patch-program caches warm, as in `mrmt` and policies); "
            "`fresh`: a new pipeline per world (caches cold). Medians per plan. `ising` = this package's defaults "
            "(boundary-refined sharing, chip tour, legs as descents of the BFS fields: no chip path calls), `ising-paper` = the paper's configuration.",
            "",
            text,
            "",
            f"Route cost (median, {presets[0]}): Ising {np.median(first['cost_ising']):.1f}, strong {np.median(first['cost_strong']):.1f}; "
            f"accelerator calls per Ising plan (median): {np.median(first['calls']):.0f}. Run took {elapsed:.0f} s.",
        ])
        write_results_section(SECTION, block)
        print("wrote", SECTION)


if __name__ == "__main__":
    main()
