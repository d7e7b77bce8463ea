"""Compiled search loop of Ising pathfinding (paper 5.1, Algorithm 1): the one implementation.

Contract: :func:`run_query` runs one query (ranking, patch programs memoised in a :class:`ProgramPool`,
chip seeds from the query's ``numpy.random.Generator``, one submission per step through
:func:`ising_backend.submit_packs`, decoding, scoring, win draws) and returns each submission's calls
and emulation seconds for the caller to charge; a merge style that does not fit a program is skipped and
counted.  Oracle: ``tests/path_reference.py``; design notes: docs/design/ising_path.md.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np
from numba import types
from numba.typed import Dict

from ising_backend import fill_packs, merge_styles_flat, pack_layout, submit_packs
from ising_backend.mapping.numeric import ising_of_qubo
from planners.ising.path.kernels import extract_path, rank_local_targets, score_patch_samples
from planners.ising.path.qubo import _patch_qubo_kernel

__all__ = ["ProgramPool", "PoolTables", "QueryLoop", "QueryOut", "run_query", "REACHED", "BUDGET_SPENT", "EXHAUSTED", "COUNT_NAMES", "QUERY_OPTIONS"]

REACHED, BUDGET_SPENT, EXHAUSTED = 0, 1, 2
COUNT_NAMES = ("patch_solves", "anneal_calls", "segments", "backtracks", "direct_moves")
_EXACT_KEY_CELLS = 55  # patches up to 7x7: the key is the free-cell mask itself

#: The scalar arguments of :func:`run_query` as one record (a numpy structured array of one row:
#: cheaper to hand to compiled code than the scalars one by one): the search options, the budgets,
#: the mapping scale and limits.
QUERY_OPTIONS = np.dtype([
    ("size", np.int64), ("interior", np.bool_), ("merged", np.bool_), ("backtrack", np.bool_),
    ("num_reads", np.int64), ("per_call", np.int64), ("pack", np.bool_), ("max_attempts", np.int64),
    ("max_calls", np.int64), ("degree", np.bool_), ("scale", np.float64), ("Lh", np.int64), ("Lj", np.int64),
    ("n_spins", np.int64), ("free_cells", np.int64),
])


class PoolTables(NamedTuple):
    """A :class:`ProgramPool`'s arrays, one row (slot) per memoised patch problem."""

    count: np.ndarray  # (1,) slots in use
    n_var: np.ndarray  # the problem's variables (free patch cells but the centre)
    cells: np.ndarray  # their patch cells
    lh: np.ndarray  # the logical Ising model: h
    lJ: np.ndarray  # J
    loff: np.ndarray  # offset
    width: np.ndarray  # the widest style's spins
    ph: np.ndarray  # each style's chip program, C order in the first k * width (k * width^2) entries: h
    pJ: np.ndarray  # J
    ptr: np.ndarray  # each style's spin groups per variable (merge pointers)
    idx: np.ndarray  # and their spins
    status: np.ndarray  # merge code per style (0: fits)
    comp: np.ndarray  # the problem's free-cell mask (checked on a hashed key)
    target: np.ndarray  # its local target


class QueryLoop(NamedTuple):
    """What :func:`run_query` needs of a grid and configuration (:meth:`~.runner.QueryRunner.loop_args`)."""

    nbr: np.ndarray  # the patch frame's neighbour table
    ring: np.ndarray  # its ring of local targets
    offsets: np.ndarray  # each patch cell's (row, col) offset from the centre
    adj4: np.ndarray  # its 4-adjacency
    diag: np.ndarray  # and diagonal pairs
    coef: np.ndarray  # the QUBO weights (C, B, Dg, A_end, A)
    style_ids: np.ndarray  # the merge styles tried
    options: np.ndarray  # one QUERY_OPTIONS record


class QueryOut(NamedTuple):
    """:func:`run_query`'s result."""

    status: int  # REACHED, BUDGET_SPENT or EXHAUSTED
    row: int  # where the walk ended
    col: int
    walk: np.ndarray  # (L, 2) the cells walked, segments and backtracks stitched
    counts: np.ndarray  # (5,) by COUNT_NAMES
    mapping: np.ndarray  # (k, 4) per style: reads, valid reads, wins, map_errors
    sub_calls: np.ndarray  # per chip submission: its calls
    sub_emu: np.ndarray  # and emulation seconds
    err: np.ndarray  # (row, col, local target, style) of the first program a style could not map (-1: none)
    err_comp: np.ndarray  # its free-cell mask


class Submission(NamedTuple):
    """The chip programs of one step (:func:`_submission`)."""

    h: np.ndarray  # (P, W) program fields
    J: np.ndarray  # (P, W, W) couplings
    rows: np.ndarray  # (P, 2) = (slot, style) of each problem program
    where: np.ndarray  # (P, 2) = (chip program, first spin) holding it
    sizes: np.ndarray  # (P,) its spins


class ProgramPool:
    """Memoised patch programs of one planner as compiled arrays (cleared when full)."""

    def __init__(self, n_cells: int, n_styles: int, n_spins: int, budget_bytes: int = 48 << 20):
        self._shape = (n_cells, n_styles, n_spins, budget_bytes)
        nv = max(n_cells - 2, 1)
        N = max(int(n_spins), 1)
        cap = int(max(64, min(4096, budget_bytes // max(1, n_styles * N * N * 2))))
        self.keys = Dict.empty(key_type=types.int64, value_type=types.int64)
        # the chip programs are the integer coefficients the chip takes, handed to its kernel as they are
        self.tables = PoolTables(
            count=np.zeros(1, dtype=np.int64), n_var=np.zeros(cap, dtype=np.int64),
            cells=np.zeros((cap, nv), dtype=np.int64), lh=np.zeros((cap, nv)), lJ=np.zeros((cap, nv, nv)),
            loff=np.zeros(cap), width=np.zeros(cap, dtype=np.int64),
            ph=np.zeros((cap, n_styles * N), dtype=np.int16), pJ=np.zeros((cap, n_styles * N * N), dtype=np.int16),
            ptr=np.zeros((cap, n_styles, nv + 1), dtype=np.int64), idx=np.zeros((cap, n_styles, N), dtype=np.int64),
            status=np.zeros((cap, n_styles), dtype=np.int64), comp=np.zeros((cap, n_cells), dtype=np.bool_),
            target=np.zeros(cap, dtype=np.int64))

    def arrays(self) -> tuple:
        """``(keys, tables)``: the typed dict apart from the :class:`PoolTables` (a record holding a typed
        dict is typed in Python on every compiled call; a record of arrays is not)."""
        return self.keys, self.tables

    def __deepcopy__(self, memo) -> "ProgramPool":
        """An empty pool of the same size (a memo: a copy's plans are the same without its entries;
        the typed dict cannot be copied)."""
        return ProgramPool(*self._shape)


@numba.njit(cache=True)
def _key(comp, target):
    """The pool key of a problem: the free-cell mask and target themselves up to 7x7 patches, a
    hash beyond (checked against the slot's problem)."""
    n = comp.shape[0]
    if n <= _EXACT_KEY_CELLS:
        key = np.int64(target)
        for i in range(n):
            if comp[i]:
                key |= np.int64(1) << np.int64(i + 8)
        return key
    key = np.uint64(14695981039346656037) ^ np.uint64(target)
    for i in range(n):
        key = (key ^ np.uint64(comp[i])) * np.uint64(1099511628211)
    return np.int64(key >> np.uint64(1))


@numba.njit(cache=True)
def _program(keys, t, comp, target, loop):
    """Pool slot (of ``keys`` and :class:`PoolTables` ``t``) of the patch program (built and merged on a
    miss; a style that does not fit has a non-zero ``status`` and no program)."""
    n = comp.shape[0]
    key = _key(comp, target)
    if key in keys:
        slot = keys[key]
        if n <= _EXACT_KEY_CELLS or (t.target[slot] == target and np.array_equal(t.comp[slot], comp)):
            return slot
    o = loop.options[0]
    coef = loop.coef
    var, qv, Qv, off = _patch_qubo_kernel(loop.adj4, loop.diag, comp, n // 2, target, o.degree, coef[0], coef[1],
                                          coef[2], coef[3], coef[4])
    m = var.shape[0]
    h, J, offset = ising_of_qubo(qv, Qv, off)
    if t.count[0] >= t.n_var.shape[0]:  # full: start over (a cache; results do not depend on it)
        keys.clear()
        t.count[0] = 0
    slot = t.count[0]
    w = 0
    t.status[slot, :] = 0
    if m > 0:  # every style's mapping, straight into the slot
        H = np.empty(m, dtype=np.int64)
        C = np.empty((m, m), dtype=np.int64)
        for i in range(m):
            H[i] = np.int64(np.rint(h[i] * o.scale))
            for j in range(m):
                C[i, j] = np.int64(np.rint(J[i, j] * o.scale))
        w = merge_styles_flat(H, C, loop.style_ids, o.Lh, o.Lj, o.Lj, o.n_spins, t.ph[slot], t.pJ[slot], t.ptr[slot],
                              t.idx[slot], t.status[slot])
    t.count[0] += 1
    keys[key] = slot
    t.comp[slot] = comp
    t.target[slot] = target
    t.n_var[slot] = m
    t.cells[slot, :m] = var
    t.lh[slot, :m] = h
    t.lJ[slot, :m, :m] = J
    t.loff[slot] = offset
    t.width[slot] = w
    return slot


@numba.njit(cache=True)
def _submission(t, slots, nb, k, pack, n_spins):
    """The :class:`Submission` of one step: the fitting styles of the problems ``slots[:nb]`` (those with
    variables) of :class:`PoolTables` ``t``, zero-padded to the widest (or block-packed into ``n_spins``-spin
    programs)."""
    n_var, width, ph, pJ, ptr, status = t.n_var, t.width, t.ph, t.pJ, t.ptr, t.status
    P = 0
    W = 0
    for b in range(nb):
        sl = slots[b]
        if n_var[sl] > 0:
            for s in range(k):
                P += status[sl, s] == 0
            W = max(W, width[sl])
    rows = np.empty((P, 2), dtype=np.int64)
    sizes = np.empty(P, dtype=np.int64)
    h = np.zeros((P, W), dtype=ph.dtype)
    J = np.zeros((P, W, W), dtype=pJ.dtype)
    p = 0
    for b in range(nb):
        sl = slots[b]
        if n_var[sl] == 0:
            continue
        w = width[sl]
        for s in range(k):
            if status[sl, s] != 0:
                continue
            rows[p, 0], rows[p, 1] = sl, s
            sizes[p] = ptr[sl, s, n_var[sl]]
            h[p, :w] = ph[sl, s * w:(s + 1) * w]
            J[p, :w, :w] = pJ[sl, s * w * w:(s + 1) * w * w].reshape((w, w))
            p += 1
    where = np.zeros((P, 2), dtype=np.int64)
    for q in range(P):
        where[q, 0] = q
    if pack and P > 1:
        pack_of, order, n_packs, width_p = pack_layout(sizes, n_spins)
        h, J, where = fill_packs(h, J, sizes, order, pack_of, n_packs, width_p)
    return Submission(h, J, rows, where, sizes)


@numba.njit(cache=True)
def run_query(rng, keys, tables, padded, field, sr, sc, gr, gc, loop, machine):
    """One query of Algorithm 1 (see the module docstring) from ``(sr, sc)`` to ``(gr, gc)``: ``keys,
    tables`` are :meth:`ProgramPool.arrays`, ``loop`` a :class:`QueryLoop` (its ``options``' ``per_call``:
    the local targets per submission), ``machine`` the session's record
    (:attr:`ising_backend.MachineSession.args`).  Returns a :class:`QueryOut`."""
    nbr, ring, offsets, style_ids = loop.nbr, loop.ring, loop.offsets, loop.style_ids
    n_var, cells_p, width, ph, pJ = tables.n_var, tables.cells, tables.width, tables.ph, tables.pJ
    o = loop.options[0]
    size, num_reads, per_call, pack = o.size, o.num_reads, o.per_call, o.pack
    max_attempts, max_calls, n_spins, free_cells = o.max_attempts, o.max_calls, o.n_spins, o.free_cells
    rad = size // 2
    n = size * size
    centre = n // 2
    k = style_ids.shape[0]
    per_target = k * num_reads
    cap = 2 * (free_cells + 2) * (n + 2) + 8
    walk = np.empty((cap, 2), dtype=np.int64)
    seg_cells = np.empty((cap, 2), dtype=np.int64)
    seg_start = np.empty(cap, dtype=np.int64)
    seg_len = np.empty(cap, dtype=np.int64)
    nfail = max_attempts * per_call + free_cells + 8
    f_pos = np.empty((nfail, 2), dtype=np.int64)
    f_cell = np.empty((nfail, 2), dtype=np.int64)
    sub_calls = np.zeros(max_attempts + 1, dtype=np.int64)
    sub_emu = np.zeros(max_attempts + 1)
    counts = np.zeros(5, dtype=np.int64)
    mapping = np.zeros((k, 4), dtype=np.int64)
    err = np.full(4, -1, dtype=np.int64)
    err_comp = np.zeros(n, dtype=np.bool_)
    visited = np.zeros(padded.shape, dtype=np.bool_)
    excluded = np.zeros(padded.shape, dtype=np.bool_)
    winners = np.empty(k, dtype=np.int64)
    slots = np.empty(per_call, dtype=np.int64)
    fits = np.empty(per_call, dtype=np.int64)
    spins = np.empty((0, num_reads, 0), dtype=np.int8)
    rows = np.empty((0, 2), dtype=np.int64)
    where = np.empty((0, 2), dtype=np.int64)
    sizes = np.empty(0, dtype=np.int64)
    pr, pc = sr, sc
    walk[0, 0], walk[0, 1] = sr, sc
    wl = 1
    visited[sr + rad, sc + rad] = True
    nseg = 0
    seg_top = 0
    nf = 0
    nsub = 0
    used = 0
    status = REACHED
    while not (pr == gr and pc == gc):
        if counts[0] >= max_attempts or used + per_target > max_calls:
            status = BUDGET_SPENT
            break
        excluded[:, :] = visited
        for t in range(nf):
            if f_pos[t, 0] == pr and f_pos[t, 1] == pc:
                excluded[f_cell[t, 0] + rad, f_cell[t, 1] + rad] = True
        comp, ranked = rank_local_targets(padded, pr, pc, gr, gc, size, nbr, ring, excluded, o.interior, o.merged,
                                          field)
        if ranked.shape[0] == 0:
            if o.backtrack and nseg > 0:
                nseg -= 1
                s0 = seg_start[nseg]
                L = seg_len[nseg]
                for t in range(L - 2, -1, -1):  # reversed(seg[:-1])
                    walk[wl, 0], walk[wl, 1] = seg_cells[s0 + t, 0], seg_cells[s0 + t, 1]
                    wl += 1
                pr, pc = seg_cells[s0, 0], seg_cells[s0, 1]
                seg_top = s0
                counts[3] += 1
                continue
            status = EXHAUSTED
            break
        # calls left in the budget limit how many targets share this submission
        room = min(max(1, (max_calls - used) // per_target), max_attempts - counts[0])
        nb = min(per_call, room, ranked.shape[0])
        if tables.count[0] + nb > n_var.shape[0]:  # the step's programs must not evict each other
            keys.clear()
            tables.count[0] = 0
        on_chip = 0
        for b in range(nb):
            slots[b] = _program(keys, tables, comp, ranked[b], loop)
            sl = slots[b]
            fits[b] = 0
            if n_var[sl] == 0:
                continue
            for s in range(k):
                if tables.status[sl, s] == 0:
                    fits[b] += 1
                else:
                    mapping[s, 3] += 1
                    if err[0] < 0:
                        err[0], err[1], err[2], err[3] = pr, pc, ranked[b], s
                        err_comp[:] = comp
            on_chip += fits[b] > 0
        # one target whose every style fits, unpacked: the slot's programs as they are (no copies)
        whole = nb == 1 and fits[0] == k and not pack
        if on_chip:
            seed = rng.integers(0, 9223372036854775807)
            # float64 programs: the one anneal specialization every layer shares (the same samples)
            if whole:
                w = width[slots[0]]
                hf = ph[slots[0], : k * w].reshape((k, w)).astype(np.float64)
                Jf = pJ[slots[0], : k * w * w].reshape((k, w, w)).astype(np.float64)
            else:
                sub = _submission(tables, slots, nb, k, pack, n_spins)
                rows, where, sizes = sub.rows, sub.where, sub.sizes
                hf, Jf = sub.h.astype(np.float64), sub.J.astype(np.float64)
            spins, _calls, sub_emu[nsub] = submit_packs(hf, Jf, num_reads, np.uint64(seed), machine)
            sub_calls[nsub] = spins.shape[0] * num_reads
            used += spins.shape[0] * num_reads
            nsub += 1
            counts[1] += 1
            counts[0] += on_chip
        chosen = -1
        direct = False
        path = np.zeros(0, dtype=np.int64)
        at = 0
        for b in range(nb):
            sl = slots[b]
            m = n_var[sl]
            cells = cells_p[sl, :m]
            li = ranked[b]
            if m == 0:
                if chosen < 0:
                    path = extract_path(np.zeros(0, dtype=np.bool_), cells, centre, li, nbr)
                    if path.shape[0] > 0:
                        chosen, direct = b, True
                continue
            P = fits[b]
            if P == 0:
                continue  # no style fits: counted above
            if whole:
                n_valid, best, energy, logical = score_patch_samples(
                    spins, tables.ptr[sl], tables.idx[sl], m, cells, centre, li, nbr, tables.lh[sl, :m],
                    tables.lJ[sl, :m, :m], tables.loff[sl])
            else:
                w = 0
                for q in range(P):
                    w = max(w, sizes[at + q])
                sp = np.zeros((P, num_reads, w), dtype=np.int8)
                for q in range(P):
                    f = where[at + q, 1]
                    sp[q, :, : sizes[at + q]] = spins[where[at + q, 0], :, f: f + sizes[at + q]]
                n_valid, best, energy, logical = score_patch_samples(
                    sp, tables.ptr[sl][rows[at: at + P, 1]], tables.idx[sl][rows[at: at + P, 1]], m, cells, centre,
                    li, nbr, tables.lh[sl, :m], tables.lJ[sl, :m, :m], tables.loff[sl])
            best_score = np.inf
            brow = -1
            for q in range(P):
                s = q if whole else rows[at + q, 1]
                mapping[s, 0] += num_reads
                mapping[s, 1] += n_valid[q]
                if energy[q] < best_score:
                    best_score = energy[q]
                    brow = q
            if brow >= 0 and chosen < 0:
                chosen = b
                tol = 1e-9 * max(1.0, abs(best_score))
                nw = 0
                for q in range(P):
                    if energy[q] <= best_score + tol:
                        winners[nw] = q if whole else rows[at + q, 1]
                        nw += 1
                x = np.empty(m, dtype=np.bool_)
                for i in range(m):
                    x[i] = logical[brow, best[brow], i] > 0
                path = extract_path(x, cells, centre, li, nbr)
                win = winners[rng.integers(0, nw)] if nw > 1 else winners[0]
                mapping[win, 2] += 1
            at += P
        if nf + nb > f_pos.shape[0]:  # failures without a chip call (no style fits) are not budgeted
            f_pos = np.concatenate((f_pos, np.empty_like(f_pos)))
            f_cell = np.concatenate((f_cell, np.empty_like(f_cell)))
        for b in range(nb if chosen < 0 else chosen):  # the targets ranked before the chosen one failed
            f_pos[nf, 0], f_pos[nf, 1] = pr, pc
            f_cell[nf, 0], f_cell[nf, 1] = pr + offsets[ranked[b], 0], pc + offsets[ranked[b], 1]
            nf += 1
        if chosen < 0:
            continue
        if direct:
            counts[4] += 1
        # the segment, cut where it passes the goal
        L = path.shape[0]
        for t in range(L):
            if pr + offsets[path[t], 0] == gr and pc + offsets[path[t], 1] == gc:
                L = t + 1
                break
        s0 = seg_top
        for t in range(L):
            seg_cells[s0 + t, 0] = pr + offsets[path[t], 0]
            seg_cells[s0 + t, 1] = pc + offsets[path[t], 1]
        for t in range(1, L):
            walk[wl, 0], walk[wl, 1] = seg_cells[s0 + t, 0], seg_cells[s0 + t, 1]
            wl += 1
        for t in range(L):
            visited[seg_cells[s0 + t, 0] + rad, seg_cells[s0 + t, 1] + rad] = True
        seg_start[nseg] = s0
        seg_len[nseg] = L
        nseg += 1
        seg_top = s0 + L
        counts[2] += 1
        pr, pc = seg_cells[s0 + L - 1, 0], seg_cells[s0 + L - 1, 1]
    return QueryOut(status, pr, pc, walk[:wl], counts, mapping, sub_calls[:nsub], sub_emu[:nsub], err, err_comp)
