"""The chip side of Ising target sharing (paper 5.3): a stage's program record and its refusals.

Contract: :class:`StageSolver` holds what a stage's one chip submission (:func:`.stage_steps.submit_stage`:
every split x rule mapped, block-packed, annealed, decoded and scored) needs: the portfolio's rule ids,
the chip's coefficient limits and spins, the machine and the running call's meter (whose ledger the
call's session charges); :func:`stage_refusal` names a refused stage program.
Design notes: docs/design/ising_sharing.md.
"""

from __future__ import annotations

import numpy as np

from ising_backend import QUANTIZE_RULE_IDS, STACK_NONFINITE
from planners.ising.sharing.stage_steps import StageProgram

__all__ = ["StageSolver", "stage_refusal"]


def stage_refusal(status: int) -> str:
    """The failure of a stage the chip would refuse (the :func:`ising_backend.pack_qubo_stack` ``status``)."""
    if status == STACK_NONFINITE:
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
        self.n_spins = int(chip.spec.n_spins)
        self.meter = None

    def capacity(self) -> int:
        """Spins per packed program: the chip's, or those clear of the stuck spins a faulty chip's
        health probe found."""
        return int(self.chip.usable_spins)

    def program(self) -> StageProgram:
        """The stage steps' ``program`` record (:func:`.stage_steps.solve_splits`)."""
        Lh, Lj = self.limits
        return StageProgram(rules=self.rule_ids, Lh=Lh, Lj=Lj, capacity=self.capacity(), num_reads=int(self.config.reads),
                            n_spins=self.n_spins, retries=int(self.config.retries))
