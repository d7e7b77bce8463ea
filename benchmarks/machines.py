"""The Ising pipeline on other Ising machines: validity, route cost, calls and host time per machine.

Set-up: the paper's worlds (``generate_world(i, n_robots=3, n_targets=10, placement="centre")``,
seeds ``0..N-1``, default 100), the ``ising`` preset (``--preset``) planned with seed ``i`` on
each machine: the emulator (healthy, and faulty at ``readout_flip_prob=0.01, dead_cores=1,
stuck_spins=2``), and each ``--samplers`` name behind a :class:`ising_backend.SamplerChip` of
the paper's spec; the strong pipeline (SSA + 3-opt + A*) and the exact optimum beside them.
One machine (one ledger) per row, warmed up on one world first; the machines plan world by world in turn, so
machine noise falls on all of them alike.

Reported per machine: valid plans, mean route cost and its gap to the emulator's and to the
exact optimum, mean physical calls per plan, median host CPU ms per plan (measured minus
the machine's own seconds, ``emulation_s``) and its ratio to the healthy emulator's and to
strong's, median seconds inside the machine per plan.

    flock /tmp/mrmt-bench.lock python benchmarks/machines.py --write-results

``--write-results`` replaces the "Ising machines" section of ``benchmarks/RESULTS.md``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from ising_backend import ChipSpec, EmulatedChip, MachineSpec
from mrmt_env.generation import generate_world
from planners.pipeline import make_pipeline

try:
    from _common import cpu_name, finish  # run as a script: python benchmarks/<name>.py
except ImportError:  # imported as benchmarks.machines
    from benchmarks._common import cpu_name, finish

SECTION = "## Ising machines: the pipeline on other samplers and on a faulty chip"
FAULTY = {"readout_flip_prob": 0.01, "dead_cores": 1, "stuck_spins": 2}


def run(pipes: dict, worlds) -> dict:
    """Every pipeline on every world, interleaved world by world (machine noise falls on all alike)."""
    for pipe in pipes.values():
        pipe.plan(worlds[0], seed=0)  # compile and warm up outside the measurement
    out = {name: {"valid": [], "cost": [], "calls": [], "host": [], "inside": []} for name in pipes}
    for i, w in enumerate(worlds):
        for name, pipe in pipes.items():
            p = pipe.plan(w, seed=i)
            r = out[name]
            r["valid"].append(bool(p.success))
            r["cost"].append(p.route_cost if p.success else np.nan)
            r["calls"].append(p.compute.chip_calls)
            r["host"].append(p.compute.host_cpu_s)
            r["inside"].append(p.compute.emulation_s)
    return {name: {"valid": int(np.sum(r["valid"])), "cost": np.array(r["cost"], float),
                   "calls": float(np.mean(r["calls"])), "host": float(np.median(r["host"])),
                   "inside": float(np.median(r["inside"]))} for name, r in out.items()}


def main(argv=None) -> str:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", type=int, default=100)
    ap.add_argument("--preset", default="ising")
    ap.add_argument("--samplers", default="dwave-sa,neal,openjij-sa,dwave-tabu")
    ap.add_argument("--write-results", action="store_true")
    args = ap.parse_args(argv)
    worlds = [generate_world(i, n_robots=3, n_targets=10, placement="centre") for i in range(args.worlds)]
    t0 = time.perf_counter()
    machines = {"emulator": EmulatedChip(), "emulator, faulty": EmulatedChip(ChipSpec(**FAULTY))}
    for name in filter(None, args.samplers.split(",")):
        opts = (("timeout", 1),) if name == "dwave-tabu" else ()
        try:
            machines[name] = MachineSpec(ChipSpec(), name, opts).build()
        except ValueError as exc:
            print(f"skipped {name}: {exc}")
    pipes = {"exact": make_pipeline("exact"), "strong": make_pipeline("strong")}
    pipes.update({name: make_pipeline(args.preset, chip=chip) for name, chip in machines.items()})
    rows = run(pipes, worlds)
    exact, strong = rows.pop("exact")["cost"], rows.pop("strong")
    base = rows["emulator"]
    lines = [SECTION, "",
             f"`{args.preset}` preset, {args.worlds} paper worlds (3 robots x 10 targets, centre placement), "
             f"planning seed = world seed; one machine per row, the machines planning world by world in turn. {cpu_name()}; "
             f"{time.perf_counter() - t0:.0f} s in all. Exact optimum mean {np.mean(exact):.2f}; strong "
             f"{np.nanmean(strong['cost']):.2f} ({strong['host'] * 1e3:.2f} ms host per plan).", "",
             "| machine | valid | mean cost | vs emulator | gap to exact | calls / plan | host ms / plan | "
             "host vs emulator | host vs strong | in machine ms / plan |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for name, r in rows.items():
        mean = np.nanmean(r["cost"])
        lines.append(f"| {name} | {r['valid']}/{args.worlds} | {mean:.2f} | "
                     f"{100 * (mean / np.nanmean(base['cost']) - 1):+.2f} % | {100 * (mean / np.mean(exact) - 1):.2f} % | "
                     f"{r['calls']:.0f} | {r['host'] * 1e3:.2f} | {r['host'] / base['host']:.2f}x | "
                     f"{r['host'] / strong['host']:.1f}x | {r['inside'] * 1e3:.1f} |")
    lines += ["", "Command: `flock /tmp/mrmt-bench.lock python benchmarks/machines.py --write-results`. "
              "Host ms = measured CPU time less the seconds spent inside the machine (emulation, or the "
              "sampler's own run time); the chip's time and energy are charged by the spec (50 us, 0.45 uJ "
              "per call) whatever the machine."]
    return finish(SECTION, lines, args.write_results)


if __name__ == "__main__":
    main()
