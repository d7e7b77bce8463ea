"""Compiled one-hot subproblem solve of the clustered Ising tour (paper 5.2): the one implementation.

Contract: :func:`solve_order` solves one open-path subproblem (cluster order, local TSP or refinement
patch): penalty, one-hot Ising model, spin-budget branching above the budget, per attempt a seed from the
construction's ``numpy.random.Generator``, the programs on the logical solver or, quantized by one rule,
on the chip, decode and the cheapest valid order; each attempt's calls and emulation seconds are
returned for the caller to charge.  Oracle: ``tests/tour_reference.py``; design: docs/design/ising_tour.md.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from ising_backend import quantize_rules, solve_submit, submit_packs
from ising_backend.mapping.branching import branch_stack, frozen_spins
from planners.ising.tour.kernels import best_onehot, expand_branches, onehot_ising

__all__ = ["solve_order", "OrderOptions", "OrderStats", "OrderOut", "SOLVED", "UNSOLVED", "TOO_MANY_BITS",
           "UNQUANTIZABLE"]

SOLVED, UNSOLVED, TOO_MANY_BITS, UNQUANTIZABLE = 0, 1, 2, 3


class OrderOptions(NamedTuple):
    """:func:`solve_order`'s settings."""

    margin_factor: float  # the one-hot penalty over the largest weight
    max_retries: int
    num_reads: int
    budget: int  # the spin budget of one program
    max_bits: int  # the most frozen spins (branching bits)
    rule: int  # the chip's quantization rule id
    Lh: float  # and its limits
    Lj: float


class OrderStats(NamedTuple):
    """:func:`solve_order`'s counts."""

    programs: int  # for TOO_MANY_BITS: the bits needed
    reads: int
    valid_reads: int
    valid_programs: int
    retries: int
    unsolved: int  # 0/1
    subproblems: int
    valid_subproblems: int


class OrderOut(NamedTuple):
    """:func:`solve_order`'s result."""

    status: int  # SOLVED, UNSOLVED, TOO_MANY_BITS or UNQUANTIZABLE
    order: np.ndarray  # (s,) or (0,)
    stats: OrderStats
    calls: np.ndarray  # per attempt: its calls
    emu: np.ndarray  # and emulation seconds


@numba.njit(cache=True)
def solve_order(rng, d, entry, ex, options, solver, machine):
    """Best valid order of one one-hot open-path subproblem (module docstring).

    ``options`` an :class:`OrderOptions`; ``solver`` = the logical solver's session record
    (:meth:`~ising_backend.MachineSession.args_for`) and ``machine`` None, or ``solver`` None and ``machine``
    the chip's (:attr:`~ising_backend.MachineSession.args`): programs quantized by ``rule`` within ``Lh`` /
    ``Lj``.  The unused record is None, so numba prunes its branch before typing: a logical solve does not
    compile the chip's submission (cold start).  Returns an :class:`OrderOut`: :data:`SOLVED`,
    :data:`UNSOLVED` (no valid read after the retries), :data:`TOO_MANY_BITS` (``stats.programs`` holds
    the bits needed) or :data:`UNQUANTIZABLE` (a non-finite coefficient).
    """
    max_retries, num_reads, budget = options.max_retries, options.num_reads, options.budget
    s = d.shape[0]
    n = s * s
    w_max = 0.0
    for i in range(s):
        w_max = max(w_max, abs(entry[i]), abs(ex[i]))
        for j in range(s):
            w_max = max(w_max, abs(d[i, j]))
    A = 1.0 * (options.margin_factor * w_max + 1.0)
    h, J, off = onehot_ising(d, entry, ex, A, 1.0)
    programs = reads = valid_reads = valid_programs = retries = subproblems = valid_subproblems = 0
    calls = np.zeros(max_retries + 1, dtype=np.int64)
    emu = np.zeros(max_retries + 1)
    none = np.zeros(0, dtype=np.int64)
    k = max(n - budget, 0)
    if k > options.max_bits:
        return OrderOut(TOO_MANY_BITS, none, OrderStats(k, 0, 0, 0, 0, 0, 0, 0), calls[:0], emu[:0])
    if k:
        frozen = frozen_spins(h, J, k)
        free, hb, Jb, _offs = branch_stack(h, J, off, frozen)
        B = hb.shape[0]
        nf = free.shape[0]
        Js = np.empty((B, nf, nf))
        for b in range(B):
            Js[b] = Jb
    else:  # the model as it is: one program
        frozen = np.zeros(0, dtype=np.int64)
        free = np.arange(n)
        hb = h.reshape(1, n).copy()
        Jb = J
        Js = J.reshape(1, n, n).copy()
        B, nf = 1, n
    if machine is not None:  # every branch program quantized by the rule, as the chip takes it
        rules = np.full(1, options.rule, dtype=np.int64)
        for b in range(B):
            codes, qh, qJ = quantize_rules(hb[b], Jb, rules, options.Lh, options.Lj, True, 95.0)
            if codes[0] != 0:
                return OrderOut(UNQUANTIZABLE, none, OrderStats(0, 0, 0, 0, 0, 0, 0, 0), calls[:0], emu[:0])
            hb[b] = qh[0]
            Js[b] = qJ[0]
    for attempt in range(max_retries + 1):
        seed = rng.integers(0, 9223372036854775807)
        # one branch each, pruned where its record is None (numba prunes only on a None argument)
        if solver is not None:
            spins = np.empty((B, num_reads, nf), dtype=np.int8)
            emu[attempt] = solve_submit(hb, Js, num_reads, seed, solver, spins, np.zeros((B, num_reads)))
        if machine is not None:
            spins, _sub, emu[attempt] = submit_packs(hb, Js, num_reads, np.uint64(seed), machine)
        calls[attempt] = B * num_reads
        if k:
            bits = expand_branches(spins, free, frozen, n)
        else:
            bits = np.empty((num_reads, n), dtype=np.uint8)
            for r in range(num_reads):
                for v in range(n):
                    bits[r, v] = 1 if spins[0, r, v] > 0 else 0
        valid, best, orders = best_onehot(bits, s, d, entry, ex)
        nv = 0
        for r in range(B * num_reads):
            nv += valid[r]
        programs += B
        reads += B * num_reads
        valid_reads += nv
        for b in range(B):
            any_b = 0
            for r in range(num_reads):
                any_b |= valid[b * num_reads + r]
            valid_programs += any_b
        subproblems += 1
        valid_subproblems += nv > 0
        if best >= 0:
            stats = OrderStats(programs, reads, valid_reads, valid_programs, retries, 0, subproblems, valid_subproblems)
            return OrderOut(SOLVED, orders[best].copy(), stats, calls[: attempt + 1], emu[: attempt + 1])
        retries += 1
    stats = OrderStats(programs, reads, valid_reads, valid_programs, retries, 1, subproblems, valid_subproblems)
    return OrderOut(UNSOLVED, none, stats, calls, emu)
