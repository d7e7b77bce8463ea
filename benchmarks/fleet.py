"""Fleet scale against the solver a user would pick: the pipelines beside PyVRP, same worlds, same run.

Points (issue 24): 64x64 with 10 robots and 100 targets, 128x128 with 20 robots and 300 targets,
each on ``uniform`` (20 % obstacles) and ``warehouse`` maps, ``--worlds`` worlds per point (world
seeds ``1000 ..``, planning seed = world index).  Methods: ``fast``, ``strong``, ``ising`` (this
package's defaults: the fleet search above 20 targets), ``ising-layers`` (the preset's chip sharing
and tour at any size), ``ising-paper`` (the paper's configuration), ``ising-fleet`` (chip-selected
moves between robots, :mod:`planners.ising.fleet`) with its default kicks (5 N, at least 1,500, at most 15 N) and with
exactly 2 N, 5 N and 15 N kicks (``ising-fleet@<k>x``), and
``pyvrp`` at time budgets of 0.05, 0.3 and 1 s (``--long`` adds 10 s).  Every method plans every
world once, one after the other, so all see the same machine load; the world's distance fields
are computed before any plans (both kinds of planner read them).  Per method and point: success,
mean route cost and its mean ratio to PyVRP at 1 s (0.3 s with ``--quick``) world by world,
medians of host seconds, chip calls (physical + projected logical), system latency (host + chip
time, calls one after another) and both energies (accelerator only, the paper's convention;
system = accelerator + host x 15 W).

Figures (``--figure-dir``, default ``docs``): ``fleet_<map>_<side>.png``, route cost against
system latency and against system energy (accelerator energy marked apart, hollow), the PyVRP
budgets joined as its cost-latency curve, and the ``ising-fleet`` kick budgets as its own.

    flock /tmp/mrmt-bench.lock nice -n 10 python benchmarks/fleet.py --long --write-results
    python benchmarks/fleet.py --quick            # 2 worlds, 64x64 only, budgets 0.05 and 0.3 s
"""

from __future__ import annotations

import argparse
import math
import resource

import numpy as np

from mrmt_env.generation import generate_world
from planners.pipeline import make_pipeline

try:
    from _common import cpu_name, finish  # run as a script: python benchmarks/<name>.py
except ImportError:  # imported as benchmarks.fleet
    from benchmarks._common import cpu_name, finish

SECTION = "## Fleet scale against PyVRP (issue 24)"
#: (side, robots, targets) of the issue's two fleet points, and of its fleet-size check (``--huge``).
POINTS = ((64, 10, 100), (128, 20, 300))
HUGE = ((256, 100, 1000),)
PRESETS = ("fast", "strong", "ising", "ising-layers", "ising-paper", "ising-fleet@2x", "ising-fleet@5x", "ising-fleet",
           "ising-fleet@15x")
BUDGETS = (0.05, 0.3, 1.0)
LONG_BUDGET = 10.0


def method_name(budget: float) -> str:
    return f"pyvrp@{budget:g}s"


def make_method(name: str):
    """The pipeline of a method name: a preset, ``pyvrp@<seconds>s``, ``ortools@<seconds>s``, ``ising-fleet@<k>x``
    (exactly ``k N`` kicks; the preset's default is 5 N, at least 1,500, at most 15 N), ``ising-fleet@greedy`` (host picks the moves) or
    ``ising-layers`` (preset ``ising``'s chip sharing and tour at any size)."""
    if name.startswith("pyvrp@"):
        return make_pipeline("pyvrp", sharing_options={"seconds": float(name[6:-1])})
    if name.startswith("ortools@"):  # the second classical peer (guided local search)
        return make_pipeline("ortools", sharing_options={"seconds": float(name[8:-1])})
    if name == "ising-layers":  # preset ising's own layers at every size (the preset: fleet search above 20 targets)
        return make_pipeline(sharing="ising", tour="ising", path="field")
    if name == "ising-fleet@greedy":  # the ablation: the host picks the moves, no chip call
        return make_pipeline("ising-fleet", sharing_options={"selection": "greedy"})
    if name.startswith("ising-fleet@"):
        return make_pipeline("ising-fleet", sharing_options={"kicks": None, "kicks_per_target": int(name[12:-1]),
                                                             "min_kicks": 0})
    return make_pipeline(name)


def run(points, layouts, methods, n_worlds: int) -> list[dict]:
    for side, r, n in points:  # warm-up: numba caches and the kernels' size classes, untimed
        for layout in layouts:
            warm = generate_world(999, height=side, width=side, n_robots=r, n_targets=n, layout=layout)
            for name in methods:
                (make_pipeline("pyvrp", sharing_options={"iterations": 50, "seconds": None})
                 if name.startswith("pyvrp@") else make_pipeline("ortools", sharing_options={"solutions": 5})
                 if name.startswith("ortools@") else make_method(name)).plan(warm, seed=0)
    rows = []
    for side, r, n in points:
        for layout in layouts:
            for w in range(n_worlds):
                world = generate_world(1000 + w, height=side, width=side, n_robots=r, n_targets=n, layout=layout)
                world.distance_matrix  # the fields every method reads, computed once before any plans
                for name in methods:
                    plan = make_method(name).plan(world, seed=w)
                    rec = plan.compute.to_record()
                    solver = plan.stats.get("solver", {})
                    fleet = plan.stats.get("fleet", {})
                    rows.append(dict(layout=layout, side=side, n_robots=r, n_targets=n, world=w, method=name,
                                     success=bool(plan.success),
                                     cost=float(plan.route_cost) if plan.success else math.nan,
                                     host_s=rec["host_cpu_s"], chip_s=rec["chip_time_s"],
                                     calls=rec["chip_calls"] + rec["logical_calls"], latency_s=rec["latency_s"],
                                     latency_parallel_s=rec["latency_parallel_s"],
                                     accel_j=rec["accelerator_energy_j"], system_j=rec["total_energy_j"],
                                     stopped_by=solver.get("stopped_by"), iterations=solver.get("iterations"),
                                     rounds=fleet.get("rounds", 0), contested=fleet.get("contested_rounds", 0),
                                     offered=fleet.get("offered", 0),
                                     failure=plan.failure,
                                     peak_mib=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024))
                    print(f"{layout:9s} {side}x{side} R={r} N={n} world {w} {name:12s} ok={plan.success} "
                          f"cost={plan.route_cost:6.0f} latency={rec['latency_s']:.3f} s calls={rows[-1]['calls']}",
                          flush=True)
    return rows


def summarize(rows, methods, reference: str) -> list[dict]:
    """Per (map, point, method) statistics; ``ratio`` is the mean cost ratio to ``reference`` world by world."""
    out = []
    ref = {(x["layout"], x["side"], x["world"]): x["cost"] for x in rows if x["method"] == reference}
    for key in dict.fromkeys((x["layout"], x["side"]) for x in rows):
        for name in methods:
            rs = [x for x in rows if (x["layout"], x["side"]) == key and x["method"] == name]
            if not rs:
                continue
            ok = [x for x in rs if x["success"]]
            ratios = [x["cost"] / ref[(*key, x["world"])] for x in ok if ref.get((*key, x["world"]), 0) > 0]

            def med(k):
                return float(np.median([x[k] for x in rs]))

            stops = sorted({x["stopped_by"] for x in rs if x["stopped_by"]})
            out.append(dict(layout=key[0], side=key[1], n_robots=rs[0]["n_robots"], n_targets=rs[0]["n_targets"],
                            method=name, worlds=len(rs), success=len(ok) / len(rs),
                            cost=float(np.mean([x["cost"] for x in ok])) if ok else math.nan,
                            ratio=float(np.mean(ratios)) if ratios else math.nan,
                            host_s=med("host_s"), chip_s=med("chip_s"), calls=med("calls"),
                            latency_s=med("latency_s"), accel_j=med("accel_j"), system_j=med("system_j"),
                            stopped_by="/".join(stops)))
    return out


def plot(summary, layout: str, side: int, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pts = [x for x in summary if (x["layout"], x["side"]) == (layout, side)]
    colours = {"fast": "tab:orange", "strong": "tab:green", "ising": "tab:blue", "ising-layers": "tab:gray",
               "ising-paper": "tab:purple"}
    colours.update({x["method"]: "tab:cyan" for x in pts if x["method"].startswith("ising-fleet")})
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, key, label in ((axes[0], "latency_s", "system latency per plan (s, host + chip)"),
                           (axes[1], "system_j", "energy per plan (J)")):
        for prefix, colour in (("pyvrp@", "tab:red"), ("ortools@", "tab:brown"), ("ising-fleet", "tab:cyan")):
            curve = sorted((x[key], x["cost"]) for x in pts if x["method"].startswith(prefix))
            if curve:
                ax.plot(*zip(*curve), "-", color=colour, alpha=0.6)
        for x in pts:
            colour = colours.get(x["method"], "tab:brown" if x["method"].startswith("ortools@") else "tab:red")
            ax.plot(x[key], x["cost"], "o", color=colour)
            ax.annotate(x["method"], (x[key], x["cost"]), fontsize=7, xytext=(4, 3), textcoords="offset points")
            if key == "system_j" and x["accel_j"] > 0:  # the paper's convention: the accelerator alone
                ax.plot(x["accel_j"], x["cost"], "o", mfc="none", color=colour)
                ax.plot([x["accel_j"], x["system_j"]], [x["cost"], x["cost"]], ":", color=colour, lw=0.8)
        ax.set_xscale("log")
        ax.set_xlabel(label + ("; hollow: accelerator only" if key == "system_j" else ""))
        ax.set_ylabel("mean route cost")
        ax.grid(alpha=0.3)
    n = pts[0]
    fig.suptitle(f"{layout} {side}x{side}, {n['n_robots']} robots, {n['n_targets']} targets "
                 f"({n['worlds']} worlds): lower left is better", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def table(summary, reference: str) -> list[str]:
    lines = [f"| map | grid, R, N | method | success | mean cost | vs {reference} | host s | chip calls | "
             "latency s (host + chip) | accel energy | system energy | stopped by |",
             "|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|---|"]
    for x in summary:
        lines.append(f"| {x['layout']} | {x['side']}x{x['side']}, {x['n_robots']}, {x['n_targets']} | {x['method']} | "
                     f"{100 * x['success']:.0f} % | {x['cost']:.1f} | {x['ratio']:.3f} | {x['host_s']:.3g} | "
                     f"{x['calls']:.0f} | {x['latency_s']:.3g} | {1e6 * x['accel_j']:.0f} uJ | "
                     f"{x['system_j']:.3g} J | {x['stopped_by'] or '-'} |")
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", type=int, default=None, help="worlds per point and map (default 5; 1 with --huge)")
    ap.add_argument("--layouts", default="uniform,warehouse")
    ap.add_argument("--long", action="store_true", help=f"add PyVRP at {LONG_BUDGET:g} s (long)")
    ap.add_argument("--huge", action="store_true",
                    help="the issue's fleet-size check instead: 100 robots x 1,000 targets on a 256x256 warehouse "
                         "(strong, ising, ising-fleet, pyvrp@1s; --worlds default 1; peak RSS reported)")
    ap.add_argument("--quick", action="store_true", help="2 worlds, 64x64 only, PyVRP at 0.05 and 0.3 s (a check)")
    ap.add_argument("--methods", default=None,
                    help="comma-separated subset of methods (e.g. ising-fleet,ising-fleet@greedy,pyvrp@1s); "
                         "its section is headed with --label")
    ap.add_argument("--label", default=None, help="suffix of the RESULTS.md section heading (with --methods)")
    ap.add_argument("--figure-dir", default="docs", help="where fleet_<map>_<side>.png go ('' for none)")
    ap.add_argument("--write-results", action="store_true", help="replace the section in benchmarks/RESULTS.md")
    args = ap.parse_args()
    if args.worlds is None:
        args.worlds = 1 if args.huge else 5
    if args.worlds < 1:
        ap.error(f"--worlds must be >= 1, got {args.worlds}")
    points, budgets, n_worlds = POINTS, BUDGETS + ((LONG_BUDGET,) if args.long else ()), args.worlds
    if args.quick:
        points, budgets, n_worlds = POINTS[:1], BUDGETS[:2], min(args.worlds, 2)
    methods = PRESETS + tuple(method_name(b) for b in budgets) + ("ortools@1s",)
    reference = method_name(max(b for b in budgets if b <= 1.0))  # PyVRP at 1 s (0.3 s with --quick)
    section = SECTION
    if args.methods:
        methods = tuple(m.strip() for m in args.methods.split(",") if m.strip())
        section = f"{SECTION}, {args.label or 'selected methods'}"
        args.figure_dir = ""
    layouts = args.layouts.split(",")
    if args.huge:
        points, layouts, methods = HUGE, ["warehouse"], ("strong", "ising", "ising-layers", "pyvrp@1s")
        section, reference, args.figure_dir = f"{SECTION}, 100 robots x 1,000 targets", "pyvrp@1s", ""
    rows = run(points, layouts, methods, n_worlds)
    summary = summarize(rows, methods, reference)
    figures = []
    if args.figure_dir:
        for layout in layouts:
            for side, _, _ in points:
                path = f"{args.figure_dir}/fleet_{layout}_{side}.png"
                plot(summary, layout, side, path)
                figures.append(f"`{path}`")
    lines = [section, "",
             f"`python benchmarks/fleet.py{' --long' if args.long else ''}{' --quick' if args.quick else ''}"
             f"{' --huge' if args.huge else ''}"
             f"{f' --methods {args.methods}' if args.methods else ''} "
             f"--worlds {n_worlds}` on {cpu_name()} (2 cores, shared; every method on every world in the same "
             f"run): {n_worlds} worlds per point (seeds 1000..), mean route cost and its mean ratio to "
             f"{reference} world by world, medians of host seconds, chip calls (physical + projected logical), "
             "system latency "
             "(host + chip time, calls one after another) and energies (accelerator: the paper's convention; "
             "system: accelerator + host x 15 W). PyVRP runs on one thread for its whole time budget "
             f"(`stopped by`). Figures: {', '.join(figures) or 'none'}.", ""] + table(summary, reference)
    for key in dict.fromkeys((x["layout"], x["side"]) for x in rows):
        rs = [x for x in rows if (x["layout"], x["side"]) == key and x["method"] == "ising-fleet"]
        if rs and sum(x["rounds"] for x in rs):
            rounds = sum(x["rounds"] for x in rs)
            lines.append(f"\n`ising-fleet` on {key[0]} {key[1]}x{key[1]}: {rounds / len(rs):.0f} chip rounds per plan, "
                         f"{sum(x['offered'] for x in rs) / rounds:.1f} moves offered per round, "
                         f"{100 * sum(x['contested'] for x in rs) / rounds:.0f} % of rounds with clashing moves "
                         "(the chip's choice is not simply all of them).")
    if args.huge:
        lines.append("\nSystem latency per plan (host + chip) and the process's peak RSS after each plan (the "
                     "world's BFS fields, about 290 MiB, and the warm-up world's included): "
                     + "; ".join(f"{x['method']} {x['latency_s']:.1f} s, {x['peak_mib']:.0f} MiB" for x in rows) + ".")
    fails = [x for x in rows if not x["success"]]
    for x in fails[:10]:
        lines.append(f"\nFailed: {x['layout']} {x['side']} world {x['world']} {x['method']}: {x['failure']}")
    finish(section, lines, args.write_results)


if __name__ == "__main__":
    main()
