"""Wall time of ``mrmt reproduce`` at the paper's sizes, and where the time goes.  (Issue 6.)

Two measurements:

1. **Full run** -- ``agents.experiments.reproduce`` at the paper's sizes (1000
   path queries, 100 tour / sharing / end-to-end instances, Table 5, figures,
   summary) with the default 2-process pool: the wall time a user waits, per
   experiment.
2. **Breakdown** -- the same experiments at 1/``--fraction`` of the sizes run
   inline (one process) with timers around the accelerator entry points:
   ``EmulatedChip.anneal_batch``/``sample`` (the emulated physical chip: numba
   kernel plus program checks) and ``LogicalIsingSolver`` calls (the logical
   Ising backend of the tour layer).  Per experiment it reports the measured
   host time of the classical baselines, of the Ising methods, and inside the
   latter the chip-emulation and logical-solver time; the rest of the Ising
   methods' time is Python glue (decomposition, QUBO building, mapping,
   decoding, scoring); wall time not inside any measured call is runner
   overhead (world generation, exact-tour scoring, figures, files).

    flock /tmp/mrmt-bench.lock python benchmarks/reproduce_time.py [--fraction 10] [--skip-full]
"""

from __future__ import annotations

import argparse
import functools
import json
import tempfile
import time

from agents import experiments

ACCEL = {}


def _patch(cls, name: str, key: str) -> None:
    orig = getattr(cls, name)
    depth = {"n": 0}

    @functools.wraps(orig)
    def timed(*args, **kwargs):
        if depth["n"]:
            return orig(*args, **kwargs)
        depth["n"] += 1
        t0 = time.perf_counter()
        try:
            return orig(*args, **kwargs)
        finally:
            ACCEL[key] = ACCEL.get(key, 0.0) + time.perf_counter() - t0
            depth["n"] -= 1

    setattr(cls, name, timed)


def install_timers() -> None:
    from ising_backend import EmulatedChip, LogicalIsingSolver

    for name in ("anneal_batch", "sample", "anneal_models"):
        if hasattr(EmulatedChip, name):
            _patch(EmulatedChip, name, "chip")
    for name in ("anneal_batch", "sample", "solve", "solve_many"):
        if hasattr(LogicalIsingSolver, name):
            _patch(LogicalIsingSolver, name, "logical")


def host_split(result) -> dict:
    ising = sum(r["cpu_s"] for r in result.rows if r["method"] == "ising")
    classical = sum(r["cpu_s"] for r in result.rows if r["method"] != "ising")
    return {"ising_host_s": ising, "classical_s": classical}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--fraction", type=int, default=10, help="breakdown run at 1/N of the paper sizes")
    p.add_argument("--skip-full", action="store_true")
    p.add_argument("--jobs", type=int, default=2)
    args = p.parse_args(argv)
    report: dict = {}

    if not args.skip_full:
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            out = experiments.reproduce(tmp, quick=False, n_jobs=args.jobs, progress=True)
            total = time.perf_counter() - t0
        report["full"] = {"wall_s": total, "per_experiment_wall_s": out["wall_s"],
                          "sizes": dict(experiments.PAPER_SIZES), "jobs": args.jobs}
        for name, res in out["results"].items():
            report["full"][name] = host_split(res)
        print(f"full reproduce at paper sizes, {args.jobs} workers: {total:.1f} s")
        for name, wall in out["wall_s"].items():
            print(f"  {name:9s} {wall:7.1f} s  {report['full'][name]}")

    install_timers()
    sizes = {k: max(1, v // args.fraction) for k, v in experiments.PAPER_SIZES.items()}
    runners = {
        "path": lambda: experiments.path_experiment(sizes["path"], n_jobs=1, progress=False),
        "tour": lambda: experiments.tour_experiment(sizes["tour"], n_jobs=1, progress=False),
        "sharing": lambda: experiments.sharing_experiment(sizes["sharing"], n_jobs=1, progress=False),
        "endtoend": lambda: experiments.endtoend_experiment(sizes["endtoend"], n_jobs=1, progress=False),
    }
    report["breakdown"] = {"sizes": sizes}
    print(f"breakdown (inline, sizes {sizes}):")
    print(f"  {'experiment':10s} {'wall':>8s} {'classical':>10s} {'ising host':>11s} {'chip emu':>9s} "
          f"{'logical':>9s} {'glue':>8s} {'other':>8s}")
    for name, run in runners.items():
        ACCEL.clear()
        t0 = time.perf_counter()
        res = run()
        wall = time.perf_counter() - t0
        split = host_split(res)
        chip, logical = ACCEL.get("chip", 0.0), ACCEL.get("logical", 0.0)
        glue = split["ising_host_s"] - chip - logical
        other = wall - split["ising_host_s"] - split["classical_s"]
        row = {"wall_s": wall, **split, "chip_emulation_s": chip, "logical_solver_s": logical,
               "ising_glue_s": glue, "runner_other_s": other}
        report["breakdown"][name] = row
        print(f"  {name:10s} {wall:8.2f} {split['classical_s']:10.3f} {split['ising_host_s']:11.3f} {chip:9.3f} "
              f"{logical:9.3f} {glue:8.3f} {other:8.3f}")
    print(json.dumps(report, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
