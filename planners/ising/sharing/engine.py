"""A stage's chip submission of Ising target sharing (paper 5.3) in one compiled call.

Contract: :func:`run_stage` does what ``reference_solve_packed`` (``tests/sharing_reference.py``)
does with its separate calls -- every split x rule mapped (:func:`.kernels.map_stage`), packed first-fit
decreasing (:func:`ising_backend.pack_layout`), placed (:func:`ising_backend.fill_packs`), annealed on the
chip through :func:`ising_backend.anneal_submit` (the emulator's kernel, or a callback into any
machine's ``anneal_batch``; the seed ``anneal_batch`` would get), decoded and scored (:func:`.kernels.score_stage`, :func:`.kernels.candidate_sides`) --
and returns the same arrays, the calls and the measured emulation seconds for
:meth:`~ising_backend.EmulatedChip.charge`.  A stage it cannot run as the chip would (a
non-finite quantized coefficient: :data:`STAGE_NONFINITE`; a program outside the chip's symmetric
coefficient limits, which the chip's own check (:func:`ising_backend.programs_fit`) refuses:
:data:`STAGE_UNFIT`) comes back with that status and nothing annealed; the caller names it.
"""

from __future__ import annotations

import numba
import numpy as np

from ising_backend import anneal_submit, fill_packs, pack_layout, programs_fit, via_callback
from planners.ising.sharing.kernels import candidate_sides, map_stage, score_stage

__all__ = ["run_stage", "STAGE_OK", "STAGE_NONFINITE", "STAGE_UNFIT"]

STAGE_OK, STAGE_NONFINITE, STAGE_UNFIT = 0, 1, 2


@numba.njit(cache=True)
def run_stage(q, Q, sizes, rules, Lh, Lj, capacity, num_reads, seed, machine, free, anchors, dist, n_robots, reject,
              nfix, fixed):
    """One stage submission (module docstring).  Returns ``(status, calls, emulation_s, n_valid, best,
    c_split, c_cut, side0, n0, side1, n1)`` (the last seven as :func:`.kernels.score_stage` and
    :func:`.kernels.candidate_sides`)."""
    P = sizes.shape[0]
    k = rules.shape[0]
    f = free.shape[1]
    status, qh, qJ = map_stage(q, Q, sizes, rules, Lh, Lj)
    prog_sizes = np.empty(P * k, dtype=np.int64)
    for p in range(P):
        for r in range(k):
            prog_sizes[p * k + r] = sizes[p]
    if via_callback(machine):  # a machine behind the callback: packs up to its usable spins, as the checked path
        capacity = max(capacity, prog_sizes.max())
    pack_of, order, n_packs, width = pack_layout(prog_sizes, capacity)
    h, J, where = fill_packs(qh, qJ, prog_sizes, order, pack_of, n_packs, width)
    code = STAGE_NONFINITE if status.any() else (STAGE_OK if programs_fit(h, J, -Lh, Lh, -Lj, Lj) else STAGE_UNFIT)
    if code != STAGE_OK:
        e = np.zeros(0, dtype=np.int64)
        return (code, 0, 0.0, np.zeros((P, k), dtype=np.int64), np.zeros((P, k)), e, np.zeros(0),
                np.zeros((0, f + 1), dtype=np.int64), e, np.zeros((0, f + 1), dtype=np.int64), e)
    spins = np.empty((n_packs, num_reads, width), dtype=np.int8)
    energies = np.empty((n_packs, num_reads))
    emu = anneal_submit(h, J, num_reads, seed, machine, spins, energies)
    calls = n_packs * num_reads if width > 0 else 0
    n_valid, best, c_split, c_cut, c_side = score_stage(spins, where, sizes, k, free, anchors, dist, n_robots, reject,
                                                        nfix, fixed)
    s0, n0, s1, n1 = candidate_sides(c_split, c_side, free, sizes + nfix, anchors)
    return STAGE_OK, calls, emu, n_valid, best, c_split, c_cut, s0, n0, s1, n1
