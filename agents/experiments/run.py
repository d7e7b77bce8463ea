"""Running the experiments on the task runner (:mod:`agents.runner`) and ``reproduce``."""

from __future__ import annotations

import json
import time
from pathlib import Path

from agents.experiments.figures import plot_experiment
from agents.experiments.paper import (PAPER, PAPER_SIZES, PATH_METHODS, QUICK_SIZES,
                                      SHARING_METHODS, TOUR_METHODS, endtoend_methods)
from agents.experiments.records import ExperimentResult, _clean, write_rows
from agents.experiments.summary import mapping_table, summarize, write_summary
from agents.experiments.tasks import _endtoend_instance, _path_instance, _sharing_instance, _tour_instance
from agents.runner import RunConfig, run_tasks

def _run_instances(task, n: int, args: tuple, run, desc: str) -> list[dict]:
    """``task(i, *args)`` for instances ``0 .. n-1`` on the runner ``run`` (a :class:`RunConfig`)."""
    parts = run_tasks(task, [(i, *args) for i in range(n)], run, desc=desc, unit="inst")
    rows = [r for part in parts for r in part]
    rows.sort(key=lambda r: r["instance"])
    return rows


def _runner(run: RunConfig | None, n_jobs: int, progress: bool) -> RunConfig:
    return run if run is not None else RunConfig.from_jobs(n_jobs, progress=progress)


def _check_n(name: str, n: int) -> int:
    if int(n) != n or n < 1:
        raise ValueError(f"{name} must be an integer >= 1, got {n!r}")
    return int(n)


def path_experiment(n: int = 1000, seed: int = 0, methods=PATH_METHODS, placement: str = "uniform",
                    n_jobs: int = 2, progress: bool = True, chip=None,
                    run: RunConfig | None = None) -> ExperimentResult:
    """Paper 6.2.1: ``n`` single-target queries on 10x10 worlds (1 robot, 1 target)."""
    n = _check_n("n", n)
    t0 = time.perf_counter()
    rows = _run_instances(_path_instance, n, (seed, tuple(methods), placement, chip),
                          _runner(run, n_jobs, progress), "path")
    return ExperimentResult("path", rows, tuple(methods), {"n": n, "seed": seed, "placement": placement},
                            time.perf_counter() - t0)


def tour_experiment(n: int = 100, seed: int = 0, methods=TOUR_METHODS, n_targets: int = 10,
                    placement: str = "uniform", n_jobs: int = 2, progress: bool = True, chip=None,
                    run: RunConfig | None = None) -> ExperimentResult:
    """Paper 6.2.2: ``n`` open tours of one robot over ``n_targets`` targets; gap to the exact tour."""
    n = _check_n("n", n)
    t0 = time.perf_counter()
    rows = _run_instances(_tour_instance, n, (seed, tuple(methods), n_targets, placement, chip),
                          _runner(run, n_jobs, progress), "tour")
    return ExperimentResult("tour", rows, tuple(methods),
                            {"n": n, "seed": seed, "n_targets": n_targets, "placement": placement},
                            time.perf_counter() - t0)


def sharing_experiment(n: int = 100, seed: int = 0, methods=SHARING_METHODS, n_robots: int = 3,
                       n_targets: int = 10, placement: str = "centre", pricing_tour: str = "brute",
                       n_jobs: int = 2, progress: bool = True, chip=None,
                    run: RunConfig | None = None) -> ExperimentResult:
    """Paper 6.2.3: ``n`` allocations of ``n_targets`` targets to ``n_robots`` robots.

    ``pricing_tour`` is the tour solver handed to the sharing methods (used by
    Ising bundle assignment); every allocation is then scored with exact
    tours so only the allocation differs between methods.
    """
    n = _check_n("n", n)
    t0 = time.perf_counter()
    rows = _run_instances(_sharing_instance, n, (seed, tuple(methods), n_robots, n_targets, placement, pricing_tour, chip),
                          _runner(run, n_jobs, progress), "sharing")
    return ExperimentResult("sharing", rows, tuple(methods),
                            {"n": n, "seed": seed, "n_robots": n_robots, "n_targets": n_targets,
                             "placement": placement, "pricing_tour": pricing_tour},
                            time.perf_counter() - t0)


def endtoend_experiment(n: int = 100, seed: int = 0, methods=None, n_robots: int = 3,
                        n_targets: int = 10, placement: str = "centre", n_jobs: int = 2,
                        progress: bool = True, chip=None,
                    run: RunConfig | None = None) -> ExperimentResult:
    """Paper 6.2.4: the fast, strong and Ising pipelines on ``n`` worlds of ``n_robots`` x ``n_targets``
    (``methods=None``: those and PyVRP where installed, :func:`~agents.experiments.paper.endtoend_methods`)."""
    n = _check_n("n", n)
    methods = endtoend_methods() if methods is None else methods
    t0 = time.perf_counter()
    rows = _run_instances(_endtoend_instance, n, (seed, tuple(methods), n_robots, n_targets, placement, chip),
                          _runner(run, n_jobs, progress), "end-to-end")
    return ExperimentResult("endtoend", rows, tuple(methods),
                            {"n": n, "seed": seed, "n_robots": n_robots, "n_targets": n_targets,
                             "placement": placement},
                            time.perf_counter() - t0)



def reproduce(out, quick: bool = False, seed: int = 0, n_jobs: int = 2, progress: bool = True,
              sizes: dict | None = None, experiments=("path", "tour", "sharing", "endtoend"), chip=None,
              run: RunConfig | None = None) -> dict:
    """Run the section-6 experiments and write everything into ``out``.

    Files: ``{name}.csv`` / ``{name}.json`` (one row per instance and method)
    and ``fig_{name}.png`` for each experiment, ``mapping.csv`` /
    ``mapping.json`` (Table 5), ``summary.json`` (measured statistics with the
    paper's) and ``summary.md``.

    ``chip`` (an :class:`ising_backend.ChipSpec`) is the emulated chip of every Ising method
    (default the paper's chip); ``run`` the task runner (default: ``n_jobs`` processes, inline for 1).

    Returns:
        ``{"files": [paths...], "results": {name: ExperimentResult}, "wall_s": {...}}``
    """
    run = _runner(run, n_jobs, progress)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    base = dict(QUICK_SIZES if quick else PAPER_SIZES)
    base.update(sizes or {})
    unknown = set(experiments) - set(PAPER_SIZES)
    if unknown:
        raise ValueError(f"unknown experiment(s) {sorted(unknown)}; known: {', '.join(PAPER_SIZES)}")
    runners = {
        "path": lambda: path_experiment(base["path"], seed=seed, chip=chip, run=run),
        "tour": lambda: tour_experiment(base["tour"], seed=seed, chip=chip, run=run),
        "sharing": lambda: sharing_experiment(base["sharing"], seed=seed, chip=chip, run=run),
        "endtoend": lambda: endtoend_experiment(base["endtoend"], seed=seed, chip=chip, run=run),
    }
    results: dict = {}
    files: list[Path] = []
    wall: dict = {}
    for name in experiments:
        t0 = time.perf_counter()
        res = runners[name]()
        results[name] = res
        files += list(write_rows(res.rows, out / name))
        files.append(plot_experiment(res, out / f"fig_{name}.png"))
        wall[name] = time.perf_counter() - t0
    mapping = mapping_table(results.get("path"), results.get("sharing"))
    files += list(write_rows(mapping, out / "mapping"))
    summary = {name: {k: _clean(v) for k, v in summarize(res).items()} for name, res in results.items()}
    paper = {name: PAPER[name] for name in results}
    with open(out / "summary.json", "w") as f:
        json.dump({"quick": quick, "seed": seed, "sizes": {k: base[k] for k in results}, "wall_s": wall,
                   "chip": None if chip is None else chip.to_dict(),
                   "measured": summary, "paper": paper}, f, indent=1)
    files.append(out / "summary.json")
    files.append(write_summary(results, mapping, out / "summary.md", quick, wall))
    return {"files": files, "results": results, "wall_s": wall, "mapping": mapping}
