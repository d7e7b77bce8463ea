"""The map families side by side: generate, plan, export to MovingAI, draw.

Generates worlds of each family (``uniform``, ``warehouse``, ``rooms``,
``maze``; :mod:`mrmt_env.maps`), plans them with a pipeline and prints the
obstacle density, generation time, route cost and planning time.  Optionally
writes one map of each family as MovingAI ``.map`` / ``.scen`` files (the
maps in ``examples/data/`` come from ``--export examples/data``) and a
picture with one world of each family (``docs/maps.png``).

    python examples/map_families.py [--size 64] [--robots 10] [--targets 100] [--worlds 3]
        [--pipeline strong] [--export DIR] [--png maps.png]
"""

import argparse
import time
from pathlib import Path

import numpy as np

from mrmt_env import generate_world
from mrmt_env.movingai import world_from_movingai, write_movingai_map, write_movingai_scen
from planners.pipeline import make_pipeline
from planners.plan import validate_plan

FAMILIES = ("uniform", "warehouse", "rooms", "maze")
#: the small maps of ``examples/data/`` (family, height, width, robots, targets, seed)
EXPORTS = (("warehouse", 32, 32, 10, 100, 0), ("rooms", 24, 24, 5, 40, 0), ("maze", 31, 31, 5, 40, 0))


def export(out: Path) -> None:
    """Write each map of :data:`EXPORTS` as ``<family>_<H>x<W>.map`` / ``.scen`` and read it back."""
    out.mkdir(parents=True, exist_ok=True)
    for family, h, w, robots, targets, seed in EXPORTS:
        world = generate_world(seed, height=h, width=w, n_robots=robots, n_targets=targets, layout=family)
        name = f"{family}_{h}x{w}"
        write_movingai_map(world.grid, out / f"{name}.map")
        write_movingai_scen(world, out / f"{name}.scen", f"{name}.map")
        back = world_from_movingai(out / f"{name}.map", out / f"{name}.scen", n_robots=robots, n_targets=targets)
        assert back == world
        print(f"wrote {out / name}.map and .scen ({robots} robots, {targets} targets)")


def picture(path: Path, size: int, robots: int, targets: int) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from mrmt_env.render import render_rgb

    fig, axes = plt.subplots(2, 2, figsize=(10, 10.6))
    for ax, family in zip(axes.ravel(), FAMILIES):
        world = generate_world(0, height=size, width=size, n_robots=robots, n_targets=targets, layout=family)
        ax.imshow(render_rgb(world.grid, world.targets, [False] * world.n_targets, world.robots, cell=8))
        ax.set_title(f"{family}: {world.grid.mean():.0%} obstacles")
        ax.axis("off")
    fig.suptitle(f"generate_world(0, height={size}, width={size}, n_robots={robots}, n_targets={targets}, "
                 "layout=...)\nrobots: filled squares, targets: rings")
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    fig.savefig(path, dpi=80)
    print(f"wrote {path}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=64, help="grid height and width")
    parser.add_argument("--robots", type=int, default=10)
    parser.add_argument("--targets", type=int, default=100)
    parser.add_argument("--worlds", type=int, default=3, help="worlds per family")
    parser.add_argument("--pipeline", default="strong", help="planner preset: fast, strong or ising")
    parser.add_argument("--export", type=Path, default=None, help="write the example MovingAI maps here")
    parser.add_argument("--png", type=Path, default=None, help="write a picture of one world per family")
    args = parser.parse_args(argv)

    pipeline = make_pipeline(args.pipeline)
    pipeline.plan(generate_world(0), seed=0)  # compile and warm up outside the timings
    print(f"{args.size}x{args.size}, {args.robots} robots, {args.targets} targets, pipeline {args.pipeline}, "
          f"{args.worlds} worlds per family (medians)")
    print(f"{'family':10} {'obstacles':>9} {'generate':>9} {'route cost':>10} {'makespan':>8} {'plan':>9} success")
    ok = True
    for family in FAMILIES:
        density, gen, cost, makespan, plan_s, success = [], [], [], [], [], 0
        for seed in range(args.worlds):
            t = time.perf_counter()
            world = generate_world(seed, height=args.size, width=args.size, n_robots=args.robots,
                                   n_targets=args.targets, layout=family)
            gen.append(time.perf_counter() - t)
            t = time.perf_counter()
            plan = pipeline.plan(world, seed=seed)
            plan_s.append(time.perf_counter() - t)
            density.append(world.grid.mean())
            cost.append(plan.route_cost)
            makespan.append(plan.makespan)
            if plan.success:
                validate_plan(world, plan)  # legal paths visiting every target, or an error
                success += 1
        ok &= success == args.worlds
        print(f"{family:10} {np.median(density):9.0%} {1e3 * np.median(gen):7.1f}ms {np.median(cost):10.0f} "
              f"{np.median(makespan):8.0f} {1e3 * np.median(plan_s):7.1f}ms {success}/{args.worlds}")
    if args.export is not None:
        export(args.export)
    if args.png is not None:
        picture(args.png, args.size, args.robots, args.targets)
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
