"""A stack of QUBOs to packed chip programs in one compiled step: map by every rule, pack, check.

Contract: :func:`pack_qubo_stack` converts ``P`` zero-padded QUBOs to Ising form, quantizes each by every
rule of the portfolio, packs the ``P x k`` programs (program ``p * k + r``: QUBO ``p`` under rule ``r``)
first-fit decreasing on disjoint blocks and checks them against the chip's limits; :func:`submit_packs`
anneals them through the caller's machine session record.  Every layer's chip submission goes through
:func:`submit_packs`.  Design notes: docs/design/machine_link.md.
"""

from __future__ import annotations

import numba
import numpy as np

from ising_backend.mapping._quantize_kernel import quantize_rules
from ising_backend.mapping.blocks import fill_packs, pack_layout
from ising_backend.machines.link import anneal_submit
from ising_backend.mapping.numeric import ising_of_qubo
from ising_backend.machines.programs import programs_fit

__all__ = ["pack_qubo_stack", "submit_packs", "STACK_OK", "STACK_NONFINITE", "STACK_UNFIT"]

#: :func:`pack_qubo_stack`'s status: programs ready; a quantized coefficient not finite; a program
#: outside the chip's symmetric coefficient limits (the chip's own check would refuse it).
STACK_OK, STACK_NONFINITE, STACK_UNFIT = 0, 1, 2


@numba.njit(cache=True)
def pack_qubo_stack(q, Q, sizes, rules, Lh, Lj, capacity):
    """The submission of QUBO stack ``q (P, f)``, ``Q (P, f, f)`` (``sizes[p]`` free spins each) under
    the rule ids ``rules`` (module docstring).  Returns ``(status, h (packs, W), J (packs, W, W),
    where (P * k, 2))``; ``status`` is :data:`STACK_OK` or why nothing should be annealed."""
    P, f = q.shape
    k = rules.shape[0]
    bad = False
    qh = np.zeros((P * k, f))
    qJ = np.zeros((P * k, f, f))
    for p in range(P):
        n = sizes[p]
        h, J, _offset = ising_of_qubo(q[p, :n], Q[p, :n, :n], 0.0)
        st, hq, Jq = quantize_rules(h, J, rules, Lh, Lj, True, 95.0)
        for r in range(k):
            bad = bad or st[r] != 0
            qh[p * k + r, :n] = hq[r]
            qJ[p * k + r, :n, :n] = Jq[r]
    prog_sizes = np.empty(P * k, dtype=np.int64)
    for p in range(P):
        for r in range(k):
            prog_sizes[p * k + r] = sizes[p]
    pack_of, order, n_packs, width = pack_layout(prog_sizes, capacity)
    h, J, where = fill_packs(qh, qJ, prog_sizes, order, pack_of, n_packs, width)
    status = STACK_NONFINITE if bad else (STACK_OK if programs_fit(h, J, -Lh, Lh, -Lj, Lj) else STACK_UNFIT)
    return status, h, J, where


@numba.njit(cache=True, inline="always")  # inlined: no link level of its own above the anneal (compile time)
def submit_packs(h, J, reads, seed, machine):
    """One submission of the packed programs ``h (packs, W)``, ``J (packs, W, W)``: ``reads`` reads each
    (0: nothing is annealed) on the anneal record ``machine`` with ``seed``.  Returns ``(spins (packs,
    reads, W), calls, emulation_s)``, the calls and seconds for the session to settle."""
    n_packs, width = J.shape[0], J.shape[1]
    spins = np.zeros((n_packs, reads, width), dtype=np.int8)
    if reads == 0:
        return spins, 0, 0.0
    energies = np.empty((n_packs, reads))
    emu = anneal_submit(h, J, reads, seed, machine, spins, energies)
    return spins, n_packs * reads if width > 0 else 0, emu
