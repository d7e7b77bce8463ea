"""Quality and CPU time of the classical baselines, side by side with the paper (section 6.2).

Worlds: ``generate_world(seed)`` for seeds ``0 .. N-1`` (default 100): 10x10 grid,
exactly 20 obstacles, robots and targets on distinct cells of one connected
component, BFS distances.  Both robot placements are run (``uniform`` and the
paper-like ``centre``; see :mod:`mrmt_env.generation`).

* **Pathfinding**: 10 x N single-target worlds ``generate_world(seed,
  n_robots=1, n_targets=1)`` (1000 queries robot -> target): median path
  length and CPU time of BFS, A*, GBFS (paper: median length 6.0 for all, A* 35 us).
* **Tour** (1 robot, 10 targets): optimality gap of NN, 2-opt, 3-opt against
  ``brute`` (Held-Karp exact), mean and median (paper: 11.61 / 4.62 / 1.31 %
  mean gap, 0.0 % median for 3-opt), plus the non-default variants (2-opt with a
  free end, 3-opt with all 7 moves).
* **Sharing** (3 robots, 10 targets): every robot's assigned targets are
  ordered by ``brute`` (exact tours), so only the sharing decision differs
  between methods; median total route cost, makespan, imbalance and median gap
  to ``exact`` (the min-sum optimum) for round robin, PSA, SSA (insertion bids,
  the default; and marginal-tour bids priced by ``brute``), exact (paper SSA:
  28.0 / 16.0 / 14.0).
* **End to end** (3 robots, 10 targets): the ``fast`` and ``strong`` pipelines
  and ``exact+brute+astar``: median total and makespan and the median CPU time
  of one ``Pipeline.plan`` call (paper: fast 45.0 / 0.99 ms / 14.8 mJ, strong
  28.0 / 27 ms / 399 mJ).
* **Sampling noise**: the tour gaps and SSA medians on ``--noise-blocks``
  disjoint blocks of 100 worlds, to show whether a difference from the paper
  is larger than the spread between 100-world samples.

CPU time: each call is timed with ``time.perf_counter`` (wall seconds, one
core, after a warm-up call so numba compilation is excluded), the best of
``--repeats`` (default 3) per instance to damp interference from other jobs on
the shared machine; the table gives the median over instances, and the energy
proxy is that time x 15 W (paper 6.1).

    flock /tmp/mrmt-bench.lock python benchmarks/quality_classical.py --write-results
"""

from __future__ import annotations

import argparse
import platform
import time
from pathlib import Path

import numpy as np

from mrmt_env import generate_world
from planners.compute import CPU_WATTS_PER_CORE
from planners.paths_classical import AStarPath, BFSPath, GreedyBestFirstPath
from planners.pipeline import make_pipeline
from planners.sharing_classical import ExactSharing, PSASharing, RoundRobinSharing, SSASharing
from planners.tours_classical import BruteTour, NearestNeighbourTour, ThreeOptTour, TwoOptTour

try:
    from _common import cpu_name, write_results_section  # run as a script: python benchmarks/<name>.py
except ImportError:  # imported as benchmarks.<name>
    from benchmarks._common import cpu_name, write_results_section

RESULTS = Path(__file__).with_name("RESULTS.md")
SECTION = "## Issue 4: classical planners"
PLACEMENTS = ("uniform", "centre")


def timed(fn, repeats: int):
    """(result of the last call, best wall seconds over ``repeats`` calls)."""
    best = np.inf
    out = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return out, best


def bench_paths(n_worlds, repeats, placement):
    planners = {"BFS": BFSPath(), "A*": AStarPath(), "GBFS": GreedyBestFirstPath()}
    lengths = {k: [] for k in planners}
    times = {k: [] for k in planners}
    for seed in range(10 * n_worlds):
        world = generate_world(seed, n_robots=1, n_targets=1, placement=placement)
        a, b = world.robots[0], world.targets[0]
        if True:
            for name, p in planners.items():
                res, t = timed(lambda: p.find_path(world, a, b), repeats)
                lengths[name].append(res.length)
                times[name].append(t)
    return {k: (np.median(lengths[k]), np.mean(lengths[k]), np.median(times[k])) for k in planners}


def bench_tours(n_worlds, repeats, placement):
    solvers = {
        "nearest neighbour (`nn`)": NearestNeighbourTour(),
        "2-opt (`2opt`, default)": TwoOptTour(),
        "2-opt, free end": TwoOptTour(free_end=True),
        "3-opt, 4 moves (`3opt`, default)": ThreeOptTour("4"),
        "3-opt, 7 moves": ThreeOptTour("7"),
        "exact (`brute`, Held-Karp)": BruteTour(),
    }
    gaps = {k: [] for k in solvers}
    times = {k: [] for k in solvers}
    for seed in range(n_worlds):
        world = generate_world(seed, n_robots=1, n_targets=10, placement=placement)
        d = world.distance_matrix
        results = {}
        for name, s in solvers.items():
            results[name], t = timed(lambda: s.solve(d), repeats)
            times[name].append(t)
        opt = results["exact (`brute`, Held-Karp)"].cost
        for name, res in results.items():
            gaps[name].append(100.0 * (res.cost - opt) / opt)
    return {k: (np.mean(gaps[k]), np.median(gaps[k]), np.median(times[k])) for k in solvers}


def bench_sharing(n_worlds, repeats, placement):
    brute = BruteTour()
    methods = {
        "round robin (`round_robin`)": RoundRobinSharing(),
        "PSA (`psa`)": PSASharing(),
        "SSA, insertion bids (`ssa`, default)": SSASharing(),
        "SSA, marginal exact-tour bids": SSASharing(bid="tour"),
        "exact min-sum (`exact`)": ExactSharing(),
    }
    rows = {k: [] for k in methods}
    for seed in range(n_worlds):
        world = generate_world(seed, n_robots=3, n_targets=10, placement=placement)
        d = world.distance_matrix
        per = {}
        for name, m in methods.items():
            res, t = timed(lambda: m.assign(d, 3, brute), repeats)
            lens = []
            for k, group in enumerate(res.assignment):
                idx = [k] + [3 + x for x in group]
                lens.append(brute.solve(d[np.ix_(idx, idx)]).cost)
            per[name] = (sum(lens), max(lens), max(lens) - min(lens), t)
        opt = per["exact min-sum (`exact`)"][0]
        for name, (tot, mk, imb, t) in per.items():
            rows[name].append((tot, mk, imb, 100.0 * (tot - opt) / opt, t))
    out = {}
    for name, r in rows.items():
        a = np.array(r)
        out[name] = (np.median(a[:, 0]), np.median(a[:, 1]), np.median(a[:, 2]), np.median(a[:, 3]),
                     np.mean(a[:, 0]), np.median(a[:, 4]))
    return out


def bench_pipelines(n_worlds, repeats, placement):
    pipes = {
        "`fast` (psa+nn+astar)": make_pipeline("fast"),
        "`strong` (ssa+3opt+astar)": make_pipeline("strong"),
        "exact+brute+astar": make_pipeline(sharing="exact", tour="brute", path="astar"),
    }
    rows = {k: [] for k in pipes}
    for seed in range(n_worlds):
        world = generate_world(seed, n_robots=3, n_targets=10, placement=placement)
        _ = world.distance_matrix  # computed once per world, as a loaded world would
        for name, p in pipes.items():
            best = np.inf
            plan = None
            for _ in range(repeats):
                plan = p.plan(world, seed=seed)
                best = min(best, plan.compute.cpu_s)
            assert plan.success
            rows[name].append((plan.route_cost, plan.makespan, plan.imbalance, best))
    return {k: tuple(np.median(np.array(v), axis=0)) for k, v in rows.items()}


def bench_noise(blocks, placement):
    """Key statistics on ``blocks`` disjoint blocks of 100 worlds (sampling noise of a 100-world sample)."""
    brute, tours = BruteTour(), {"nn": NearestNeighbourTour(), "2opt": TwoOptTour(), "3opt": ThreeOptTour()}
    ssa = SSASharing()
    out = {k: [] for k in ("nn", "2opt", "3opt", "ssa_total", "ssa_makespan", "ssa_imbalance")}
    for b in range(blocks):
        gaps = {k: [] for k in tours}
        shares = []
        for seed in range(100 * b, 100 * (b + 1)):
            d = generate_world(seed, n_robots=1, n_targets=10, placement=placement).distance_matrix
            opt = brute.solve(d).cost
            for k, t in tours.items():
                gaps[k].append(100.0 * (t.solve(d).cost - opt) / opt)
            d = generate_world(seed, n_robots=3, n_targets=10, placement=placement).distance_matrix
            lens = []
            for k, group in enumerate(ssa.assign(d, 3).assignment):
                idx = [k] + [3 + x for x in group]
                lens.append(brute.solve(d[np.ix_(idx, idx)]).cost)
            shares.append((sum(lens), max(lens), max(lens) - min(lens)))
        for k in tours:
            out[k].append(np.mean(gaps[k]))
        a = np.array(shares)
        out["ssa_total"].append(np.median(a[:, 0]))
        out["ssa_makespan"].append(np.median(a[:, 1]))
        out["ssa_imbalance"].append(np.median(a[:, 2]))
    return out


def _us(s):
    return f"{s * 1e6:,.1f} us"


def _uj(s):
    return f"{s * CPU_WATTS_PER_CORE * 1e6:,.0f} uJ"


def render(n_worlds, repeats, res) -> str:
    cpu = cpu_name()
    L = [
        SECTION,
        "",
        f"`benchmarks/quality_classical.py` ({time.strftime('%Y-%m-%d', time.gmtime())}; {cpu}; Python "
        f"{platform.python_version()}; {n_worlds} worlds `generate_world(seed)` per setting, seeds 0..{n_worlds - 1}: "
        "10x10, exactly 20 obstacles, one connected component, distinct cells, BFS distances). "
        f"CPU time = best of {repeats} calls per instance (numba compiled beforehand), median over instances; "
        "energy proxy = CPU time x 15 W. The 2 cores are shared with other jobs, so times are indicative.",
        "",
    ]
    paper_paths = {"BFS": "6.0", "A*": "6.0 (35 us, 523 uJ)", "GBFS": "6.0"}
    for placement in PLACEMENTS:
        L += [f"### Pathfinding, {placement} placement ({10 * n_worlds} single-target worlds)", "",
              "| method | median length | mean length | median CPU | energy | paper median length |",
              "|---|---:|---:|---:|---:|---|"]
        for name, (med, mean, t) in res["paths", placement].items():
            L.append(f"| {name} | {med:.1f} | {mean:.2f} | {_us(t)} | {_uj(t)} | {paper_paths[name]} |")
        L.append("")
    paper_tour = {"nearest neighbour (`nn`)": "11.61", "2-opt (`2opt`, default)": "4.62",
                  "3-opt, 4 moves (`3opt`, default)": "1.31 (median 0.0)", "exact (`brute`, Held-Karp)": "0"}
    for placement in PLACEMENTS:
        L += [f"### Tour construction, 1 robot x 10 targets, {placement} placement", "",
              "| method | mean gap % | median gap % | median CPU | energy | paper mean gap % |",
              "|---|---:|---:|---:|---:|---|"]
        for name, (mean, med, t) in res["tours", placement].items():
            L.append(f"| {name} | {mean:.2f} | {med:.2f} | {_us(t)} | {_uj(t)} | {paper_tour.get(name, '-')} |")
        L.append("")
    for placement in PLACEMENTS:
        L += [f"### Target sharing, 3 robots x 10 targets, {placement} placement (tours by `brute`)", "",
              "| method | median total | median makespan | median imbalance | median gap to exact % | mean total "
              "| median CPU | energy |",
              "|---|---:|---:|---:|---:|---:|---:|---:|"]
        for name, (tot, mk, imb, gap, mean, t) in res["sharing", placement].items():
            L.append(f"| {name} | {tot:.1f} | {mk:.1f} | {imb:.1f} | {gap:.2f} | {mean:.2f} | {_us(t)} | {_uj(t)} |")
        L.append("| paper SSA | 28.0 | 16.0 | 14.0 | 0.0 (vs best observed) | | | 73 mJ |")
        L.append("")
    for placement in PLACEMENTS:
        L += [f"### End-to-end pipelines, 3 robots x 10 targets, {placement} placement", "",
              "| pipeline | median total | median makespan | median imbalance | median CPU (plan call) | energy |",
              "|---|---:|---:|---:|---:|---:|"]
        for name, (tot, mk, imb, t) in res["pipes", placement].items():
            L.append(f"| {name} | {tot:.1f} | {mk:.1f} | {imb:.1f} | {_us(t)} | {_uj(t)} |")
        L.append("| paper fast / strong | 45.0 / 28.0 | | | 0.99 ms / 27 ms | 14.8 mJ / 399 mJ |")
        L.append("")
    nb = len(res["noise", "uniform"]["nn"])
    L += [f"### Sampling noise: the same statistics on {nb} disjoint blocks of 100 worlds (seeds 0..{100 * nb - 1})",
          "",
          "| statistic | paper | uniform: min .. median .. max over blocks | centre: min .. median .. max |",
          "|---|---:|---|---|"]
    paper = {"nn": "11.61", "2opt": "4.62", "3opt": "1.31", "ssa_total": "28.0", "ssa_makespan": "16.0",
             "ssa_imbalance": "14.0"}
    label = {"nn": "NN mean gap %", "2opt": "2-opt mean gap %", "3opt": "3-opt (4 moves) mean gap %",
             "ssa_total": "SSA median total (brute tours)", "ssa_makespan": "SSA median makespan",
             "ssa_imbalance": "SSA median imbalance"}
    for key in paper:
        cells = []
        for placement in PLACEMENTS:
            v = np.array(res["noise", placement][key])
            cells.append(f"{v.min():.2f} .. {np.median(v):.2f} .. {v.max():.2f}")
        L.append(f"| {label[key]} | {paper[key]} | {cells[0]} | {cells[1]} |")
    L.append("")
    L += [
        "Notes. Tours: 2-opt and 3-opt start from the nearest-neighbour route; the defaults are the common textbook "
        "variants (2-opt reversals keep both route ends; 3-opt = reverse B, reverse C, reverse BC, swap B and C, "
        "first improvement, segments of one node or more), which is what reproduces the paper's gaps; the stronger "
        "variants are options (`TwoOptTour(free_end=True)`, `ThreeOptTour(moves=\"7\")`). "
        "Sharing: the paper does not say how its SSA tours were built; here every method's bundles are ordered "
        "exactly so the table isolates the allocation. `exact` is the min-sum optimum (subset DP), so its gap column "
        "is the true optimality gap of each method. The paper's 45.0 for the fast pipeline is not reproduced "
        f"(PSA + NN + A* gives a median of {res['pipes', 'uniform']['`fast` (psa+nn+astar)'][0]:.1f} (uniform) / "
        f"{res['pipes', 'centre']['`fast` (psa+nn+astar)'][0]:.1f} (centre) here): the paper's PSA or NN must "
        "differ in a way it does not describe. "
        "Paths: the paper's median length 6.0 is for a query distribution it does not describe; ours (robot start "
        "to target of a generated world) has median 7. "
        "SSA: the median total matches the paper in both placements; with `centre` placement the median makespan "
        "and imbalance fall below the paper's 16 / 14 (see the noise table), with `uniform` they bracket them. "
        "(The first author's course project draws 19 obstacles for its centre placement; `generate_world` draws "
        "exactly 20 for both.) "
        "Energies: the paper's CPU energies come from a Python implementation timed per call; ours are numba "
        "kernels with little Python overhead, so every Ising-vs-classical energy ratio computed against these "
        "baselines is smaller (harder to win) than the paper's.",
        "",
        "Reproduce: `flock /tmp/mrmt-bench.lock python benchmarks/quality_classical.py --write-results`",
        "",
    ]
    return "\n".join(L)


def write_section(block: str) -> None:
    write_results_section(SECTION, block, RESULTS)
    print(f"wrote section {SECTION!r} of {RESULTS}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--worlds", type=int, default=100, help="worlds per setting (default 100)")
    ap.add_argument("--repeats", type=int, default=3, help="timed calls per instance, best kept (default 3)")
    ap.add_argument("--noise-blocks", type=int, default=10, help="blocks of 100 worlds for the noise table (10)")
    ap.add_argument("--write-results", action="store_true", help="update benchmarks/RESULTS.md")
    args = ap.parse_args()
    # warm-up: compile / load every numba kernel outside the timed calls
    w = generate_world(0, n_robots=3, n_targets=10)
    for pre in ("fast", "strong"):
        make_pipeline(pre).plan(w)
    bench_sharing(2, 1, "uniform")
    bench_tours(2, 1, "uniform")
    bench_paths(2, 1, "uniform")
    res = {}
    for placement in PLACEMENTS:
        res["paths", placement] = bench_paths(args.worlds, args.repeats, placement)
        res["tours", placement] = bench_tours(args.worlds, args.repeats, placement)
        res["sharing", placement] = bench_sharing(args.worlds, args.repeats, placement)
        res["pipes", placement] = bench_pipelines(args.worlds, args.repeats, placement)
        res["noise", placement] = bench_noise(args.noise_blocks, placement)
    block = render(args.worlds, args.repeats, res)
    print(block)
    if args.write_results:
        write_section(block)


if __name__ == "__main__":
    main()
