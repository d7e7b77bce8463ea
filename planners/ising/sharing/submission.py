"""A stage's chip submission of Ising target sharing (paper 5.3): map, pack, anneal, decode.

Contract: :func:`run_stage` does what ``reference_solve_packed`` (``tests/sharing_reference.py``)
does with its separate calls: every split x quantization rule mapped and block-packed first-fit
decreasing into shared chip programs (:func:`ising_backend.pack_qubo_stack`), annealed through the
session's record (:func:`ising_backend.anneal_submit`: the emulator's kernel, or a callback into any
machine's ``anneal_batch``), every read decoded, checked and scored on the unquantized cut
(:func:`.kernels.score_stage`, :func:`.kernels.candidate_sides`).  It returns the calls and the
measured emulation seconds for the session's ``settle``.  A stage the chip would refuse (a
non-finite quantized coefficient, a program outside the chip's coefficient limits) comes back with
that status and nothing annealed; the caller names it (:func:`stage_refusal`).  Three small compiled
steps under a Python function: each compiles on its own, and the per-call cost (tens of microseconds)
is small beside a submission's anneal.
"""

from __future__ import annotations

import numpy as np

from ising_backend import (QUANTIZE_RULE_IDS, STACK_NONFINITE, STACK_OK, STACK_UNFIT, anneal_submit, pack_qubo_stack,
                           via_callback)
from planners.ising.sharing.kernels import candidate_sides, score_stage

__all__ = ["run_stage", "StageSolver", "stage_refusal", "STAGE_OK", "STAGE_NONFINITE", "STAGE_UNFIT"]

STAGE_OK, STAGE_NONFINITE, STAGE_UNFIT = STACK_OK, STACK_NONFINITE, STACK_UNFIT


def run_stage(problems, program, seed, machine, dist, n_robots):
    """One stage submission (module docstring) of the split ``problems = (q (P, f), Q (P, f, f), free (P, f),
    sizes (P,), anchors (P, 2), reject (P,), nfix (P,), fixed (P, f))`` (spin-budget branches: the ``nfix[p]``
    nodes after the free ones frozen at spins ``fixed[p]``) under ``program = (rule ids, Lh, Lj, capacity,
    reads)``, annealed with ``seed`` on the session record ``machine``, scored on ``dist``.  Returns
    ``(status, calls, emulation_s, n_valid, best, c_split, c_cut, side0, n0, side1, n1)`` (the last seven
    as :func:`.kernels.score_stage` and :func:`.kernels.candidate_sides`)."""
    q, Q, free, sizes, anchors, reject, nfix, fixed = problems
    rules, Lh, Lj, capacity, num_reads = program
    P, k, f = sizes.shape[0], rules.shape[0], free.shape[1]
    if via_callback(machine):  # a machine behind the callback: packs up to its usable spins, as the checked path
        capacity = max(capacity, int(sizes.max()))
    status, h, J, where = pack_qubo_stack(q, Q, sizes, rules, Lh, Lj, capacity)
    if status != STACK_OK:
        e = np.zeros(0, dtype=np.int64)
        return (status, 0, 0.0, np.zeros((P, k), dtype=np.int64), np.zeros((P, k)), e, np.zeros(0),
                np.zeros((0, f + 1), dtype=np.int64), e, np.zeros((0, f + 1), dtype=np.int64), e)
    n_packs, width = J.shape[0], J.shape[1]
    spins = np.empty((n_packs, num_reads, width), dtype=np.int8)
    energies = np.empty((n_packs, num_reads))
    emu = anneal_submit(h, J, num_reads, seed, machine, spins, energies)
    calls = n_packs * num_reads if width > 0 else 0
    n_valid, best, c_split, c_cut, c_side = score_stage(spins, where, sizes, k, free, anchors, dist, n_robots, reject,
                                                        nfix, fixed)
    s0, n0, s1, n1 = candidate_sides(c_split, c_side, free, sizes + nfix, anchors)
    return STAGE_OK, calls, emu, n_valid, best, c_split, c_cut, s0, n0, s1, n1


def stage_refusal(status: int) -> str:
    """The failure of a stage :func:`run_stage` would not submit (its ``status``)."""
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
        self.n_spins = int(chip.spec.n_spins)
        self.meter = None

    def capacity(self) -> int:
        """Spins per packed program: the chip's, or those clear of the stuck spins a faulty chip's
        health probe found."""
        return int(self.chip.usable_spins)

    def program(self) -> tuple:
        """:func:`run_stage`'s ``program`` record: rule ids, coefficient limits, packing capacity, reads."""
        return self.rule_ids, *self.limits, self.capacity(), self.config.reads

    def submit(self, problems, seed: int, machine, score_w, n_robots: int):
        """:func:`run_stage` of ``problems`` with this solver's program on the session record ``machine``."""
        return run_stage(problems, self.program(), np.uint64(seed), machine, score_w, n_robots)
