"""Issue 5 benchmark: the paper's three Ising planners and the Ising pipeline (paper section 6.2).

Side by side with the paper's figures and with the classical baselines run on
the *same* worlds (``generate_world(seed + i)``, 10x10, exactly 20 obstacles,
BFS distances):

* **pathfinding** -- ``n`` single-target queries (default 1000, uniform
  placement): success, median path length and excess over BFS, median chip
  calls, chip time and accelerator energy (paper: 996/1000, 32 calls, 14 uJ);
* **tour** -- ``n`` x 10 targets (default 100, uniform): median / mean gap to
  the exact tour (Held-Karp), median projected logical calls (paper 0.0 % /
  1.63 %, 98 calls; 3-opt 1.31 %);
* **sharing** -- ``n`` x (3 robots, 10 targets) (default 100, centre
  placement; every robot's targets toured exactly so only the allocation
  differs; Ising bundles priced by ``brute``): median total, gap to the exact
  min-sum optimum (``ExactSharing``), makespan, imbalance, chip calls and
  batches (paper 29.0 vs SSA 28.0, 20 calls / 5 batches), plus a sampling-
  noise check: ising / SSA / exact on ``--noise-worlds`` worlds (default 1000)
  in blocks of 100;
* **end to end** -- ``n`` x (3, 10) (default 100, centre): the ``ising``,
  ``strong`` (SSA + 3-opt + A*) and ``fast`` (PSA + NN + A*) pipelines: median
  cost, gap to strong, accelerator and host energy, latency (paper 32.0 /
  28.0 / 45.0);
* **Table 5** -- mapping outcomes per spin-merging style (pathfinding) and per
  quantization rule (sharing), summed over all Ising runs.

The experiment code is :mod:`agents.experiments` (one row per instance and
method); the ``run_*`` functions here return those rows (lists of dicts) and
:func:`summaries` / :func:`goal_rows` / :func:`render` turn them into the
tables, so the numbers can be reused without printing.

Time and energy follow the paper's convention: a classical method's measured
CPU wall time x 15 W; an Ising method's chip time (calls x 50 us) and
accelerator energy (calls x 0.45 uJ, projected logical calls included).  The
Ising methods' host CPU (classical glue) is reported beside it, never folded
away.

    flock /tmp/mrmt-bench.lock python benchmarks/quality_ising.py --write-results
    python benchmarks/quality_ising.py --quick
"""

from __future__ import annotations

import argparse
import math
import platform
import sys
import time
from pathlib import Path

import numpy as np

from agents import experiments as ex
from agents.experiments import records
from agents.experiments import summary as summary_stats

try:
    from _common import write_results_section  # run as a script: python benchmarks/<name>.py
except ImportError:  # imported as benchmarks.<name>
    from benchmarks._common import write_results_section

RESULTS = Path(__file__).with_name("RESULTS.md")
SECTION = "## Issue 5: Ising planners"

FULL_SIZES = {"path": 1000, "tour": 100, "sharing": 100, "endtoend": 100, "noise": 1000}
QUICK_SIZES = {"path": 100, "tour": 20, "sharing": 30, "endtoend": 10, "noise": 0}
EXPERIMENTS = ("path", "tour", "sharing", "endtoend")


# ------------------------------------------------------------------ experiments
def run_path_experiment(n: int = 1000, seed: int = 0, n_jobs: int = 2, progress: bool = False) -> list[dict]:
    """Paper 6.2.1 rows: BFS, A*, GBFS and Ising pathfinding on ``n`` single-target worlds."""
    return ex.path_experiment(n, seed=seed, n_jobs=n_jobs, progress=progress).rows


def run_tour_experiment(n: int = 100, seed: int = 0, n_jobs: int = 2, progress: bool = False) -> list[dict]:
    """Paper 6.2.2 rows: NN, 2-opt, 3-opt, exact and Ising tours, 1 robot x 10 targets."""
    return ex.tour_experiment(n, seed=seed, n_jobs=n_jobs, progress=progress).rows


def run_sharing_experiment(n: int = 100, seed: int = 0, methods=ex.SHARING_METHODS, n_jobs: int = 2,
                           progress: bool = False) -> list[dict]:
    """Paper 6.2.3 rows: round robin, PSA, SSA, exact and Ising sharing, 3 robots x 10 targets (centre)."""
    return ex.sharing_experiment(n, seed=seed, methods=tuple(methods), n_jobs=n_jobs, progress=progress).rows


def run_endtoend_experiment(n: int = 100, seed: int = 0, n_jobs: int = 2, progress: bool = False) -> list[dict]:
    """Paper 6.2.4 rows: fast, strong and Ising pipelines, 3 robots x 10 targets (centre)."""
    return ex.endtoend_experiment(n, seed=seed, n_jobs=n_jobs, progress=progress).rows


#: End-to-end variants of the Ising pipeline run beside the preset (label -> make_pipeline keywords).
VARIANTS = {
    "ising, bundles priced by the Ising tour (pricing_tour='downstream')": {
        "sharing_options": {"pricing_tour": "downstream"}
    },
}


def run_endtoend_variant(n: int, seed: int, label: str, options: dict) -> list[dict]:
    """End-to-end rows (same columns as :func:`run_endtoend_experiment`) for
    ``make_pipeline("ising", **options)`` on the same worlds, one process."""
    from mrmt_env.generation import generate_world
    from planners.pipeline import make_pipeline

    rows = []
    make_pipeline("ising", **options).plan(generate_world(seed, placement="centre"), seed=0)  # warm-up
    for i in range(n):
        world = generate_world(seed + i, n_robots=3, n_targets=10, placement="centre")
        plan = make_pipeline("ising", **options).plan(world, seed=seed + i)
        ok = records._plan_valid(world, plan)
        row = {"instance": i, "world_seed": seed + i, "method": label, "success": ok,
               "cost": float(plan.route_cost) if ok else math.nan}
        row.update(records._compute_columns(plan.compute, plan.compute.cpu_s, True))
        row.update(records._layer_columns(plan))
        rows.append(row)
    return rows


def variant_summary(rows: list[dict], strong_rows: list[dict]) -> dict:
    """Median total, gap to strong (same instance), energies, latency and calls of a variant."""
    strong = {r["instance"]: r for r in strong_rows if r["method"] == "strong" and r["success"]}
    ok = [r for r in rows if r["success"]]
    gaps = [100.0 * (r["cost"] - strong[r["instance"]]["cost"]) / strong[r["instance"]]["cost"]
            for r in ok if r["instance"] in strong]
    med = summary_stats._med
    s = {
        "success": f"{len(ok)}/{len(rows)}",
        "median total": med([r["cost"] for r in ok]),
        "median gap to strong (%)": med(gaps),
        "median accelerator energy (mJ)": 1e3 * med([r["accelerator_energy_j"] for r in rows]),
        "median latency, chip time (ms)": 1e3 * med([r["chip_time_s"] for r in rows]),
        "median host cpu (ms)": 1e3 * med([r["cpu_s"] for r in rows]),
        "median system energy (mJ)": 1e3 * med([r["total_energy_j"] for r in rows]),
        "median sharing chip calls": med([r.get("sharing_chip_calls", math.nan) for r in rows]),
        "median sharing logical calls": med([r.get("sharing_logical_calls", math.nan) for r in rows]),
        "median sharing host cpu (ms)": 1e3 * med([r.get("sharing_cpu_s", math.nan) for r in rows]),
    }
    strong_e = med([r["energy_j"] for r in strong.values()])
    s["energy ratio strong / this"] = summary_stats._ratio(1e3 * strong_e, s["median accelerator energy (mJ)"])
    return s


#: Sharing variants run beside the default (label -> IsingSharing keywords), to show what each choice buys.
SHARING_VARIANTS = {
    "greedy recursion (beam 1, refine_beam 1, reads 1)": {"beam": 1, "refine_beam": 1, "reads": 1},
    "+ literal eq. 8 weights (weight_shift 0)": {"beam": 1, "refine_beam": 1, "reads": 1, "weight_shift": 0.0},
    "+ no refinement (refine_stages 0)": {"beam": 1, "refine_beam": 1, "reads": 1, "weight_shift": 0.0,
                                          "refine_stages": 0},
}


def run_sharing_variant(n: int, seed: int, label: str, options: dict) -> list[dict]:
    """Sharing rows for ``IsingSharing(**options)`` on the sharing experiment's worlds
    (centre, 3 x 10, bundles priced and allocations toured by ``brute``)."""
    from mrmt_env.generation import generate_world
    from planners.ising.sharing import IsingSharing
    from planners.tours_classical import BruteTour

    tour = BruteTour()
    rows = []
    for i in range(n):
        world = generate_world(seed + i, n_robots=3, n_targets=10, placement="centre")
        dist = world.distance_matrix
        res = IsingSharing(**options).assign(dist, 3, tour, np.random.default_rng(seed + i))
        ok = res.failure is None
        lengths = []
        for k, group in enumerate(res.assignment):
            nodes = [k] + [3 + int(t) for t in group]
            lengths.append(float(tour.solve(dist[np.ix_(nodes, nodes)]).cost) if group else 0.0)
        rows.append({"instance": i, "method": label, "success": ok,
                     "cost": float(sum(lengths)) if ok else math.nan,
                     "makespan": float(max(lengths)) if ok else math.nan,
                     "imbalance": float(max(lengths) - min(lengths)) if ok else math.nan,
                     "chip_calls": res.compute.chip_calls, "chip_batches": res.compute.chip_batches})
    return rows


def sharing_variant_summary(rows: list[dict], exact_rows: list[dict]) -> dict:
    exact = {r["instance"]: r["cost"] for r in exact_rows if r["method"] == "exact" and r["success"]}
    ok = [r for r in rows if r["success"]]
    med = summary_stats._med
    return {
        "median total": med([r["cost"] for r in ok]),
        "mean total": summary_stats._mean([r["cost"] for r in ok]),
        "median gap to exact (%)": med([100.0 * (r["cost"] - exact[r["instance"]]) / exact[r["instance"]]
                                        for r in ok if r["instance"] in exact]),
        "median makespan": med([r["makespan"] for r in ok]),
        "median imbalance": med([r["imbalance"] for r in ok]),
        "median chip calls": med([r["chip_calls"] for r in rows]),
        "median chip batches": med([r["chip_batches"] for r in rows]),
    }


def _result(name: str, rows: list[dict]) -> ex.ExperimentResult:
    methods = tuple(dict.fromkeys(r["method"] for r in rows))
    return ex.ExperimentResult(name, rows, methods)


def summaries(rows_by_name: dict) -> dict:
    """``{experiment: {statistic: value}}`` (keys as :data:`agents.experiments.PAPER`, plus
    for sharing the number of worlds where Ising matches the exact optimum and where the
    totals are <= 28)."""
    out = {name: ex.summarize(_result(name, rows)) for name, rows in rows_by_name.items() if rows}
    rows = rows_by_name.get("sharing")
    if rows and "sharing" in out:
        cost = {(r["method"], r["instance"]): r["cost"] for r in rows if r["success"]}
        inst = sorted({r["instance"] for r in rows})
        ising = [cost.get(("ising", i)) for i in inst]
        exact = [cost.get(("exact", i)) for i in inst]
        n_opt = sum(a is not None and a == b for a, b in zip(ising, exact))
        out["sharing"]["ising worlds at the exact optimum"] = f"{n_opt}/{len(inst)}"
        for m, vals in (("ising", ising), ("ssa", [cost.get(("ssa", i)) for i in inst]), ("exact", exact)):
            n_le = sum(v is not None and v <= 28 for v in vals)
            out["sharing"][f"{m} worlds with total <= 28"] = f"{n_le}/{len(inst)}"
    return out


def mapping_rows(path_rows: list[dict] | None, sharing_rows: list[dict] | None) -> list[dict]:
    """Paper Table 5 from the Ising rows' mapping counts."""
    return ex.mapping_table(_result("path", path_rows) if path_rows else None,
                            _result("sharing", sharing_rows) if sharing_rows else None)


def sharing_blocks(rows: list[dict], block: int = 100) -> list[dict]:
    """Per block of ``block`` consecutive worlds: median and mean total of every method."""
    out = []
    instances = sorted({r["instance"] for r in rows})
    methods = tuple(dict.fromkeys(r["method"] for r in rows))
    for start in range(0, len(instances), block):
        chosen = set(instances[start:start + block])
        row = {"worlds": f"{min(chosen)}..{max(chosen)}"}
        for m in methods:
            vals = [r["cost"] for r in rows if r["method"] == m and r["instance"] in chosen and r["success"]]
            row[f"{m} median"] = float(np.median(vals)) if vals else math.nan
            row[f"{m} mean"] = float(np.mean(vals)) if vals else math.nan
        out.append(row)
    return out


#: Issue 5's goals ("better than the paper, not equal").
GOALS = (
    ("path", "success on every query (paper 996/1000)", "ising success", lambda v, n: v == f"{n}/{n}"),
    ("path", "median chip calls <= 16", "ising median chip calls", lambda v, n: v <= 16),
    ("tour", "mean gap <= 0.5 %", "ising mean gap (%)", lambda v, n: v <= 0.5),
    ("sharing", "median total <= 28", "ising median total", lambda v, n: v <= 28),
    ("endtoend", "median gap to strong <= 3 %", "ising median gap to strong (%)", lambda v, n: v <= 3.0),
    ("endtoend", "accelerator energy >= 100x below strong", "energy ratio strong / ising", lambda v, n: v >= 100),
)


def goal_rows(stats: dict, sizes: dict) -> list[dict]:
    """One row per issue-5 goal: target, measured value, met or not."""
    rows = []
    for name, target, key, ok in GOALS:
        if name not in stats:
            continue
        v = stats[name].get(key)
        try:
            met = bool(ok(v, sizes.get(name))) if v is not None else False
        except TypeError:
            met = False
        rows.append({"experiment": name, "goal": target, "statistic": key, "measured": v, "met": met})
    return rows


# ----------------------------------------------------------------- rendering
_TITLES = {"path": "Pathfinding", "tour": "Tour construction", "sharing": "Target sharing",
           "endtoend": "End-to-end pipeline"}
_SETUP = {
    "path": "{n} single-target queries, uniform placement (robot start -> target of `generate_world(i, 1 robot, 1 target)`)",
    "tour": "{n} worlds, 1 robot x 10 targets, uniform placement; gap to Held-Karp",
    "sharing": "{n} worlds, 3 robots x 10 targets, centre placement; every allocation toured exactly; Ising bundles priced by `brute`",
    "endtoend": "{n} worlds, 3 robots x 10 targets, centre placement; validated plans",
}


def _fmt(v) -> str:
    return summary_stats._fmt(v)


def render(stats: dict, sizes: dict, mapping: list[dict], blocks: list[dict], goals: list[dict],
           wall: dict, quick: bool, variants: dict | None = None, sharing_variants: dict | None = None) -> str:
    lines = [SECTION, ""]
    lines += [
        "Paper section 6.2 on the same worlds for every method (`generate_world(seed + i)`, seed 0).  "
        "Ising time and energy: chip time = calls x 50 us (sequential), accelerator energy = calls x 0.45 uJ "
        "(tour: projected logical calls); `host cpu` is the Ising methods' classical glue (decomposition, "
        "mapping, decode, scoring, bundle pricing), never folded into the accelerator figures.  "
        "Classical energy = CPU time x 15 W (numba kernels: much faster than the paper's Python baselines, "
        "so every energy ratio is harder to win than the paper's).",
        "",
        f"Machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}; 2 shared cores."
        + (" **Quick run (small sizes), not the paper's sizes.**" if quick else ""),
        "",
    ]
    if goals:
        lines += ["### Goals of issue 5", "", "| experiment | goal | measured | met |", "|---|---|---:|---|"]
        for g in goals:
            lines.append(f"| {g['experiment']} | {g['goal']} | {_fmt(g['measured'])} | {'yes' if g['met'] else '**no**'} |")
        lines.append("")
    for name in EXPERIMENTS:
        if name not in stats:
            continue
        s, paper = stats[name], ex.PAPER[name]
        lines += [f"### {_TITLES[name]}: {_SETUP[name].format(n=sizes[name])} ({wall.get(name, 0):.0f} s)", "",
                  "| statistic | paper | measured |", "|---|---:|---:|"]
        lines += summary_stats._paper_rows(paper, s)
        lines.append("")
    if sharing_variants:
        keys = list(next(iter(sharing_variants.values())).keys())
        lines += ["### Target sharing: what each choice buys (same worlds; `IsingSharing` options)", "",
                  "| variant | " + " | ".join(keys) + " |", "|---|" + "---:|" * len(keys)]
        for label, v in sharing_variants.items():
            lines.append(f"| {label} | " + " | ".join(_fmt(v.get(k)) for k in keys) + " |")
        lines.append("")
    if variants:
        keys = list(next(iter(variants.values())).keys())
        lines += ["### End-to-end Ising pipeline variants (same worlds; energy = accelerator only)", "",
                  "| statistic | " + " | ".join(f"`{k}`" for k in variants) + " |",
                  "|---|" + "---:|" * len(variants)]
        for key in keys:
            lines.append(f"| {key} | " + " | ".join(_fmt(v.get(key)) for v in variants.values()) + " |")
        lines.append("")
    if blocks:
        methods = [k[: -len(" median")] for k in blocks[0] if k.endswith(" median")]
        lines += [f"### Target sharing, sampling noise: {len(blocks)} blocks of 100 centre worlds", "",
                  "| worlds | " + " | ".join(f"{m} median / mean" for m in methods) + " |",
                  "|---|" + "---:|" * len(methods)]
        for b in blocks:
            lines.append(f"| {b['worlds']} | " + " | ".join(f"{_fmt(b[m + ' median'])} / {b[m + ' mean']:.2f}"
                                                            for m in methods) + " |")
        alls = {m: [b[m + " median"] for b in blocks] for m in methods}
        lines.append("| median of blocks | " + " | ".join(f"{_fmt(float(np.median(alls[m])))}" for m in methods) + " |")
        lines.append("")
    if mapping:
        lines += ["### Table 5: mapping outcomes (counts summed over all Ising runs above)", "",
                  "| layer | mapping choice | candidates | valid | wins | paper valid/cand. share | measured | "
                  "paper win share | measured |", "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
        for m in mapping:
            share = m["valid_rate_pct"] if m["layer"] == "path" else m["candidate_share_pct"]
            kind = "valid" if m["layer"] == "path" else "cand."
            lines.append(
                f"| {m['layer']} | {m['choice']} | {m['candidates']} | {m['valid']} | {m['wins']} | "
                f"{_fmt(m['paper_share_pct'])}% {kind} | {_fmt(share)}% | {_fmt(m['paper_win_share_pct'])}% | "
                f"{_fmt(m['win_share_pct'])}% |"
            )
        lines.append("")
    notes = _notes(stats, blocks, variants or {})
    if notes:
        lines += ["Notes.", ""] + [f"* {n}" for n in notes] + [""]
    cmd = "flock /tmp/mrmt-bench.lock python benchmarks/quality_ising.py --write-results"
    lines += [f"Reproduce: `{cmd}{' --quick' if quick else ''}`", ""]
    return "\n".join(lines)


def _notes(stats: dict, blocks: list[dict], variants: dict) -> list[str]:
    """What limits a missed goal, in measured numbers."""
    out = []
    sh = stats.get("sharing")
    if sh and not sh.get("ising median total", 99) <= 28:
        msg = (f"Sharing median total {_fmt(sh.get('ising median total'))} on these worlds, where SSA gives "
               f"{_fmt(sh.get('ssa median total'))} and the exact min-sum optimum {_fmt(sh.get('exact median total'))}: "
               "a median <= 28 here would need the optimum on nearly every world "
               f"(worlds with total <= 28: Ising {sh.get('ising worlds with total <= 28')}, SSA "
               f"{sh.get('ssa worlds with total <= 28')}, exact {sh.get('exact worlds with total <= 28')}; "
               f"Ising at the exact optimum on {sh.get('ising worlds at the exact optimum')}).")
        if blocks:
            allm = {m: float(np.median([b[m + ' median'] for b in blocks])) for m in ("ising", "ssa", "exact")}
            means = {m: float(np.mean([b[m + ' mean'] for b in blocks])) for m in ("ising", "ssa", "exact")}
            msg += (f" Over {100 * len(blocks)} worlds (noise table) the median of block medians is "
                    f"{_fmt(allm['ising'])} (SSA {_fmt(allm['ssa'])}, exact {_fmt(allm['exact'])}) and the mean "
                    f"total {means['ising']:.2f} (SSA {means['ssa']:.2f}, exact {means['exact']:.2f}).")
        out.append(msg)
    ee = stats.get("endtoend")
    if ee and not (ee.get("energy ratio strong / ising") or 0) >= 100:
        strong_mj = ee.get("strong median energy (mJ)") or math.nan
        calls = math.floor(1e-5 * strong_mj / 0.45e-6) if math.isfinite(strong_mj) else math.nan
        msg = (f"End-to-end energy ratio strong / Ising = {_fmt(ee.get('energy ratio strong / ising'))}: the strong "
               f"classical pipeline is numba code at {_fmt(ee.get('strong median host cpu (ms)'))} ms "
               f"({_fmt(ee.get('strong median energy (mJ)'))} mJ), so 100x asks for "
               f"<= {_fmt(10 * strong_mj)} uJ, about "
               f"{_fmt(calls)} chip calls "
               f"for the whole plan; the Ising pipeline uses {_fmt(ee.get('ising median path chip calls'))} path "
               f"calls, {_fmt(ee.get('ising median sharing chip calls'))} sharing calls and "
               f"{_fmt(ee.get('ising median tour logical calls'))} tour logical calls.")
        out.append(msg)
    return out


def write_section(block: str) -> None:
    write_results_section(SECTION, block, RESULTS)
    print(f"wrote section {SECTION!r} of {RESULTS}", file=sys.stderr)


# ---------------------------------------------------------------------- main
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="small sizes (a smoke run, minutes -> seconds)")
    ap.add_argument("--n", type=int, default=None,
                    help="instances for tour/sharing/end-to-end (pathfinding: 10 x n queries)")
    ap.add_argument("--noise-worlds", type=int, default=None,
                    help="worlds for the sharing noise check (multiple of 100; 0 = skip)")
    ap.add_argument("--only", nargs="+", choices=EXPERIMENTS, default=list(EXPERIMENTS))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--progress", action="store_true")
    ap.add_argument("--write-results", action="store_true", help="update benchmarks/RESULTS.md")
    args = ap.parse_args(argv)

    sizes = dict(QUICK_SIZES if args.quick else FULL_SIZES)
    if args.n is not None:
        if args.n < 1:
            ap.error(f"--n must be >= 1, got {args.n}")
        sizes.update(path=10 * args.n, tour=args.n, sharing=args.n, endtoend=args.n)
    if args.noise_worlds is not None:
        if args.noise_worlds < 0 or args.noise_worlds % 100:
            ap.error(f"--noise-worlds must be a non-negative multiple of 100, got {args.noise_worlds}")
        sizes["noise"] = args.noise_worlds

    runners = {
        "path": lambda: run_path_experiment(sizes["path"], args.seed, args.jobs, args.progress),
        "tour": lambda: run_tour_experiment(sizes["tour"], args.seed, args.jobs, args.progress),
        "sharing": lambda: run_sharing_experiment(sizes["sharing"], args.seed, n_jobs=args.jobs,
                                                  progress=args.progress),
        "endtoend": lambda: run_endtoend_experiment(sizes["endtoend"], args.seed, args.jobs, args.progress),
    }
    rows: dict = {}
    wall: dict = {}
    for name in args.only:
        t0 = time.perf_counter()
        rows[name] = runners[name]()
        wall[name] = time.perf_counter() - t0
        print(f"{name}: {len(rows[name])} rows in {wall[name]:.1f} s", file=sys.stderr)
    blocks: list[dict] = []
    if "sharing" in args.only and sizes["noise"]:
        t0 = time.perf_counter()
        noise = run_sharing_experiment(sizes["noise"], args.seed, methods=("ising", "ssa", "exact"),
                                       n_jobs=args.jobs, progress=args.progress)
        blocks = sharing_blocks(noise)
        print(f"sharing noise: {len(noise)} rows in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    variants: dict = {}
    if "endtoend" in args.only:
        preset_rows = [r for r in rows["endtoend"] if r["method"] == "ising"]
        variants["ising preset (bundles priced exactly on the host)"] = variant_summary(preset_rows, rows["endtoend"])
        for label, options in VARIANTS.items():
            t0 = time.perf_counter()
            vrows = run_endtoend_variant(sizes["endtoend"], args.seed, label, options)
            variants[label] = variant_summary(vrows, rows["endtoend"])
            print(f"end-to-end variant {label!r}: {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    sharing_variants: dict = {}
    if "sharing" in args.only:
        own = [r for r in rows["sharing"] if r["method"] == "ising"]
        sharing_variants["defaults"] = sharing_variant_summary(own, rows["sharing"])
        for label, options in SHARING_VARIANTS.items():
            vrows = run_sharing_variant(sizes["sharing"], args.seed, label, options)
            sharing_variants[label] = sharing_variant_summary(vrows, rows["sharing"])
    stats = summaries(rows)
    mapping = mapping_rows(rows.get("path"), rows.get("sharing"))
    goals = goal_rows(stats, sizes)
    block = render(stats, sizes, mapping, blocks, goals, wall, args.quick, variants, sharing_variants)
    print(block)
    if args.write_results:
        write_section(block)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
