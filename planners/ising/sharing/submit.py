"""The chip side of Ising target sharing (paper 5.3): what a stage's compiled submission needs.

Every split of a stage x every quantization rule of the portfolio goes into one chip submission
(:func:`.engine.run_stage`): mapped at once, block-packed first-fit decreasing into shared chip
programs, every read decoded, checked and scored on the unquantized cut; splits beyond the chip
go in as their spin-budget branches (:func:`.kernels.branch_problems`).  :class:`StageSolver`
holds the portfolio's rule ids, the chip's coefficient limits, the machine and the running call's
meter (whose ledger the call's session charges).
"""

from __future__ import annotations

import numpy as np

from ising_backend import QUANTIZE_RULE_IDS
from planners.ising.sharing.engine import STAGE_NONFINITE

__all__ = ["StageSolver", "stage_refusal"]


def stage_refusal(status: int) -> str:
    """The failure of a stage :func:`.engine.run_stage` would not submit (its ``status``)."""
    if status == STAGE_NONFINITE:
        return "a split program could not be quantized: a coefficient is not finite (distances too large to add)"
    return "the chip refused a mapped split program: a quantized coefficient is outside the chip's range"


class StageSolver:
    """:class:`~planners.ising.sharing.IsingSharing`'s chip side, a component: ``StageSolver(config,
    chip)``; ``meter`` is the running sharing call's :class:`ising_backend.MeteredSolver`."""

    def __init__(self, config, chip):
        self.config = config
        self.chip = chip
        self.rule_ids = np.array([QUANTIZE_RULE_IDS[r] for r in config.rules], dtype=np.int64)
        self.limits = tuple(float(v) for v in chip.spec.coefficient_limits)
        self.meter = None

    def capacity(self) -> int:
        """Spins per packed program: the chip's, or those clear of the stuck spins a faulty chip's
        health probe found."""
        return int(self.chip.usable_spins)

    def args(self, machine) -> tuple:
        """The stage record of the compiled sharing (:func:`.compiled_stages.solve_problems`): rule ids,
        coefficient limits, spins, packing capacity, reads and the session's ``machine`` record."""
        return (self.rule_ids, *self.limits, int(self.chip.spec.n_spins), self.capacity(), self.config.reads,
                machine)
