"""Compiled search loop of Ising pathfinding (paper 5.1, Algorithm 1): the one implementation.

Contract: :func:`run_query` runs one query (ranking, patch programs memoised in a :class:`ProgramPool`,
chip seeds from the query's ``numpy.random.Generator``, one submission per step through
:func:`ising_backend.submit_packs`, decoding, scoring, win draws) and returns each submission's calls
and emulation seconds for the caller to charge; a merge style that does not fit a program is skipped and
counted.  Oracle: ``tests/path_reference.py``; design notes: docs/design/ising_path.md.
"""

from __future__ import annotations


import numba
import numpy as np
from numba import types
from numba.typed import Dict

from ising_backend import fill_packs, merge_styles_flat, pack_layout, submit_packs
from ising_backend.numeric import ising_of_qubo
from planners.ising.path.kernels import extract_path, rank_local_targets, score_patch_samples
from planners.ising.path.qubo import _patch_qubo_kernel

__all__ = ["ProgramPool", "run_query", "REACHED", "BUDGET_SPENT", "EXHAUSTED", "COUNT_NAMES", "QUERY_OPTIONS"]

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


class ProgramPool:
    """Memoised patch programs of one planner as compiled arrays (cleared when full)."""

    def __init__(self, n_cells: int, n_styles: int, n_spins: int, budget_bytes: int = 48 << 20):
        self._shape = (n_cells, n_styles, n_spins, budget_bytes)
        nv = max(n_cells - 2, 1)
        N = max(int(n_spins), 1)
        cap = int(max(64, min(4096, budget_bytes // max(1, n_styles * N * N * 2))))
        self.keys = Dict.empty(key_type=types.int64, value_type=types.int64)
        self.count = np.zeros(1, dtype=np.int64)
        self.n_var = np.zeros(cap, dtype=np.int64)
        self.cells = np.zeros((cap, nv), dtype=np.int64)
        self.lh = np.zeros((cap, nv))
        self.lJ = np.zeros((cap, nv, nv))
        self.loff = np.zeros(cap)
        self.width = np.zeros(cap, dtype=np.int64)
        # a slot's k chip programs of width w, C order in the first k*w (k*w*w) entries: the
        # integer coefficients the chip takes, handed to its kernel as they are
        self.ph = np.zeros((cap, n_styles * N), dtype=np.int16)
        self.pJ = np.zeros((cap, n_styles * N * N), dtype=np.int16)
        self.ptr = np.zeros((cap, n_styles, nv + 1), dtype=np.int64)
        self.idx = np.zeros((cap, n_styles, N), dtype=np.int64)
        self.status = np.zeros((cap, n_styles), dtype=np.int64)  # merge code per style (0: fits)
        self.comp = np.zeros((cap, n_cells), dtype=np.bool_)  # the slot's problem, checked on a hashed key
        self.target = np.zeros(cap, dtype=np.int64)

        self._tables = (self.count, self.n_var, self.cells, self.lh, self.lJ, self.loff, self.width,
                        self.ph, self.pJ, self.ptr, self.idx, self.status, self.comp, self.target)

    def arrays(self) -> tuple:
        """``(keys, tables)``: the typed dict apart from the tuple of arrays (a tuple holding a typed
        dict is typed in Python on every compiled call; a tuple of arrays is not)."""
        return self.keys, self._tables

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
def _program(pool, comp, target, adj4, diag, degree, coef, scale, style_ids, Lh, Lj, n_spins):
    """Pool slot of the patch program (built and merged on a miss; a style that does not fit has a
    non-zero ``status`` and no program)."""
    keys, count, n_var, cells, lh, lJ, loff, width, ph, pJ, ptr, idx, status, pcomp, ptarget = pool
    n = comp.shape[0]
    key = _key(comp, target)
    if key in keys:
        slot = keys[key]
        if n <= _EXACT_KEY_CELLS or (ptarget[slot] == target and np.array_equal(pcomp[slot], comp)):
            return slot
    var, qv, Qv, off = _patch_qubo_kernel(adj4, diag, comp, n // 2, target, degree, coef[0], coef[1], coef[2],
                                          coef[3], coef[4])
    m = var.shape[0]
    h, J, o = ising_of_qubo(qv, Qv, off)
    if count[0] >= n_var.shape[0]:  # full: start over (a cache; results do not depend on it)
        keys.clear()
        count[0] = 0
    slot = count[0]
    w = 0
    status[slot, :] = 0
    if m > 0:  # every style's mapping, straight into the slot
        H = np.empty(m, dtype=np.int64)
        C = np.empty((m, m), dtype=np.int64)
        for i in range(m):
            H[i] = np.int64(np.rint(h[i] * scale))
            for j in range(m):
                C[i, j] = np.int64(np.rint(J[i, j] * scale))
        w = merge_styles_flat(H, C, style_ids, Lh, Lj, Lj, n_spins, ph[slot], pJ[slot], ptr[slot], idx[slot],
                              status[slot])
    count[0] += 1
    keys[key] = slot
    pcomp[slot] = comp
    ptarget[slot] = target
    n_var[slot] = m
    cells[slot, :m] = var
    lh[slot, :m] = h
    lJ[slot, :m, :m] = J
    loff[slot] = o
    width[slot] = w
    return slot


@numba.njit(cache=True)
def _submission(pool, slots, nb, k, pack, n_spins):
    """The chip programs of one step: the fitting styles of the problems ``slots[:nb]`` (those with
    variables), zero-padded to the widest (or block-packed into ``n_spins``-spin programs).

    Returns ``(h, J, rows (P, 2) = (slot, style), where (P, 2) = (program, first spin), sizes (P,))``."""
    n_var, width, ph, pJ, ptr, status = pool[2], pool[7], pool[8], pool[9], pool[10], pool[12]
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
    return h, J, rows, where, sizes


@numba.njit(cache=True)
def run_query(rng, keys, tables, padded, field, sr, sc, gr, gc, loop, machine):
    """One query of Algorithm 1 (see the module docstring); ``keys, tables`` are
    :meth:`ProgramPool.arrays`; ``loop`` is ``(nbr .. diag, coef, style_ids, options)``
    (:meth:`~.runner.QueryRunner.loop_args`): the patch frame's tables, the QUBO weights, the merge
    styles and a :data:`QUERY_OPTIONS` record (``per_call``: the local targets per submission);
    ``machine`` the session's record (:attr:`ising_backend.MachineSession.args`).

    Returns ``(status, pos_r, pos_c, walk (L, 2), counts (5,), mapping (k, 4), sub_calls, sub_emu,
    err (4,), err_comp (n,))``: counts = patch_solves, anneal_calls, segments, backtracks,
    direct_moves; mapping rows per style = reads, valid reads, wins, map_errors; per chip submission
    its calls and emulation seconds; ``err`` = (row, col, local target, style) of the first program
    a style could not map (``-1`` if none) and ``err_comp`` its free-cell mask.
    """
    nbr, ring, offsets, adj4, diag, coef, style_ids, options = loop
    count, n_var, cells_p, lh, lJ, loff, width, ph, pJ, ptr, idx, status_p, pcomp, ptarget = tables
    o = options[0]
    size, interior, merged, backtrack = o.size, o.interior, o.merged, o.backtrack
    num_reads, per_call, pack, max_attempts, max_calls = o.num_reads, o.per_call, o.pack, o.max_attempts, o.max_calls
    degree, scale, Lh, Lj, n_spins, free_cells = o.degree, o.scale, o.Lh, o.Lj, o.n_spins, o.free_cells
    pool = (keys, count, n_var, cells_p, lh, lJ, loff, width, ph, pJ, ptr, idx, status_p, pcomp, ptarget)
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
        comp, ranked = rank_local_targets(padded, pr, pc, gr, gc, size, nbr, ring, excluded, interior, merged, field)
        if ranked.shape[0] == 0:
            if backtrack and nseg > 0:
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
        if count[0] + nb > n_var.shape[0]:  # the step's programs must not evict each other
            keys.clear()
            count[0] = 0
        on_chip = 0
        for b in range(nb):
            slots[b] = _program(pool, comp, ranked[b], adj4, diag, degree, coef, scale, style_ids, Lh, Lj, n_spins)
            sl = slots[b]
            fits[b] = 0
            if n_var[sl] == 0:
                continue
            for s in range(k):
                if status_p[sl, s] == 0:
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
                h, J, rows, where, sizes = _submission(pool, slots, nb, k, pack, n_spins)
                hf, Jf = h.astype(np.float64), J.astype(np.float64)
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
                    spins, ptr[sl], idx[sl], m, cells, centre, li, nbr, lh[sl, :m], lJ[sl, :m, :m], loff[sl])
            else:
                w = 0
                for q in range(P):
                    w = max(w, sizes[at + q])
                sp = np.zeros((P, num_reads, w), dtype=np.int8)
                for q in range(P):
                    f = where[at + q, 1]
                    sp[q, :, : sizes[at + q]] = spins[where[at + q, 0], :, f: f + sizes[at + q]]
                n_valid, best, energy, logical = score_patch_samples(
                    sp, ptr[sl][rows[at: at + P, 1]], idx[sl][rows[at: at + P, 1]], m, cells, centre, li, nbr,
                    lh[sl, :m], lJ[sl, :m, :m], loff[sl])
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
    return status, pr, pc, walk[:wl], counts, mapping, sub_calls[:nsub], sub_emu[:nsub], err, err_comp
