"""A different Ising chip: more spins, a wider coefficient range, more cores.

Builds the paper's Ising pipeline twice -- on the default emulated chip
(45 spins, integer h, J in [-7, 7], 4 chips x 2 cores) and on a custom one
(100 spins, [-15, 15], 8 chips x 2 cores) -- and compares route cost, chip
calls, chip latency (sequential and parallel over the cores) and accelerator
energy on the same worlds.

    python examples/custom_chip.py [--worlds 10]
"""

import argparse
import functools

import numpy as np

from agents.evaluation import evaluate
from agents.runner import RunConfig
from agents.policy import PlannerPolicy
from ising_backend import ChipSpec, EmulatedChip
from planners.pipeline import make_pipeline

CUSTOM = ChipSpec(n_spins=100, h_range=(-15, 15), j_range=(-15, 15), n_chips=8, cores_per_chip=2)


def ising_policy(spec: ChipSpec, seed: int) -> PlannerPolicy:
    """The Ising pipeline with every Ising layer on one chip of ``spec``."""
    pipeline = make_pipeline("ising", chip=EmulatedChip(spec, seed=seed))
    return PlannerPolicy(pipeline, seed=seed)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", type=int, default=10, help="worlds (3 robots x 10 targets)")
    parser.add_argument("--jobs", type=int, default=2, help="worker processes")
    args = parser.parse_args(argv)

    controllers = [
        ("ising, default chip", functools.partial(ising_policy, ChipSpec())),
        ("ising, custom chip", functools.partial(ising_policy, CUSTOM)),
    ]
    result = evaluate(controllers, n_worlds=args.worlds, run=RunConfig.from_jobs(args.jobs))
    print(f"default chip: {ChipSpec().n_spins} spins, h/J in {ChipSpec().h_range}, {ChipSpec().n_cores} cores")
    print(f"custom chip:  {CUSTOM.n_spins} spins, h/J in {CUSTOM.h_range}, {CUSTOM.n_cores} cores")
    print(result.format_summary())
    for name, _ in controllers:
        rows = result.by_controller(name)
        print(f"{name:22s} median chip calls {np.median([r['chip_calls'] for r in rows]):.0f}, "
              f"logical calls {np.median([r['logical_calls'] for r in rows]):.0f}, "
              f"8c/16c-parallel chip time {1e3 * np.median([r['chip_time_parallel_s'] for r in rows]):.2f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
