"""Map families: generation time per world, and the planners on the big registered ids.

Part 1: ``generate_world`` per family (``uniform``, ``warehouse``, ``rooms``, ``maze``) on square
grids of ``--sides`` (default 64, 128, 256, 1024, 2048) with 10 robots and 100 targets (fewer on
2048 x 2048, where the distance-field limit allows 32 nodes): median wall time per world (the
``World``'s validation, R BFS fields, included), obstacle share.

Part 2: every new registered id through ``agents.evaluation.evaluate`` (the env loop, one plan per
episode) with the strong and fast pipelines on ``--worlds`` worlds: success, median route cost,
makespan, the most env steps against the id's step limit, median host time per plan.

    flock /tmp/mrmt-bench.lock python benchmarks/maps.py --write-results
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from mrmt_env.generation import MAX_FIELD_CELLS, generate_world

try:
    from _common import cpu_name, write_results_section  # run as a script: python benchmarks/<name>.py
except ImportError:  # imported as benchmarks.maps
    from benchmarks._common import cpu_name, write_results_section

SECTION = "## Map families (issue 10)"
FAMILIES = ("uniform", "warehouse", "rooms", "maze")
IDS = ("mrmt_env/MRMT-64x64-v0", "mrmt_env/MRMT-Warehouse-v0", "mrmt_env/MRMT-Rooms-v0", "mrmt_env/MRMT-Maze-v0",
       "mrmt_env/MRMT-Warehouse-128x128-v0", "mrmt_env/MRMT-Assign-Warehouse-v0")


def generation(sides, n_worlds: int) -> list[dict]:
    for family in FAMILIES:  # warm-up: numba caches
        generate_world(0, height=32, width=32, layout=family)
    rows = []
    for side in sides:
        n_targets = min(100, MAX_FIELD_CELLS // (side * side) - 10)
        worlds = n_worlds if side <= 256 else max(1, n_worlds // 5)
        for family in FAMILIES:
            times, density = [], []
            for seed in range(worlds):
                t = time.perf_counter()
                w = generate_world(seed, height=side, width=side, n_robots=10, n_targets=n_targets, layout=family)
                times.append(time.perf_counter() - t)
                density.append(float(w.grid.mean()))
            rows.append(dict(side=side, family=family, n_targets=n_targets, worlds=worlds,
                             ms=1e3 * float(np.median(times)), density=float(np.mean(density))))
            print(f"{side:5d} {family:9s} N={n_targets:3d} {rows[-1]['ms']:9.1f} ms  {rows[-1]['density']:.1%}",
                  flush=True)
    return rows


def planners(ids, n_worlds: int, controllers) -> list[dict]:
    import gymnasium as gym

    from agents.evaluation import evaluate
    from agents.runner import RunConfig

    rows = []
    for env_id in ids:
        res = evaluate(list(controllers), env_id=env_id, n_worlds=n_worlds, run=RunConfig.from_jobs(1, progress=False))
        spec = gym.spec(env_id)
        for name in controllers:
            rs = [r for r in res.rows if r["controller"] == name]
            rows.append(dict(env_id=env_id, controller=name, worlds=len(rs),
                             success=sum(bool(r["is_success"]) for r in rs),
                             cost=float(np.median([r["route_cost"] for r in rs])),
                             makespan=float(np.median([r["makespan"] for r in rs])),
                             steps_max=int(max(r["steps"] for r in rs)), limit=spec.max_episode_steps,
                             plan_ms=1e3 * float(np.median([r["host_cpu_s"] for r in rs]))))
            r = rows[-1]
            print(f"{env_id:36s} {name:6s} {r['success']}/{r['worlds']} cost {r['cost']:.0f} makespan "
                  f"{r['makespan']:.0f} steps max {r['steps_max']} (limit {r['limit']}) plan {r['plan_ms']:.1f} ms",
                  flush=True)
    return rows


def block(gen_rows, plan_rows, n_worlds: int) -> str:
    sides = sorted({r["side"] for r in gen_rows})
    lines = [SECTION, "",
             f"`python benchmarks/maps.py` on {cpu_name()} (2 cores shared with other jobs; wall times vary "
             "with the load).", "",
             "Generation, median ms per world (10 robots; 100 targets, on 2048 x 2048 the distance-field "
             "limit's 22; the `World`'s validation and its robots' BFS fields included):", "",
             "| family | obstacles | " + " | ".join(f"{s} x {s}" for s in sides) + " |",
             "|---|---:|" + "---:|" * len(sides)]
    for family in FAMILIES:
        rs = {r["side"]: r for r in gen_rows if r["family"] == family}
        dens = rs[max(s for s in sides if s <= 64) if any(s <= 64 for s in sides) else sides[0]]["density"]
        lines.append(f"| {family} | {dens:.0%} | " + " | ".join(f"{rs[s]['ms']:.1f}" for s in sides) + " |")
    lines += ["", f"The registered big-world ids in the env loop (`agents.evaluation.evaluate`, {n_worlds} worlds "
              "each, one plan per episode; steps: moves in the grid env, decisions in the plan-level env):", "",
              "| id | controller | success | median route cost | median makespan | most steps / step limit | "
              "median host time per plan |", "|---|---|---:|---:|---:|---:|---:|"]
    for r in plan_rows:
        lines.append(f"| `{r['env_id']}` | {r['controller']} | {r['success']}/{r['worlds']} | {r['cost']:.0f} | "
                     f"{r['makespan']:.0f} | {r['steps_max']} / {r['limit']} | {r['plan_ms']:.1f} ms |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sides", type=int, nargs="+", default=[64, 128, 256, 1024, 2048])
    parser.add_argument("--gen-worlds", type=int, default=10, help="worlds per (family, side); a fifth above 256")
    parser.add_argument("--worlds", type=int, default=10, help="worlds per registered id")
    parser.add_argument("--controllers", nargs="+", default=["strong", "fast"])
    parser.add_argument("--write-results", action="store_true", help="update the section of benchmarks/RESULTS.md")
    args = parser.parse_args(argv)
    gen_rows = generation(args.sides, args.gen_worlds)
    plan_rows = planners(IDS, args.worlds, args.controllers)
    text = block(gen_rows, plan_rows, args.worlds)
    print(text)
    if args.write_results:
        write_results_section(SECTION, text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
