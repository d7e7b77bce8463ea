"""Planning quality against the exact optimum: the ``ising`` defaults beside the paper's configuration.

On worlds no test or tuning run used (seeds from ``--seed``, default 10000), every layer and the
whole pipeline are scored against the optimum, which is cheap at the paper's size (BFS paths,
Held-Karp tours, exact min-sum sharing):

* paths: ``--queries`` single-target queries (1 robot, 1 target): share of optimal (BFS-length)
  paths and median chip calls;
* tours: ``--worlds`` worlds of 1 robot x 10 targets: valid tours, gap to Held-Karp;
  ``ising`` runs on the physical chip (move selection), ``ising-paper`` on the logical solver,
  ``chip-onehot`` is the paper's one-hot programs quantized for the physical chip;
* sharing: 3 robots x 10 targets, every robot's targets toured exactly, gap to exact sharing;
* end to end: 3 robots x 10 targets, validated plans, gap of the route cost to the ``exact``
  pipeline.

Gaps are reported as distributions (mean, median, p90, max, share at the optimum), sharing and
end to end for both placements (uniform, centre).  Chip calls: physical + projected logical.

    flock /tmp/mrmt-bench.lock python benchmarks/quality_exact.py --write-results
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from mrmt_env.generation import generate_world
from planners import registry
from planners.pipeline import make_pipeline
from planners.tours_classical import BruteTour, exact_route_cost

try:
    from _common import cpu_name, finish  # run as a script: python benchmarks/<name>.py
except ImportError:  # imported as benchmarks.quality_exact
    from benchmarks._common import cpu_name, finish

SECTION = "## Planning quality against the exact optimum (issue 13)"


def gap_stats(gaps) -> dict:
    """Mean, median, p90, max (%) and the share at the optimum of relative gaps (fractions; NaN = failed)."""
    g = 100.0 * np.asarray(gaps, dtype=float)
    ok = g[np.isfinite(g)]
    if ok.size == 0:
        return {"n": len(g), "ok": 0, "gaps": g}
    return {"n": len(g), "ok": int(ok.size), "gaps": g, "mean": float(ok.mean()), "median": float(np.median(ok)),
            "p90": float(np.percentile(ok, 90)), "max": float(ok.max()), "at_opt": float((ok <= 1e-9).mean())}


def _calls(compute) -> int:
    return int(compute.chip_calls + compute.logical_calls)


def paths(n: int, seed: int) -> dict:
    out = {}
    for name in ("ising-paper", "ising"):
        solver = registry.create("path", name)
        optimal, calls = 0, []
        for i in range(n):
            w = generate_world(seed + i, n_robots=1, n_targets=1)
            best = int(w.robot_fields[0][tuple(w.targets[0])])
            res = solver.find_path(w, w.robots[0], w.targets[0], np.random.default_rng(seed + i))
            optimal += bool(res.success and res.length == best)
            calls.append(_calls(res.compute))
        out[name] = {"optimal": optimal, "n": n, "calls": float(np.median(calls))}
    return out


TOUR_METHODS = {"ising": ("ising", {}), "ising-paper": ("ising-paper", {}),
                "chip-onehot": ("ising", {"backend": "chip-onehot"}), "2opt": ("2opt", {}), "3opt": ("3opt", {})}


def tours(n: int, seed: int) -> dict:
    dists = [generate_world(seed + i, n_robots=1, n_targets=10).distance_matrix for i in range(n)]
    opt = [BruteTour().solve(d).cost for d in dists]
    out = {}
    for label, (name, options) in TOUR_METHODS.items():
        solver = registry.create("tour", name, options)
        gaps, calls, host, valid, clean, reads = [], [], [], 0, 0, 0
        for i, d in enumerate(dists):
            t0 = time.perf_counter()
            r = solver.solve(d, np.random.default_rng(seed + i))
            host.append(time.perf_counter() - t0 - r.compute.emulation_s)
            ok = r.failure is None and sorted(r.order) == list(range(1, 11))
            valid += ok
            gaps.append(r.cost / opt[i] - 1 if ok else np.nan)
            calls.append(_calls(r.compute))
            m = r.stats.get("mapping", {}).get("tour", {})
            clean += m.get("valid_reads", 0)
            reads += m.get("reads", 0)
        out[label] = {**gap_stats(gaps), "valid": valid, "calls": float(np.median(calls)),
                      "host_ms": 1e3 * float(np.median(host)), "valid_reads": (clean, reads)}
    return out


def sharing(n: int, seed: int, placement: str) -> dict:
    worlds = [generate_world(seed + i, n_robots=3, n_targets=10, placement=placement) for i in range(n)]
    totals, calls = {}, {}
    for name in ("exact", "ising", "ising-paper", "ssa"):
        solver = registry.create("sharing", name)
        totals[name], calls[name] = [], []
        for i, w in enumerate(worlds):
            d = w.distance_matrix
            res = solver.assign(d, 3, registry.create("tour", "brute"), np.random.default_rng(seed + i))
            ok = res.failure is None and sorted(t for g in res.assignment for t in g) == list(range(10))
            totals[name].append(sum(exact_route_cost(d, [k] + [3 + t for t in g]) if g else 0.0
                                    for k, g in enumerate(res.assignment)) if ok else np.nan)
            calls[name].append(_calls(res.compute))
    ex = np.array(totals["exact"])
    return {name: {**gap_stats(np.array(v) / ex - 1), "calls": float(np.median(calls[name]))}
            for name, v in totals.items()}


E2E = ("exact", "ising", "ising-paper", "strong", "fast")
#: the strongest classical peer, stopped by iterations (deterministic), when the `peers` extra is installed
PYVRP = "pyvrp@1000it"


def _e2e_pipelines() -> dict:
    pipes = {name: (lambda name=name: make_pipeline(name)) for name in E2E}
    try:
        import pyvrp  # noqa: F401
    except ImportError:
        print(f"{PYVRP} left out: pip install 'mrmt-ising[peers]'")
    else:
        pipes[PYVRP] = lambda: make_pipeline("pyvrp", sharing_options={"seconds": None, "iterations": 1000})
    return pipes


def endtoend(n: int, seed: int, placement: str) -> dict:
    worlds = [generate_world(seed + i, n_robots=3, n_targets=10, placement=placement) for i in range(n)]
    out, cost = {}, {}
    pipes = _e2e_pipelines()
    for name, make in pipes.items():
        pipe = make()
        pipe.plan(worlds[0], seed=0)  # warm (numba caches, lazy imports)
        cost[name], calls, energy, host = [], [], [], []
        for i, w in enumerate(worlds):
            t0 = time.perf_counter()
            p = pipe.plan(w, seed=seed + i)
            host.append(time.perf_counter() - t0 - p.compute.emulation_s)
            cost[name].append(p.route_cost if p.success else np.nan)
            calls.append(_calls(p.compute))
            energy.append(p.compute.accelerator_energy_j)
        out[name] = {"calls": float(np.median(calls)), "energy_uj": 1e6 * float(np.median(energy)),
                     "host_ms": 1e3 * float(np.median(host))}
    ex = np.array(cost["exact"], dtype=float)
    for name in pipes:
        out[name].update(gap_stats(np.array(cost[name], dtype=float) / ex - 1))
    return out


def _f(v, nd=2) -> str:
    return "-" if v is None or (isinstance(v, float) and not np.isfinite(v)) else f"{v:.{nd}f}"


def _gap_row(label, s, extra=()) -> str:
    if not s.get("ok"):
        return f"| {label} | {s.get('ok', 0)}/{s['n']} | - | - | - | - | - |" + "".join(f" {e} |" for e in extra)
    return (f"| {label} | {s['ok']}/{s['n']} | {_f(s['mean'])} | {_f(s['median'])} | {_f(s['p90'])} | "
            f"{_f(s['max'], 1)} | {100 * s['at_opt']:.0f} % |" + "".join(f" {e} |" for e in extra))


def render(res: dict, args, seconds: float) -> list[str]:
    lines = [SECTION, "",
             f"`python benchmarks/quality_exact.py --worlds {args.worlds} --queries {args.queries} --seed {args.seed}` "
             f"on {cpu_name()} ({seconds:.0f} s).  Worlds of seeds {args.seed}.. (used by no test or tuning "
             "run); gaps in % to the optimum, as distributions; chip calls = physical + projected logical, "
             "medians.  `ising` = this package's defaults, `ising-paper` = the paper's configuration "
             "(what `mrmt reproduce` runs).", ""]
    p = res["paths"]
    lines += ["### Paths: single-target queries", "",
              "| method | optimal paths | median chip calls |", "|---|---:|---:|"]
    for name, s in p.items():
        lines.append(f"| {name} | {s['optimal']}/{s['n']} ({100 * s['optimal'] / s['n']:.1f} %) | {_f(s['calls'], 0)} |")
    lines += ["", "### Tours: 1 robot x 10 targets, gap to Held-Karp", "",
              "| method | valid | mean | median | p90 | max | at optimum | median calls | valid reads | median host ms |",
              "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for name, s in res["tours"].items():
        c, r = s["valid_reads"]
        vr = f"{c}/{r}" if r else "-"
        lines.append(_gap_row(name, s, (_f(s["calls"], 0), vr, _f(s["host_ms"], 2))).replace(
            f"| {s.get('ok', 0)}/{s['n']} |", f"| {s['valid']}/{s['n']} |", 1))
    for placement in args.placements:
        lines += ["", f"### Sharing: 3 robots x 10 targets, {placement} placement, gap to exact sharing", "",
                  "| method | success | mean | median | p90 | max | at optimum | median calls |",
                  "|---|---:|---:|---:|---:|---:|---:|---:|"]
        for name, s in res[f"sharing-{placement}"].items():
            lines.append(_gap_row(name, s, (_f(s["calls"], 0),)))
    for placement in args.placements:
        lines += ["", f"### End to end: 3 robots x 10 targets, {placement} placement, gap to the exact pipeline", "",
                  "| pipeline | success | mean | median | p90 | max | at optimum | median calls | median accel. energy uJ | median host ms |",
                  "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
        for name, s in res[f"e2e-{placement}"].items():
            lines.append(_gap_row(name, s, (_f(s["calls"], 0), _f(s["energy_uj"], 1), _f(s["host_ms"], 2))))
    return lines


PANELS = (("tours", "tour, 1 robot x 10 targets", ("ising", "ising-paper", "3opt", "2opt")),
          ("sharing-{p}", "sharing, 3 x 10, {p}", ("ising", "ising-paper", "ssa")),
          ("e2e-{p}", "end to end, 3 x 10, {p}", ("ising", "ising-paper", "strong", "fast")))
COLOURS = {"ising": "tab:blue", "ising-paper": "tab:purple", "3opt": "tab:green", "strong": "tab:green",
           "ssa": "tab:green", "2opt": "tab:orange", "fast": "tab:orange"}


def plot(res: dict, path: str, placement: str) -> None:
    """Empirical distribution of the gap to the optimum, one panel per layer."""
    from pathlib import Path

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8), sharey=True)
    for ax, (key, title, methods) in zip(axes, PANELS):
        data = res[key.format(p=placement)]
        for m in methods:
            g = np.sort(data[m]["gaps"][np.isfinite(data[m]["gaps"])])
            if not g.size:
                continue
            y = np.arange(1, g.size + 1) / data[m]["n"]
            ax.step(np.concatenate([[0.0], g]), np.concatenate([[0.0], y]), where="post", color=COLOURS.get(m),
                    label=f"{m} (mean {data[m]['mean']:.2f} %)")
        ax.set_xscale("symlog", linthresh=1.0)
        ax.set_xlabel("gap to the optimum (%)")
        ax.set_title(title.format(p=placement), fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    axes[0].set_ylabel("share of worlds with at most this gap")
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--worlds", type=int, default=200, help="worlds per tour / sharing / end-to-end table")
    ap.add_argument("--queries", type=int, default=200, help="single-target path queries")
    ap.add_argument("--seed", type=int, default=10000, help="first world seed")
    ap.add_argument("--placements", default="uniform,centre", help="target placements of the sharing and end-to-end tables")
    ap.add_argument("--figure", default="docs/quality/gaps.png", help="gap distribution figure ('' for none)")
    ap.add_argument("--write-results", action="store_true", help="write the section into benchmarks/RESULTS.md")
    args = ap.parse_args(argv)
    for name in ("worlds", "queries"):
        if getattr(args, name) < 1:
            ap.error(f"--{name} = {getattr(args, name)} must be >= 1")
    args.placements = [p for p in args.placements.split(",") if p]
    bad = [p for p in args.placements if p not in ("uniform", "centre")]
    if bad or not args.placements:
        ap.error(f"--placements {args.placements!r}: each must be uniform or centre")
    t0 = time.perf_counter()
    res = {"paths": paths(args.queries, args.seed), "tours": tours(args.worlds, args.seed)}
    for placement in args.placements:
        res[f"sharing-{placement}"] = sharing(args.worlds, args.seed, placement)
        res[f"e2e-{placement}"] = endtoend(args.worlds, args.seed, placement)
    lines = render(res, args, time.perf_counter() - t0)
    if args.figure:
        plot(res, args.figure, args.placements[0])
        lines += ["", f"Figure: `{args.figure}` (share of worlds within each gap, per layer).", ""]
    finish(SECTION, lines, args.write_results)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
