"""The compiled steps of the split stages (paper 5.3, Algorithm 3) on node-set ids.

Contract: each step is one compiled call from :mod:`.stages` / :mod:`.refine`: :func:`solve_splits` solves
a list of groups' splits on the chip (split problems, submissions with retries through
:func:`ising_backend.pack_qubo_stack` and the session record, reads scored and kept as each split's
candidates), :func:`todo_groups` gives the groups a stage splits, :func:`expand_states` the states it
leaves.  Oracle: ``tests/sharing_search_reference.py``; design notes: docs/design/ising_sharing.md.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from ising_backend import STACK_OK, pack_qubo_stack, submit_packs, via_callback
from planners.ising.sharing.split_problem import (
    SplitProblems, StageScores, Sides, add_balance, branch_problems, candidate_sides, score_stage, split_model,
)
from planners.ising.sharing.node_sets import intern, nodes_of, robots_in, size

__all__ = ["solve_splits", "submit_stage", "problems_of", "keep_candidates", "todo_groups", "expand_states", "set_sizes",
           "set_nodes", "StageProgram", "StageOut", "StageBook", "StoreArrays", "Splits", "SOLVED", "FAILED_SPLIT",
           "REFUSED_STAGE", "NO_ROOM", "COUNTERS"]

#: :func:`solve_splits`' status: every split has candidates; a split had none after the retries (``what``:
#: its group's set id); a stage the chip would refuse (``what``: the :func:`ising_backend.pack_qubo_stack`
#: status); a split with more candidates than the store's width.
SOLVED, FAILED_SPLIT, REFUSED_STAGE, NO_ROOM = 0, 1, 2, 3
#: The sharing call's counters, in the order of its ``counters`` array (indices below).
COUNTERS = ("stages", "splits", "trivial_splits", "bundles", "tour_solves", "states", "pair_resplits",
            "pair_accepted", "coarse_splits")
STAGES, SPLITS, TRIVIAL, BUNDLES, TOUR_SOLVES, STATES, PAIR_RESPLITS, PAIR_ACCEPTED, COARSE = range(9)
_SEED_HIGH = 9223372036854775807  # rng.integers(2**63 - 1), as the reference draws chip seeds


class StageProgram(NamedTuple):
    """How a stage goes to the chip (:meth:`.submission.StageSolver.program`)."""

    rules: np.ndarray  # the quantization rules' ids, one program per split and rule
    Lh: float  # the chip's coefficient limits
    Lj: float
    capacity: int  # spins per packed program
    num_reads: int
    n_spins: int  # the chip's spins (splits beyond them are branched)
    retries: int  # of a split without a valid read


class StageOut(NamedTuple):
    """:func:`submit_stage`'s result; nothing is annealed unless ``status`` is ``STACK_OK``."""

    status: int  # the ising_backend.pack_qubo_stack status
    calls: int  # the submission's chip calls
    emu: float  # and emulation seconds
    scores: StageScores  # every read decoded, checked and scored
    sides: Sides  # each distinct valid partition's sides


class StageBook(NamedTuple):
    """What :func:`solve_splits` counts in place."""

    mapping: np.ndarray  # (k, 3) per rule: candidates, valid reads, wins
    counters: np.ndarray  # the sharing call's counters, by COUNTERS
    calls: np.ndarray  # (retries + 1,) per submission: its chip calls
    emu: np.ndarray  # and emulation seconds


class StoreArrays(NamedTuple):
    """Each split problem's distinct valid candidates, best cut first (a row per problem)."""

    cut: np.ndarray  # (rows, C)
    side0: np.ndarray  # (rows, C) set ids
    side1: np.ndarray
    count: np.ndarray  # (rows,)


class Splits(NamedTuple):
    """:func:`problems_of`' result, zero-padded to the largest split."""

    q: np.ndarray  # (P, f)
    Q: np.ndarray  # (P, f, f)
    free: np.ndarray  # (P, f)
    sizes: np.ndarray  # (P,)
    anchors: np.ndarray  # (P, 2)


@numba.njit(cache=True)
def set_sizes(pool, ids):
    """The node counts of sets ``ids``."""
    out = np.empty(ids.shape[0], dtype=np.int64)
    for i in range(ids.shape[0]):
        out[i] = size(pool, ids[i])
    return out


@numba.njit(cache=True)
def set_nodes(pool, s):
    """A copy of set ``s``'s sorted nodes."""
    return nodes_of(pool, s).copy()


@numba.njit(cache=True)
def problems_of(w, groups, R, balance, pool):
    """:func:`.split_problem.split_model` of every group (set ids), with the balance term
    (:func:`.split_problem.add_balance`) when ``balance``: the :class:`Splits`."""
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
        m = split_model(w, nodes_of(pool, groups[p]), R)
        if balance:
            add_balance(w, m.free, m.a, m.b, R, m.q, m.Q, balance)
        n = sizes[p]
        anchors[p, 0] = m.a
        anchors[p, 1] = m.b
        free[p, :n] = m.free
        q[p, :n] = m.q
        Q[p, :n, :n] = m.Q
    return Splits(q, Q, free, sizes, anchors)


@numba.njit(cache=True)
def keep_candidates(out, parent, pending, pids, reads, rng, mapping, store, pool):
    """A submission's reads (``out``: a :class:`StageOut`) into the :class:`StoreArrays` ``store``'s
    candidates of the pending splits: split ``i`` (problem ``pending[i]``, branches ``parent == i``)
    gets its distinct valid partitions in store row ``pids[pending[i]]``, best cut first; per rule
    ``mapping`` counts candidates, valid reads and wins (ties between rules drawn from ``rng``).
    Returns ``(room, failed)``: ``room`` False when a split has more candidates than the store's
    width; ``failed`` the pending problems without a valid candidate."""
    b_valid, b_best, c_split, cut = out.scores.n_valid, out.scores.best, out.scores.split, out.scores.cut
    s0, n0, s1, n1 = out.sides.side0, out.sides.n0, out.sides.side1, out.sides.n1
    c_cut, c_m0, c_m1, c_n = store.cut, store.side0, store.side1, store.count
    P = pending.shape[0]
    nk = b_valid.shape[1]
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
        if cnt > c_cut.shape[1]:
            return False, failed[:n_failed]
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
    return True, failed[:n_failed]


@numba.njit(cache=True)
def todo_groups(groups, ng, R, kind, base_max, above, pool):
    """(state, group) pairs to split -- groups with several robots (``kind`` 0), else one-robot groups
    with more than ``base_max`` targets and robotless ones with more than ``above`` -- and each one's
    node count: ``(states, groups, sizes)``."""
    S = groups.shape[0]
    ts = np.empty(S * groups.shape[1], dtype=np.int64)
    tg = np.empty_like(ts)
    tz = np.empty_like(ts)
    n = 0
    for si in range(S):
        for gi in range(ng[si]):
            g = groups[si, gi]
            nr = robots_in(pool, g, R)
            if kind == 0:
                take = nr >= 2
            else:
                take = size(pool, g) - nr > (base_max if nr else above)
            if take:
                ts[n] = si
                tg[n] = gi
                tz[n] = size(pool, g)
                n += 1
    return ts[:n], tg[:n], tz[:n]


@numba.njit(cache=True)
def expand_states(score, groups, ng, todo_s, todo_g, rows, width, max_states, store):
    """``SplitSearch.expand`` (the oracle) on set ids: every state's split groups replaced by up to
    ``width`` candidates each, at most ``max_states`` states, best summed cut first (``store``: the
    :class:`StoreArrays`)."""
    c_cut, c_m0, c_m1, c_n = store.cut, store.side0, store.side1, store.count
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
def submit_stage(problems, program, seed, machine, dist, n_robots):
    """One stage submission of the split ``problems`` (:class:`~.split_problem.SplitProblems`) under the
    :class:`StageProgram` ``program``: every split x rule mapped and packed (:func:`ising_backend.pack_qubo_stack`),
    annealed with ``seed`` on the session record ``machine``, every read decoded, checked and scored on
    ``dist``.  Returns a :class:`StageOut`."""
    sizes, free, anchors = problems.sizes, problems.free, problems.anchors
    rules = program.rules
    capacity = program.capacity
    if via_callback(machine):  # a machine behind the callback: packs up to its usable spins, as the checked path
        capacity = max(capacity, sizes.max())
    status, h, J, where = pack_qubo_stack(problems.q, problems.Q, sizes, rules, program.Lh, program.Lj, capacity)
    # a refused stage: nothing annealed, no read to score
    spins, calls, emu = submit_packs(h, J, program.num_reads if status == STACK_OK else 0, seed, machine)
    scores = score_stage(spins, where, sizes, rules.shape[0], free, anchors, dist, n_robots, problems.reject,
                         problems.nfix, problems.fixed)
    sides = candidate_sides(scores.split, scores.side, free, sizes + problems.nfix, anchors)
    return StageOut(status, calls, emu, scores, sides)


@numba.njit(cache=True)
def solve_splits(ws, R, groups, balance, reject, rows, rng, program, machine, book, store, pool):
    """The splits of ``groups`` (set ids) solved on the chip: problem ``i * S + s`` is group ``i``'s anchored
    split on the weights ``ws[s]`` (``S = ws.shape[0]``; the balance term when ``balance``), its distinct
    valid candidates, best cut on ``ws[0]`` first, into store row ``rows[i * S + s]`` -- one partition for a
    split without a free node, else the submissions of ``ReferenceStages.solve_all`` (the oracle): all
    pending splits in one submission, those without a valid candidate again, up to ``retries`` times.
    ``program`` the :class:`StageProgram`; the :class:`StageBook` ``book`` gets each submission's charge.
    Returns ``(status, what, submissions)``."""
    n_spins, retries = program.n_spins, program.retries
    counters = book.counters
    c_cut, c_m0, c_m1, c_n = store.cut, store.side0, store.side1, store.count
    S = ws.shape[0]
    P = groups.shape[0] * S
    f = 0
    for g in groups:
        f = max(f, size(pool, g) - 2)
    q = np.zeros((P, f))
    Q = np.zeros((P, f, f))
    free = np.zeros((P, f), dtype=np.int64)
    sizes = np.empty(P, dtype=np.int64)
    anchors = np.empty((P, 2), dtype=np.int64)
    for s in range(S):
        sp = problems_of(ws[s], groups, R, balance, pool)
        for i in range(groups.shape[0]):
            p = i * S + s
            n = sp.sizes[i]
            sizes[p] = n
            anchors[p] = sp.anchors[i]
            free[p, :n] = sp.free[i, :n]
            q[p, :n] = sp.q[i, :n]
            Q[p, :n, :n] = sp.Q[i, :n, :n]
    n_pending = 0
    pending = np.empty(P, dtype=np.int64)
    for p in range(P):
        row = rows[p]
        c_n[row] = 0
        if sizes[p] == 0:  # one partition only: nothing to solve
            counters[TRIVIAL] += 1
            a, b = anchors[p, 0], anchors[p, 1]
            c_cut[row, 0] = ws[0][a, b]
            c_m0[row, 0] = intern(pool, np.array([a], dtype=np.int64))
            c_m1[row, 0] = intern(pool, np.array([b], dtype=np.int64))
            c_n[row] = 1
        else:
            pending[n_pending] = p
            n_pending += 1
    pending = pending[:n_pending]
    attempts = 0
    while pending.shape[0] > 0:
        seed = rng.integers(0, _SEED_HIGH)
        m = pending.shape[0]
        if sizes[pending].max() > n_spins:  # splits beyond the chip as their spin-budget branches, merged below
            br = branch_problems(q[pending], Q[pending], free[pending], sizes[pending], n_spins)
            parent = br.parent
            problems = SplitProblems(br.q, br.Q, br.free, br.sizes, anchors[pending][parent],
                                     np.full(parent.shape[0], reject), br.nfix, br.fixed)
        else:
            parent = np.arange(m)
            problems = SplitProblems(q[pending], Q[pending], free[pending], sizes[pending], anchors[pending][parent],
                                     np.full(m, reject), np.zeros(m, dtype=np.int64), np.zeros((m, 0), dtype=np.int8))
        out = submit_stage(problems, program, np.uint64(seed), machine, ws[0], R)
        if out.status != STACK_OK:
            return REFUSED_STAGE, out.status, attempts
        book.calls[attempts] = out.calls
        book.emu[attempts] = out.emu
        room, failed = keep_candidates(out, parent, pending, rows, program.num_reads, rng, book.mapping, store, pool)
        if not room:
            return NO_ROOM, 0, attempts + 1
        if failed.shape[0] and attempts >= retries:
            return FAILED_SPLIT, groups[failed[0] // S], attempts + 1
        attempts += 1
        pending = failed
    return SOLVED, 0, attempts
