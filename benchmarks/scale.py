"""How the pipelines scale with the number of targets, on random and warehouse maps.

For N in ``--targets`` (default 10, 20, 50, 100, 200, 300) with R = max(3, N // 10) robots
(or ``--robots``),
on ``--worlds`` worlds per (map, N) of ``--side`` x ``--side`` cells (default 128; layouts
``uniform`` with 20 % obstacles and ``warehouse``), every pipeline in ``--pipelines``
(default ising -- this package's defaults --, ising-paper -- the paper's configuration --,
strong, fast) plans each world once.  Reported per (map, N, pipeline): success,
mean route cost (and the ratio to the strong pipeline, world by world), median wall seconds per
plan, median chip calls (physical + projected logical) and accelerator energy.  The world set-up
(distance fields) is timed apart.  Writes ``docs/scale.png`` and the RESULTS.md section.

    flock /tmp/mrmt-bench.lock python benchmarks/scale.py --write-results
"""

from __future__ import annotations

import argparse
import math
import resource
import time

import numpy as np

from mrmt_env.generation import generate_world
from planners.pipeline import make_pipeline

try:
    from _common import cpu_name, finish  # run as a script: python benchmarks/<name>.py
except ImportError:  # imported as benchmarks.scale
    from benchmarks._common import cpu_name, finish

SECTION = "## Scale (issue 10)"
ORDER = ("ising", "ising-paper", "strong", "fast")


def _pipeline(name: str):
    """The pipeline of a preset name."""
    return make_pipeline(name)


def run(layouts, targets, pipelines, side: int, n_worlds: int, robots: int | None = None) -> list[dict]:
    for layout in layouts:  # warm-up (numba caches, lazy imports): untimed
        warm = generate_world(0, height=16, width=16, n_robots=3, n_targets=10, layout=layout)
        for name in pipelines:
            _pipeline(name).plan(warm, seed=0)
    rows = []
    for layout in layouts:
        for n in targets:
            r = max(3, n // 10) if robots is None else robots
            for w in range(n_worlds):
                t0 = time.perf_counter()
                world = generate_world(1000 + w, height=side, width=side, n_robots=r, n_targets=n, layout=layout)
                setup = time.perf_counter() - t0
                for name in pipelines:
                    pipe = _pipeline(name)
                    t0 = time.perf_counter()
                    plan = pipe.plan(world, seed=w)
                    wall = time.perf_counter() - t0
                    c = plan.compute
                    rows.append(dict(layout=layout, n_targets=n, n_robots=r, world=w, pipeline=name,
                                     success=bool(plan.success), cost=float(plan.route_cost) if plan.success else math.nan,
                                     wall_s=wall, setup_s=setup, calls=c.chip_calls + c.logical_calls,
                                     accel_j=c.accelerator_energy_j, failure=plan.failure,
                                     peak_mib=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024))
                    print(f"{layout:9s} N={n:3d} R={r:2d} world {w} {name:6s} ok={plan.success} "
                          f"cost={plan.route_cost:7.0f} {wall:6.2f} s calls={rows[-1]['calls']}", flush=True)
    return rows


def summarize(rows) -> list[dict]:
    out = []
    keys = sorted({(r["layout"], r["n_targets"], r["pipeline"]) for r in rows},
                  key=lambda k: (k[0], k[1], ORDER.index(k[2]) if k[2] in ORDER else 9))
    strong = {(r["layout"], r["n_targets"], r["world"]): r["cost"] for r in rows if r["pipeline"] == "strong"}
    for layout, n, name in keys:
        rs = [r for r in rows if (r["layout"], r["n_targets"], r["pipeline"]) == (layout, n, name)]
        ok = [r for r in rs if r["success"]]
        ratios = [r["cost"] / strong[(layout, n, r["world"])] for r in ok
                  if strong.get((layout, n, r["world"]), math.nan) > 0]
        out.append(dict(layout=layout, n_targets=n, n_robots=rs[0]["n_robots"], pipeline=name,
                        success=len(ok) / len(rs), cost=float(np.mean([r["cost"] for r in ok])) if ok else math.nan,
                        ratio=float(np.mean(ratios)) if ratios else math.nan,
                        wall_s=float(np.median([r["wall_s"] for r in rs])),
                        setup_s=float(np.median([r["setup_s"] for r in rs])),
                        calls=float(np.median([r["calls"] for r in rs])),
                        accel_j=float(np.median([r["accel_j"] for r in rs])),
                        peak_mib=float(max(r["peak_mib"] for r in rs))))
    return out


def plot(summary, path, side: int = 128) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(14, 4.2))
    styles = {"uniform": "-", "warehouse": "--"}
    colours = {"ising": "tab:blue", "ising-paper": "tab:purple", "strong": "tab:green", "fast": "tab:orange"}
    for (key, label, log), ax in zip((("ratio", "route cost / strong pipeline", False),
                                      ("wall_s", "wall seconds per plan", True),
                                      ("calls", "chip calls per plan (physical + logical)", True)), axes):
        for s in sorted({(x["layout"], x["pipeline"]) for x in summary}):
            pts = sorted((x["n_targets"], x[key]) for x in summary if (x["layout"], x["pipeline"]) == s)
            if key == "calls" and all(v == 0 for _, v in pts):
                continue
            ax.plot([p[0] for p in pts], [p[1] for p in pts], styles.get(s[0], "-"), marker="o",
                    color=colours.get(s[1]), label=f"{s[1]} ({s[0]})")
        ax.set_xscale("log")
        if log:
            ax.set_yscale("log")
        ax.set_xlabel("targets N (robots max(3, N/10))")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle(f"scaling on {side}x{side} maps: uniform (solid) and warehouse (dashed)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--targets", default="10,20,50,100,200,300")
    ap.add_argument("--layouts", default="uniform,warehouse")
    ap.add_argument("--pipelines", default="ising,ising-paper,strong,fast", help="pipeline presets")
    ap.add_argument("--side", type=int, default=128)
    ap.add_argument("--worlds", type=int, default=3)
    ap.add_argument("--robots", type=int, default=None, help="robots per world (default max(3, N // 10))")
    ap.add_argument("--figure", default="docs/scale.png")
    ap.add_argument("--write-results", action="store_true")
    args = ap.parse_args()
    rows = run(args.layouts.split(","), [int(n) for n in args.targets.split(",")], args.pipelines.split(","),
               args.side, args.worlds, args.robots)
    summary = summarize(rows)
    if args.figure:
        plot(summary, args.figure, args.side)
    suffix = "" if args.side == 128 else f", {args.side}x{args.side}"
    suffix += "" if args.robots is None else f", {args.robots} robots"
    lines = [SECTION + suffix, "",
             f"`python benchmarks/scale.py` on {cpu_name()}: {args.worlds} worlds per (map, N) of "
             f"{args.side}x{args.side}, " + ("R = max(3, N // 10)" if args.robots is None else f"R = {args.robots}")
             + " robots; mean route cost and its ratio to the strong "
             "pipeline on the same worlds, medians of wall seconds per plan (world set-up apart), chip calls "
             "(physical + projected logical) and accelerator energy; peak RSS = the benchmark process's "
             f"high-water mark so far (everything run before included). Figure: `{args.figure}`.", "",
             "| map | N | R | pipeline | success | mean cost | vs strong | wall s/plan | world set-up s | chip calls | accel energy | peak RSS |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for x in summary:
        lines.append(f"| {x['layout']} | {x['n_targets']} | {x['n_robots']} | {x['pipeline']} | "
                     f"{100 * x['success']:.0f} % | {x['cost']:.1f} | {x['ratio']:.3f} | {x['wall_s']:.3g} | "
                     f"{x['setup_s']:.3g} | {x['calls']:.0f} | {1e6 * x['accel_j']:.0f} uJ | {x['peak_mib']:.0f} MiB |")
    fails = [r for r in rows if not r["success"]]
    for r in fails[:10]:
        lines.append(f"\nFailed: {r['layout']} N={r['n_targets']} world {r['world']} {r['pipeline']}: {r['failure']}")
    finish(SECTION + suffix, lines, args.write_results)


if __name__ == "__main__":
    main()
