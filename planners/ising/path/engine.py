"""Compiled search loop of Ising pathfinding (paper 5.1, Algorithm 1) on the emulated chip.

Contract: :func:`run_query` makes, for one query, the decisions of the Python loop in
:mod:`.search` (its reference; the tests compare both): the same ranking, patch programs,
chip seeds (drawn from the query's ``numpy.random.Generator``), annealing kernel and padding
(the chip's own :func:`~ising_backend.anneal.anneal_kernel` with
:meth:`~ising_backend.EmulatedChip.kernel_args`), decoding, scoring, win draws and
bookkeeping.  Each submission's calls and its measured emulation seconds (a monotonic clock
around the kernel) are returned, so the caller charges the chip exactly as
:meth:`~ising_backend.EmulatedChip.anneal_batch` would.

Patch programs are memoised in a :class:`ProgramPool` (compiled arrays keyed by free-cell
mask and local target).  A query whose program cannot be merged onto the chip returns
:data:`NEEDS_REFERENCE` so the caller reruns it with the Python loop (which names the error).
"""

from __future__ import annotations


import numba
import numpy as np
from numba import types
from numba.typed import Dict

from ising_backend import CallLedger, ChipUnavailableError, SolverOutputError, anneal_submit, merge_styles_flat
from planners.ising.fallback import unavailable_message
from planners.ising.numeric import pairwise_sum
from planners.ising.path.kernels import extract_path, rank_local_targets, score_patch_samples
from planners.ising.path.qubo import _patch_qubo_kernel

__all__ = ["ProgramPool", "CompiledSearch", "run_query", "REACHED", "BUDGET_SPENT", "EXHAUSTED",
           "NEEDS_REFERENCE"]

REACHED, BUDGET_SPENT, EXHAUSTED, NEEDS_REFERENCE = 0, 1, 2, 3
_COUNT_NAMES = ("patch_solves", "anneal_calls", "segments", "backtracks", "direct_moves")


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

        self._arrays = (self.keys, self.count, self.n_var, self.cells, self.lh, self.lJ, self.loff, self.width,
                        self.ph, self.pJ, self.ptr, self.idx)

    def arrays(self) -> tuple:
        return self._arrays

    def __deepcopy__(self, memo) -> "ProgramPool":
        """An empty pool of the same size (a memo: a copy's plans are the same without its entries;
        the typed dict cannot be copied)."""
        return ProgramPool(*self._shape)


@numba.njit(cache=True)
def _ising_of_qubo(q, Q, offset):
    """``ising_backend.ising_from_qubo``'s arithmetic (numpy's summation order)."""
    n = q.shape[0]
    h = np.empty(n)
    J = np.empty((n, n))
    row = np.empty(n)
    flat = np.empty(n * n)
    for i in range(n):
        for j in range(n):
            row[j] = Q[i, j] + Q[j, i]
            J[i, j] = Q[i, j] / 4.0
            flat[i * n + j] = Q[i, j]
        h[i] = q[i] / 2.0 + pairwise_sum(row, 0, n) / 4.0
    return h, J, offset + pairwise_sum(q, 0, n) / 2.0 + pairwise_sum(flat, 0, n * n) / 4.0


@numba.njit(cache=True)
def _program(keys, count, n_var, cells, lh, lJ, loff, width, ph, pJ, ptr, idx, comp, target, adj4, diag, degree,
             coef, scale, style_ids, Lh, Lj, n_spins):
    """Pool slot of the patch program (built and merged on a miss); -1 if a style cannot merge."""
    n = comp.shape[0]
    key = np.int64(target)
    for i in range(n):
        if comp[i]:
            key |= np.int64(1) << np.int64(i + 8)
    if key in keys:
        return keys[key]
    var, qv, Qv, off = _patch_qubo_kernel(adj4, diag, comp, n // 2, target, degree, coef[0], coef[1], coef[2],
                                          coef[3], coef[4])
    m = var.shape[0]
    h, J, o = _ising_of_qubo(qv, Qv, off)
    if count[0] >= n_var.shape[0]:  # full: start over (a cache; results do not depend on it)
        keys.clear()
        count[0] = 0
    slot = count[0]
    w = 0
    if m > 0:  # every style's mapping, straight into the slot (kept only if all fit)
        H = np.empty(m, dtype=np.int64)
        C = np.empty((m, m), dtype=np.int64)
        for i in range(m):
            H[i] = np.int64(np.rint(h[i] * scale))
            for j in range(m):
                C[i, j] = np.int64(np.rint(J[i, j] * scale))
        ok, w = merge_styles_flat(H, C, style_ids, Lh, Lj, Lj, n_spins, ph[slot], pJ[slot], ptr[slot], idx[slot])
        if not ok:
            return -1
    count[0] += 1
    keys[key] = slot
    n_var[slot] = m
    cells[slot, :m] = var
    lh[slot, :m] = h
    lJ[slot, :m, :m] = J
    loff[slot] = o
    width[slot] = w
    return slot


@numba.njit(cache=True)
def run_query(rng, keys, count, n_var, cells_p, lh, lJ, loff, width, ph, pJ, ptr, idx, padded, field, sr, sc, gr, gc, size, nbr, ring, offsets, adj4, diag, interior, merged, backtrack,
              num_reads, max_attempts, max_calls, degree, coef, scale, style_ids, Lh, Lj, n_spins, handle, sweeps,
              geometric, beta_hot, beta_cold, mismatch, flip_prob, free_cells):
    """One query of Algorithm 1 (see the module docstring).

    Returns ``(status, pos_r, pos_c, walk (L, 2), counts (5,), mapping (k, 4), sub_calls, sub_emu)``:
    counts = patch_solves, anneal_calls, segments, backtracks, direct_moves; mapping rows per
    style = programs, valid, wins, map_errors; per chip submission its calls and emulation seconds.
    """
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
    f_pos = np.empty((max_attempts + free_cells + 8, 2), dtype=np.int64)
    f_cell = np.empty((max_attempts + free_cells + 8, 2), dtype=np.int64)
    sub_calls = np.zeros(max_attempts + 1, dtype=np.int64)
    sub_emu = np.zeros(max_attempts + 1)
    counts = np.zeros(5, dtype=np.int64)
    mapping = np.zeros((k, 4), dtype=np.int64)
    visited = np.zeros(padded.shape, dtype=np.bool_)
    excluded = np.zeros(padded.shape, dtype=np.bool_)
    winners = np.empty(k, dtype=np.int64)
    scores = np.empty(k)
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
        li = ranked[0]
        tr = pr + offsets[li, 0]
        tc = pc + offsets[li, 1]
        slot = _program(keys, count, n_var, cells_p, lh, lJ, loff, width, ph, pJ, ptr, idx, comp, li, adj4, diag, degree, coef, scale, style_ids, Lh, Lj,
                        n_spins)
        if slot < 0:
            return NEEDS_REFERENCE, pr, pc, walk[:wl], counts, mapping, sub_calls[:nsub], sub_emu[:nsub]
        m = n_var[slot]
        cells = cells_p[slot, :m]
        direct = False
        path = np.zeros(0, dtype=np.int64)
        if m == 0:
            path = extract_path(np.zeros(0, dtype=np.bool_), cells, centre, li, nbr)
            direct = path.shape[0] > 0
            found = direct
        else:
            seed = rng.integers(0, 9223372036854775807)
            w = width[slot]
            spins = np.empty((k, num_reads, w), dtype=np.int8)
            energies = np.empty((k, num_reads))
            sub_emu[nsub] = anneal_submit(ph[slot, : k * w].reshape((k, w)),
                                          pJ[slot, : k * w * w].reshape((k, w, w)), num_reads,
                                          np.uint64(seed), handle, sweeps, geometric, beta_hot, beta_cold, mismatch,
                                          flip_prob, spins, energies)
            sub_calls[nsub] = k * num_reads
            nsub += 1
            used += k * num_reads
            counts[1] += 1
            counts[0] += 1
            n_valid, best, energy, logical = score_patch_samples(
                spins, ptr[slot], idx[slot], m, cells, centre, li, nbr, lh[slot, :m],
                lJ[slot, :m, :m], loff[slot])
            best_score = np.inf
            brow = -1
            for s in range(k):
                mapping[s, 0] += num_reads
                mapping[s, 1] += n_valid[s]
                scores[s] = energy[s]
                if energy[s] < best_score:
                    best_score = energy[s]
                    brow = s
            found = brow >= 0
            if found:
                tol = 1e-9 * max(1.0, abs(best_score))
                nw = 0
                for s in range(k):
                    if scores[s] <= best_score + tol:
                        winners[nw] = s
                        nw += 1
                x = np.empty(m, dtype=np.bool_)
                for i in range(m):
                    x[i] = logical[brow, best[brow], i] > 0
                path = extract_path(x, cells, centre, li, nbr)
                if nw > 1:
                    win = winners[rng.integers(0, nw)]
                else:
                    win = winners[0]
                mapping[win, 2] += 1
        if not found:
            f_pos[nf, 0], f_pos[nf, 1] = pr, pc
            f_cell[nf, 0], f_cell[nf, 1] = tr, tc
            nf += 1
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
    return status, pr, pc, walk[:wl], counts, mapping, sub_calls[:nsub], sub_emu[:nsub]


class CompiledSearch:
    """:class:`~planners.ising.path.IsingPath`'s side of the compiled loop: run a query with
    :func:`run_query` and turn its arrays into the planner's result (needs ``config``, ``frame``,
    ``chip``, ``_pool``, ``_engine_args``, ``_nbr``, ``_padded`` and ``_finish``)."""

    def _engine_query(self, grid, s, g, rng, field):
        """One query on the compiled loop: ``(status, (row, col) where it stopped, walk (L, 2), counts (5,),
        mapping (k, 4), sub_calls, sub_emu)`` (see :func:`run_query`); nothing charged yet."""
        status, pr, pc, walk, counts, mp, sub_calls, sub_emu = run_query(
            rng, *self._pool.arrays(), self._padded(grid), field, s[0], s[1], g[0], g[1],
            *self._loop_args(grid))
        return status, (int(pr), int(pc)), walk, counts, mp, sub_calls, sub_emu

    def _loop_args(self, grid) -> tuple:
        """:func:`run_query`'s arguments after the goal: the patch frame, the search options, the
        budgets on ``grid``, the mapping and chip arguments and the free-cell count (memoised for
        the last grid)."""
        cached = self._loop_for
        if cached is not None and cached[0] is grid:
            return cached[1]
        cfg = self.config
        fr = self.frame
        max_attempts, _per_target, max_calls = self._budgets(grid)
        args = (fr.size, self._nbr, fr.ring, fr.offsets, fr.adj4, fr.diag, cfg.interior_targets,
                cfg.target_order == "merged", cfg.backtrack, cfg.num_reads, max_attempts, max_calls,
                *self._engine_args, self._free_cells(grid))
        self._loop_for = (grid, args)
        return args

    def _run_engine(self, grid, s, g, rng, field):
        """The query on the compiled loop (:func:`.engine.run_query`), charged to the chip per
        submission as ``anneal_batch`` would; ``None`` if it needs the reference loop."""
        cfg = self.config
        self._link.charged = CallLedger()
        try:
            status, (pr, pc), walk, counts, mp, sub_calls, sub_emu = self._engine_query(grid, s, g, rng, field)
        except (ChipUnavailableError, SolverOutputError) as exc:  # a machine behind the callback failed
            unavailable = isinstance(exc, ChipUnavailableError)
            failure = unavailable_message(exc) if unavailable else f"the chip returned malformed samples: {exc}"
            counts = dict.fromkeys(_COUNT_NAMES, 0)
            if unavailable:
                counts["chip_unavailable"] = 1
            mapping = {st: dict.fromkeys(("programs", "valid", "wins", "map_errors"), 0) for st in cfg.styles}
            return self._finish(grid, s, g, [s], counts, mapping, self._link.charged, failure, None)
        if status == NEEDS_REFERENCE:
            return None
        max_attempts, _per_target, max_calls = self._budgets(grid)
        charged = self._link.charged
        self._link.settle(sub_calls, sub_emu, charged)
        counts = dict(zip(_COUNT_NAMES, (int(v) for v in counts)))
        mapping = {st: {"programs": int(r[0]), "valid": int(r[1]), "wins": int(r[2]), "map_errors": int(r[3])}
                   for st, r in zip(cfg.styles, mp)}
        failure = None
        if status == BUDGET_SPENT:
            failure = (f"gave up at [{pr}, {pc}] before reaching goal [{g[0]}, {g[1]}]: budget spent "
                       f"({counts['patch_solves']} patch solves of max_attempts={max_attempts}, "
                       f"{charged.physical_calls} chip calls of max_chip_calls={max_calls})")
        elif status == EXHAUSTED:
            failure = (f"no path found from [{s[0]}, {s[1]}] to [{g[0]}, {g[1]}]: every local target "
                       f"reachable from [{pr}, {pc}] was visited or failed"
                       + (" and backtracking is exhausted" if cfg.backtrack else " (backtrack=False)")
                       + " (the goal may be unreachable)")
        return self._finish(grid, s, g, [(int(r), int(c)) for r, c in walk], counts, mapping, charged, failure, None)

    def _budgets(self, grid) -> tuple[int, int, int]:
        """``(max_attempts, chip calls per attempt, max_chip_calls)`` of a query on ``grid``."""
        cfg = self.config
        per_target = len(cfg.styles) * cfg.num_reads
        max_attempts = cfg.max_attempts if cfg.max_attempts is not None else max(64, self._free_cells(grid))
        max_calls = cfg.max_chip_calls if cfg.max_chip_calls is not None else max_attempts * per_target
        return max_attempts, per_target, max_calls

    def _free_cells(self, grid) -> int:
        cached = self._free_for
        if cached is not None and cached[0] is grid:
            return cached[1]
        free = int((~np.asarray(grid, dtype=bool)).sum())
        self._free_for = (grid, free)
        return free
