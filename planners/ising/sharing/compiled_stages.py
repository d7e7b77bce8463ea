"""The split stages of Ising target sharing (paper 5.3, Algorithm 3) in compiled code.

Contract: :func:`split_states` makes the decisions of :meth:`~.splits.SplitSearch.split_all`
(its reference; the tests compare both) -- the same groups, memo, stage submissions
(:func:`.engine.run_stage`), seeds and win draws from the caller's ``numpy.random.Generator``,
retries, candidate order and beam -- with groups held as node bit masks (``R + N <= 62``).
The caller hands it only worlds whose groups fit the chip (no coarse split, no spin-budget
branching: ``R + N - 2 <= n_spins``).  A split with no valid candidate after the retries, a stage
program the chip would refuse, or anything outside that contract returns ``ok = False`` at once
with the reason in ``book[4]`` (:data:`FAILED_SPLIT`, :data:`REFUSED_STAGE`, :data:`OUTSIDE`),
and the caller names it, as the Python search does.

Bookkeeping is shared with :mod:`.compiled_assign` through ``book = (mapping (k, 3), counters,
sub_calls, sub_emu, failure (3,))``: per rule candidates / valid / wins, the counters indexed below,
each chip submission's calls and emulation seconds (charged by the caller in order), and why the
search stopped (code, group mask or stage status, submissions).
"""

from __future__ import annotations

import numba
import numpy as np
from numba import types
from numba.typed import Dict

from planners.ising.sharing.engine import run_stage
from planners.ising.sharing.kernels import add_balance, split_model

__all__ = ["COUNTERS", "split_states", "solve_problems", "problems_of", "popcount", "mask_nodes", "mask_nodes_into",
           "FAILED_SPLIT", "REFUSED_STAGE", "OUTSIDE"]

#: ``book[4][0]`` when a search stops: a split without a valid candidate after the retries (``book[4][1]``
#: its group mask, ``[2]`` the submissions), a stage the chip would refuse (``[1]`` the
#: :func:`.engine.run_stage` status), a group outside the compiled search's contract (``[1]`` which check).
FAILED_SPLIT, REFUSED_STAGE, OUTSIDE = 1, 2, 3

COUNTERS = ("stages", "splits", "trivial_splits", "bundles", "tour_solves", "states", "pair_resplits",
            "pair_accepted", "submissions")
STAGES, SPLITS, TRIVIAL, BUNDLES, TOUR_SOLVES, STATES, PAIR_RESPLITS, PAIR_ACCEPTED, SUBMISSIONS = range(9)
_SEED_HIGH = 9223372036854775807  # rng.integers(2**63 - 1), as the reference draws chip seeds


@numba.njit(cache=True)
def popcount(m):
    n = 0
    while m:
        m &= m - 1
        n += 1
    return n


@numba.njit(cache=True, inline="always")
def mask_nodes_into(mask, out, i):
    """Write the nodes of a bit mask, ascending, into ``out`` from index ``i``."""
    v = 0
    while mask:
        if mask & 1:
            out[i] = v
            i += 1
        mask >>= 1
        v += 1


@numba.njit(cache=True)
def mask_nodes(mask):
    """The nodes of a bit mask, ascending."""
    out = np.empty(popcount(mask), dtype=np.int64)
    mask_nodes_into(mask, out, 0)
    return out


@numba.njit(cache=True)
def _bits(nodes, n):
    m = np.int64(0)
    for i in range(n):
        m |= np.int64(1) << nodes[i]
    return m


@numba.njit(cache=True)
def problems_of(w, groups, R, balance):
    """:func:`.kernels.split_model` of every group mask, with the balance term (:func:`.kernels.add_balance`)
    when ``balance``: ``(q (P, f), Q (P, f, f), free (P, f), sizes, anchors (P, 2))``, zero-padded to the
    largest split."""
    P = groups.shape[0]
    sizes = np.empty(P, dtype=np.int64)
    f = 0
    for p in range(P):
        sizes[p] = popcount(groups[p]) - 2
        f = max(f, sizes[p])
    q = np.zeros((P, f))
    Q = np.zeros((P, f, f))
    free = np.zeros((P, f), dtype=np.int64)
    anchors = np.empty((P, 2), dtype=np.int64)
    for p in range(P):
        a, b, fr, qq, QQ, _off = split_model(w, mask_nodes(groups[p]), R)
        if balance:
            add_balance(w, fr, a, b, R, qq, QQ, balance)
        n = sizes[p]
        anchors[p, 0] = a
        anchors[p, 1] = b
        free[p, :n] = fr
        q[p, :n] = qq
        Q[p, :n, :n] = QQ
    return q, Q, free, sizes, anchors


@numba.njit(cache=True)
def reserve(store, n):
    """The candidate store ``(cut (P, C), side0 (P, C), side1 (P, C), count (P,))`` with room for ``n`` problems."""
    cut, m0, m1, cnt = store
    if n <= cut.shape[0]:
        return store
    cap = max(n, 2 * cut.shape[0])
    C = cut.shape[1]
    cut2 = np.zeros((cap, C))
    m02 = np.zeros((cap, C), dtype=np.int64)
    m12 = np.zeros((cap, C), dtype=np.int64)
    cnt2 = np.zeros(cap, dtype=np.int64)
    cut2[: cut.shape[0]] = cut
    m02[: cut.shape[0]] = m0
    m12[: cut.shape[0]] = m1
    cnt2[: cut.shape[0]] = cnt
    return cut2, m02, m12, cnt2


@numba.njit(cache=True)
def solve_problems(q, Q, free, sizes, anchors, reject, pids, masks, score_w, R, rng, chip, retries, book, store):
    """:meth:`~.submit.StageSolver.solve_all` with the packed submission: problem ``p``'s (group
    ``masks[p]``) distinct valid candidates (best cut on ``score_w`` first) go to store row
    ``pids[p]``.  Returns ``ok`` (the reason in ``book[4]`` when not)."""
    rule_ids, Lh, Lj, n_spins, capacity, reads, handle, sweeps, geometric, beta_hot, beta_cold, mismatch, flip_prob = chip
    mapping, counters, sub_calls, sub_emu, failure = book
    c_cut, c_m0, c_m1, c_n = store
    nk = rule_ids.shape[0]
    pending = np.arange(sizes.shape[0])
    for p in range(pending.shape[0]):
        c_n[pids[p]] = 0
    attempts = 0
    while pending.shape[0] > 0:
        for p in pending:
            if sizes[p] > n_spins:  # spin-budget branching: outside the contract
                failure[0], failure[1] = OUTSIDE, 1
                return False
        s = counters[SUBMISSIONS]
        if s >= sub_calls.shape[0]:  # more submissions than the caller made room for
            failure[0], failure[1] = OUTSIDE, 2
            return False
        seed = rng.integers(0, _SEED_HIGH)
        code, calls, emu, n_valid, best, c_split, cut, s0, n0, s1, n1 = run_stage(
            q[pending], Q[pending], sizes[pending], rule_ids, Lh, Lj, capacity, reads, np.uint64(seed), handle,
            sweeps, geometric, beta_hot, beta_cold, mismatch, flip_prob, free[pending], anchors[pending], score_w, R,
            reject[pending])
        if code != 0:
            failure[0], failure[1] = REFUSED_STAGE, code
            return False
        sub_calls[s] = calls
        sub_emu[s] = emu
        counters[SUBMISSIONS] += 1
        P = pending.shape[0]
        for r in range(nk):
            mapping[r, 0] += reads * P
            for i in range(P):
                mapping[r, 1] += n_valid[i, r]
        M = c_split.shape[0]
        idx = np.empty(M, dtype=np.int64)
        winners = np.empty(nk, dtype=np.int64)
        n_failed = 0
        failed = np.empty(P, dtype=np.int64)
        for i in range(P):
            cnt = 0
            for m in range(M):
                if c_split[m] == i:
                    idx[cnt] = m
                    cnt += 1
            if cnt == 0:
                failed[n_failed] = pending[i]
                n_failed += 1
                continue
            top = best[i].min()
            tol = 1e-9 * max(1.0, abs(top))
            nw = 0
            for r in range(nk):
                if best[i, r] <= top + tol:
                    winners[nw] = r
                    nw += 1
            win = winners[rng.integers(0, nw)] if nw > 1 else winners[0]
            mapping[win, 2] += 1
            keys = np.empty(cnt)
            for j in range(cnt):
                keys[j] = -cut[idx[j]]
            order = np.argsort(keys, kind="mergesort")  # best cut first, ties in first-read order
            row = pids[pending[i]]
            for j in range(cnt):
                m = idx[order[j]]
                c_cut[row, j] = cut[m]
                c_m0[row, j] = _bits(s0[m], n0[m])
                c_m1[row, j] = _bits(s1[m], n1[m])
            c_n[row] = cnt
        if n_failed and attempts >= retries:  # the caller names the split that failed
            failure[0], failure[1], failure[2] = FAILED_SPLIT, masks[failed[0]], attempts + 1
            return False
        attempts += 1
        pending = failed[:n_failed]
    return True


@numba.njit(cache=True)
def _stage(w, R, todo, kind, reject_robots, memo, n_prob, rng, chip, retries, limit, balance, book, store):
    """:meth:`~.search.IsingSharing._stage`: store rows of the groups ``todo`` (masks), solving the
    groups not in ``memo``.  Returns ``(ok, rows, n_prob, store)``."""
    counters = book[1]
    T = todo.shape[0]
    rows = np.empty(T, dtype=np.int64)
    fresh = np.empty(T, dtype=np.int64)
    nf = 0
    for t in range(T):
        key = todo[t] | (np.int64(kind) << 62)
        if key not in memo:
            memo[key] = n_prob + nf
            fresh[nf] = todo[t]
            nf += 1
        rows[t] = memo[key]
    counters[STAGES] += 1
    counters[SPLITS] += nf
    for i in range(nf):
        if popcount(fresh[i]) - 2 > limit:  # a coarse split: outside the contract
            book[4][0], book[4][1] = OUTSIDE, 3
            return False, rows, n_prob, store
    store = reserve(store, n_prob + nf)
    c_cut, c_m0, c_m1, c_n = store
    q, Q, free, sizes, anchors = problems_of(w, fresh[:nf], R, balance if kind == 0 else 0.0)
    keep = np.empty(nf, dtype=np.int64)
    n_keep = 0
    for i in range(nf):
        if sizes[i] == 0:  # one partition only: nothing to solve
            counters[TRIVIAL] += 1
            a, b = anchors[i, 0], anchors[i, 1]
            c_cut[n_prob + i, 0] = w[a, b]
            c_m0[n_prob + i, 0] = np.int64(1) << a
            c_m1[n_prob + i, 0] = np.int64(1) << b
            c_n[n_prob + i] = 1
        else:
            keep[n_keep] = i
            n_keep += 1
    if n_keep:
        k = keep[:n_keep]
        reject = np.full(n_keep, reject_robots and kind == 0)
        if not solve_problems(q[k], Q[k], free[k], sizes[k], anchors[k], reject, n_prob + k, fresh[:nf][k], w, R,
                              rng, chip, retries, book, store):
            return False, rows, n_prob, store
    return True, rows, n_prob + nf, store


@numba.njit(cache=True)
def _expand(score, groups, ng, todo_s, todo_g, rows, width, max_states, store):
    """:meth:`~.search.IsingSharing._expand` on masks: every state's split groups replaced by up to
    ``width`` candidates each, at most ``max_states`` states, best summed cut first."""
    c_cut, c_m0, c_m1, c_n = store
    S, G = groups.shape
    cap = S * max_states
    out_score = np.empty(cap)
    out_groups = np.zeros((cap, G), dtype=np.int64)
    out_ng = np.zeros(cap, dtype=np.int64)
    pos = np.full(G, -1, dtype=np.int64)
    n_out = 0
    for si in range(S):
        mine = np.where(todo_s == si)[0]
        nm = mine.shape[0]
        if nm == 0:
            out_score[n_out] = score[si]
            out_groups[n_out] = groups[si]
            out_ng[n_out] = ng[si]
            n_out += 1
            continue
        combo_sc = np.zeros(1)
        combo = np.zeros((1, nm), dtype=np.int64)
        for j in range(nm):
            row = rows[mine[j]]
            nc = min(width, c_n[row])
            n_new = combo_sc.shape[0] * nc
            new_sc = np.empty(n_new)
            new = np.empty((n_new, nm), dtype=np.int64)
            t = 0
            for c in range(combo_sc.shape[0]):
                for x in range(nc):
                    new_sc[t] = combo_sc[c] + c_cut[row, x]
                    new[t] = combo[c]
                    new[t, j] = x
                    t += 1
            order = np.argsort(-new_sc, kind="mergesort")[:max_states]
            combo_sc = new_sc[order]
            combo = new[order]
        pos[:] = -1
        for j in range(nm):
            pos[todo_g[mine[j]]] = j
        for c in range(combo_sc.shape[0]):
            n = 0
            for gi in range(ng[si]):
                j = pos[gi]
                if j < 0:
                    out_groups[n_out, n] = groups[si, gi]
                    n += 1
                else:
                    row = rows[mine[j]]
                    out_groups[n_out, n] = c_m0[row, combo[c, j]]
                    out_groups[n_out, n + 1] = c_m1[row, combo[c, j]]
                    n += 2
            out_ng[n_out] = n
            out_score[n_out] = score[si] + combo_sc[c]
            n_out += 1
    order = np.argsort(-out_score[:n_out], kind="mergesort")[:max_states]
    return out_score[order], out_groups[order], out_ng[order]


@numba.njit(cache=True)
def _todo(groups, ng, R, kind, base_max, above):
    """(state, group) pairs to split: groups with several robots (``kind`` 0), else one-robot groups
    with more than ``base_max`` targets and robotless ones with more than ``above``."""
    S = groups.shape[0]
    robots = (np.int64(1) << R) - 1
    ts = np.empty(S * groups.shape[1], dtype=np.int64)
    tg = np.empty_like(ts)
    n = 0
    for si in range(S):
        for gi in range(ng[si]):
            g = groups[si, gi]
            nr = popcount(g & robots)
            if kind == 0:
                take = nr >= 2
            else:
                take = popcount(g) - nr > (base_max if nr else above)
            if take:
                ts[n] = si
                tg[n] = gi
                n += 1
    return ts[:n], tg[:n]


@numba.njit(cache=True)
def split_states(w, R, rng, chip, retries, limit, opts, balance, book, store):
    """:meth:`~.splits.SplitSearch.split_all`: ``(ok, groups (S, G), ng (S,), store, n_prob)`` -- the
    candidate partial solutions, best summed cut first.  ``opts = (beam, refine_beam, max_states,
    refine_stages, base_max, refine_above, reject_robots)``."""
    beam, refine_beam, max_states, refine_stages, base_max, above, reject_robots = opts
    n = w.shape[0]
    score = np.zeros(1)
    groups = np.zeros((1, n), dtype=np.int64)
    groups[0, 0] = (np.int64(1) << n) - 1
    ng = np.ones(1, dtype=np.int64)
    memo = Dict.empty(key_type=types.int64, value_type=types.int64)
    n_prob = np.int64(0)  # int64 from the start: a literal 0 would compile _stage twice
    stage = 0
    while True:
        kind = 0 if stage == 0 else 1
        ts, tg = _todo(groups, ng, R, kind, base_max, above)
        if ts.shape[0] == 0:
            if stage == 0:  # robot stages done: the refinement stages
                stage = 1
                continue
            break
        if stage > refine_stages:
            break
        todo = np.empty(ts.shape[0], dtype=np.int64)
        for t in range(ts.shape[0]):
            todo[t] = groups[ts[t], tg[t]]
        ok, rows, n_prob, store = _stage(w, R, todo, kind, reject_robots != 0, memo, n_prob, rng, chip, retries,
                                         limit, balance, book, store)
        if not ok:
            return False, groups, ng, store, n_prob
        score, groups, ng = _expand(score, groups, ng, ts, tg, rows, beam if kind == 0 else refine_beam, max_states,
                                    store)
        if stage:
            stage += 1
    book[1][STATES] += groups.shape[0]
    return True, groups, ng, store, n_prob
