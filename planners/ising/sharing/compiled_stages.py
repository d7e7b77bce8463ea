"""The split stages of Ising target sharing (paper 5.3, Algorithm 3) in compiled code.

Contract: :func:`split_states` makes the decisions of ``SplitSearch.split_all`` in
``tests/sharing_search_reference.py`` (its oracle; the tests compare both) -- the same groups,
memo, stage submissions (:func:`.engine.run_stage`), seeds and win draws from the caller's
``numpy.random.Generator``, retries, candidate order and beam -- with groups held as ids of a
node-set pool (:mod:`.node_sets`).  A split a few spins beyond the chip goes into its stage's
submission as its spin-budget branches (:func:`.kernels.branch_problems`); a group beyond that
is split on target clusters first (:func:`coarse_split`).  A split with no valid candidate after
the retries, a stage program the chip would refuse, robots that cannot be coarsened onto the
chip, or more submissions or candidates than the caller made room for returns ``ok = False`` at
once with the reason in ``book[4]`` (:data:`FAILED_SPLIT`, :data:`REFUSED_STAGE`,
:data:`UNCOARSENED`, :data:`OUTSIDE`), and the caller names it.

Bookkeeping is shared with :mod:`.compiled_assign` through ``book = (mapping (k, 3), counters,
sub_calls, sub_emu, failure (3,))``: per rule candidates / valid / wins, the counters indexed below,
each chip submission's calls and emulation seconds (charged by the caller in order), and why the
search stopped (code, group set id or stage status, submissions).
"""

from __future__ import annotations

import numba
import numpy as np
from numba import types
from numba.typed import Dict

from planners.ising.sharing.engine import run_stage
from planners.ising.sharing.compiled_coarse import coarsen, expand, fine_cut
from planners.ising.sharing.kernels import add_balance, branch_problems, split_model
from planners.ising.sharing.node_sets import ROBOTS, SIZE, intern, nodes_of, size, sizes_of

__all__ = ["COUNTERS", "split_states", "solve_problems", "problems_of", "coarse_split", "FAILED_SPLIT", "REFUSED_STAGE",
           "OUTSIDE", "UNCOARSENED"]

#: ``book[4][0]`` when a search stops: a split without a valid candidate after the retries (``book[4][1]``
#: its group's set id, ``[2]`` the submissions), a stage the chip would refuse (``[1]`` the
#: :func:`.engine.run_stage` status), a group outside the compiled search's contract (``[1]`` which check),
#: a group whose robots cannot be coarsened onto the chip (``[1]`` its robots, ``[2]`` its targets).
FAILED_SPLIT, REFUSED_STAGE, OUTSIDE, UNCOARSENED = 1, 2, 3, 4

COUNTERS = ("stages", "splits", "trivial_splits", "bundles", "tour_solves", "states", "pair_resplits",
            "pair_accepted", "coarse_splits", "submissions")
STAGES, SPLITS, TRIVIAL, BUNDLES, TOUR_SOLVES, STATES, PAIR_RESPLITS, PAIR_ACCEPTED, COARSE, SUBMISSIONS = range(10)
_SEED_HIGH = 9223372036854775807  # rng.integers(2**63 - 1), as the reference draws chip seeds


@numba.njit(cache=True)
def problems_of(w, groups, R, balance, pool):
    """:func:`.kernels.split_model` of every group (set ids), with the balance term (:func:`.kernels.add_balance`)
    when ``balance``: ``(q (P, f), Q (P, f, f), free (P, f), sizes, anchors (P, 2))``, zero-padded to the
    largest split."""
    P = groups.shape[0]
    sizes = np.empty(P, dtype=np.int64)
    f = 0
    for p in range(P):
        sizes[p] = size(pool, groups[p]) - 2
        f = max(f, sizes[p])
    q = np.zeros((P, f))
    Q = np.zeros((P, f, f))
    free = np.zeros((P, f), dtype=np.int64)
    anchors = np.empty((P, 2), dtype=np.int64)
    for p in range(P):
        a, b, fr, qq, QQ, _off = split_model(w, nodes_of(pool, groups[p]), R)
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
def solve_problems(q, Q, free, sizes, anchors, reject, pids, gids, score_w, R, rng, chip, retries, book, store,
                   pool):
    """``ReferenceStages.solve_all`` (the oracle) with the packed submission: problem ``p``'s (group
    ``gids[p]``) distinct valid candidates (best cut on ``score_w`` first) go to store row
    ``pids[p]``.  Returns ``ok`` (the reason in ``book[4]`` when not)."""
    rule_ids, Lh, Lj, n_spins, capacity, reads, machine = chip
    mapping, counters, sub_calls, sub_emu, failure = book
    c_cut, c_m0, c_m1, c_n = store
    nk = rule_ids.shape[0]
    pending = np.arange(sizes.shape[0])
    for p in range(pending.shape[0]):
        c_n[pids[p]] = 0
    attempts = 0
    while pending.shape[0] > 0:
        s = counters[SUBMISSIONS]
        if s >= sub_calls.shape[0]:  # more submissions than the caller made room for
            failure[0], failure[1] = OUTSIDE, 2
            return False
        seed = rng.integers(0, _SEED_HIGH)
        if sizes[pending].max() > n_spins:  # splits beyond the chip as their spin-budget branches, merged below
            bq, bQ, bfree, bsizes, nfix, fixed, parent = branch_problems(q[pending], Q[pending], free[pending],
                                                                        sizes[pending], n_spins)
        else:
            bq, bQ, bfree, bsizes = q[pending], Q[pending], free[pending], sizes[pending]
            parent = np.arange(pending.shape[0])
            nfix = np.zeros(pending.shape[0], dtype=np.int64)
            fixed = np.zeros((pending.shape[0], 0), dtype=np.int8)
        code, calls, emu, b_valid, b_best, c_split, cut, s0, n0, s1, n1 = run_stage(
            bq, bQ, bsizes, rule_ids, Lh, Lj, capacity, reads, np.uint64(seed), machine, bfree, anchors[pending][parent],
            score_w, R, reject[pending][parent], nfix, fixed)
        if code != 0:
            failure[0], failure[1] = REFUSED_STAGE, code
            return False
        sub_calls[s] = calls
        sub_emu[s] = emu
        counters[SUBMISSIONS] += 1
        P = pending.shape[0]
        n_valid = np.zeros((P, nk), dtype=np.int64)
        best = np.full((P, nk), np.inf)
        for e in range(parent.shape[0]):
            for r in range(nk):
                n_valid[parent[e], r] += b_valid[e, r]
                best[parent[e], r] = min(best[parent[e], r], b_best[e, r])
        for r in range(nk):
            mapping[r, 0] += reads * parent.shape[0]
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
                if parent[c_split[m]] == i:
                    idx[cnt] = m
                    cnt += 1
            if cnt == 0:
                failed[n_failed] = pending[i]
                n_failed += 1
                continue
            if cnt > c_cut.shape[1]:  # more candidates than the caller made room for
                failure[0], failure[1] = OUTSIDE, 1
                return False
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
                c_m0[row, j] = intern(pool, s0[m, :n0[m]])
                c_m1[row, j] = intern(pool, s1[m, :n1[m]])
            c_n[row] = cnt
        if n_failed and attempts >= retries:  # the caller names the split that failed
            failure[0], failure[1], failure[2] = FAILED_SPLIT, gids[failed[0]], attempts + 1
            return False
        attempts += 1
        pending = failed[:n_failed]
    return True


@numba.njit(cache=True)
def coarse_split(w, R, g, reject, balance, row, scratch, rng, chip, retries, book, store, pool):
    """``coarse_split`` (the oracle) of group ``g`` (a set id) into store row ``row`` (store row
    ``scratch`` holds the coarse split).  Returns ``(ok, store)``."""
    counters = book[1]
    n_spins = chip[3]
    nodes = nodes_of(pool, g)
    robots = np.searchsorted(nodes, R)
    clustered = 0
    if n_spins + 2 - robots < max(1, n_spins // 2):
        # more robots than leave half the chip to target clusters: neighbouring robots are clustered too
        clustered = max(2, (n_spins + 2) // 2)
        if robots < 2 or n_spins + 2 - clustered < 1:
            book[4][0], book[4][1], book[4][2] = UNCOARSENED, robots, nodes.shape[0] - robots
            return False, store
    n_clusters = n_spins + 2 - (robots if clustered == 0 else min(robots, clustered))
    members, start, wc = coarsen(w, nodes, R, n_clusters, clustered)
    m = start.shape[0] - 1
    coarse_robots = 0
    for c in range(m):
        coarse_robots += members[start[c]] < R
    counters[STAGES] += 1  # the coarse split is a stage of one split
    counters[SPLITS] += 1
    cg = np.array([intern(pool, np.arange(m))])
    q, Q, free, sizes, anchors = problems_of(wc, cg, coarse_robots, balance, pool)
    store = reserve(store, max(row, scratch) + 1)
    c_cut, c_m0, c_m1, c_n = store
    if sizes[0] == 0:  # one partition only
        counters[TRIVIAL] += 1
        c_m0[scratch, 0] = intern(pool, anchors[0, :1].copy())
        c_m1[scratch, 0] = intern(pool, anchors[0, 1:].copy())
        c_n[scratch] = 1
    elif not solve_problems(q, Q, free, sizes, anchors, np.array([reject]), np.array([scratch]), cg, wc,
                            coarse_robots, rng, chip, retries, book, store, pool):
        return False, store
    n = c_n[scratch]
    cut = np.empty(n)
    f0 = np.empty(n, dtype=np.int64)
    f1 = np.empty(n, dtype=np.int64)
    for j in range(n):
        f0[j] = expand(pool, c_m0[scratch, j], members, start)
        f1[j] = expand(pool, c_m1[scratch, j], members, start)
        cut[j] = fine_cut(w, pool, f0[j], f1[j])
    order = np.argsort(-cut, kind="mergesort")
    for j in range(n):
        c_cut[row, j] = cut[order[j]]
        c_m0[row, j] = f0[order[j]]
        c_m1[row, j] = f1[order[j]]
    c_n[row] = n
    counters[COARSE] += 1
    return True, store


@numba.njit(cache=True)
def _stage(w, R, todo, kind, reject_robots, memo, n_prob, rng, chip, retries, limit, balance, book, store, pool):
    """``SplitSearch.stage`` (the oracle): store rows of the groups ``todo`` (set ids), solving the
    groups not in ``memo``.  Returns ``(ok, rows, n_prob, store)``."""
    counters = book[1]
    T = todo.shape[0]
    rows = np.empty(T, dtype=np.int64)
    fresh = np.empty(T, dtype=np.int64)
    nf = 0
    for t in range(T):
        key = todo[t] * 2 + kind
        if key not in memo:
            memo[key] = n_prob + nf
            fresh[nf] = todo[t]
            nf += 1
        rows[t] = memo[key]
    store = reserve(store, n_prob + nf + 1)
    bal = balance if kind == 0 else 0.0
    normal = np.empty(nf, dtype=np.int64)
    n_normal = 0
    for i in range(nf):  # groups beyond the chip split on clusters first, in order, as they are met
        if size(pool, fresh[i]) - 2 > limit:
            ok, store = coarse_split(w, R, fresh[i], reject_robots and kind == 0, bal, n_prob + i, n_prob + nf, rng,
                                     chip, retries, book, store, pool)
            if not ok:
                return False, rows, n_prob, store
        else:
            normal[n_normal] = i
            n_normal += 1
    counters[STAGES] += 1
    counters[SPLITS] += nf
    c_cut, c_m0, c_m1, c_n = store
    normal = normal[:n_normal]
    q, Q, free, sizes, anchors = problems_of(w, fresh[normal], R, bal, pool)
    keep = np.empty(n_normal, dtype=np.int64)
    n_keep = 0
    for j in range(n_normal):
        row = n_prob + normal[j]
        if sizes[j] == 0:  # one partition only: nothing to solve
            counters[TRIVIAL] += 1
            a, b = anchors[j, 0], anchors[j, 1]
            c_cut[row, 0] = w[a, b]
            c_m0[row, 0] = intern(pool, np.array([a], dtype=np.int64))
            c_m1[row, 0] = intern(pool, np.array([b], dtype=np.int64))
            c_n[row] = 1
        else:
            keep[n_keep] = j
            n_keep += 1
    if n_keep:
        k = keep[:n_keep]
        reject = np.full(n_keep, reject_robots and kind == 0)
        if not solve_problems(q[k], Q[k], free[k], sizes[k], anchors[k], reject, n_prob + normal[k],
                              fresh[normal[k]], w, R, rng, chip, retries, book, store, pool):
            return False, rows, n_prob, store
    return True, rows, n_prob + nf, store


@numba.njit(cache=True)
def _expand(score, groups, ng, todo_s, todo_g, rows, width, max_states, store):
    """``SplitSearch.expand`` (the oracle) on set ids: every state's split groups replaced by up to
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
def _todo(groups, ng, R, kind, base_max, above, pool):
    """(state, group) pairs to split: groups with several robots (``kind`` 0), else one-robot groups
    with more than ``base_max`` targets and robotless ones with more than ``above``."""
    S = groups.shape[0]
    meta = sizes_of(pool)
    ts = np.empty(S * groups.shape[1], dtype=np.int64)
    tg = np.empty_like(ts)
    n = 0
    for si in range(S):
        for gi in range(ng[si]):
            g = groups[si, gi]
            nr = meta[g, ROBOTS]
            if kind == 0:
                take = nr >= 2
            else:
                take = meta[g, SIZE] - nr > (base_max if nr else above)
            if take:
                ts[n] = si
                tg[n] = gi
                n += 1
    return ts[:n], tg[:n]


@numba.njit(cache=True)
def split_states(w, R, rng, chip, retries, limit, opts, balance, book, store, pool):
    """``SplitSearch.split_all`` (the oracle): ``(ok, groups (S, G), ng (S,), store, n_prob)`` -- the
    candidate partial solutions, best summed cut first.  ``opts = (beam, refine_beam, max_states,
    refine_stages, base_max, refine_above, reject_robots)``."""
    beam, refine_beam, max_states, refine_stages, base_max, above, reject_robots = opts
    n = w.shape[0]
    score = np.zeros(1)
    groups = np.zeros((1, n), dtype=np.int64)
    groups[0, 0] = intern(pool, np.arange(n))
    ng = np.ones(1, dtype=np.int64)
    memo = Dict.empty(key_type=types.int64, value_type=types.int64)
    n_prob = np.int64(0)  # int64 from the start: a literal 0 would compile _stage twice
    stage = 0
    while True:
        kind = 0 if stage == 0 else 1
        ts, tg = _todo(groups, ng, R, kind, base_max, above, pool)
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
                                         limit, balance, book, store, pool)
        if not ok:
            return False, groups, ng, store, n_prob
        score, groups, ng = _expand(score, groups, ng, ts, tg, rows, beam if kind == 0 else refine_beam, max_states,
                                    store)
        if stage:
            stage += 1
    book[1][STATES] += groups.shape[0]
    return True, groups, ng, store, n_prob
