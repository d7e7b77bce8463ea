"""The split stages of Ising target sharing (paper 5.3, Algorithm 3): the search, in Python.

Contract: :meth:`SplitStages.split_all` makes the decisions of ``SplitSearch.split_all`` in
``tests/sharing_search_reference.py`` (its oracle): the same groups, memo, stage submissions, seeds and
win draws, retries, candidate order and beam; the loops over nodes and reads are compiled steps
(:mod:`.stage_steps`, :mod:`.clusters`).  Where the search cannot go on it raises :class:`SharingStop`
naming why.  Design notes: docs/design/ising_sharing.md.
"""

from __future__ import annotations

import numpy as np

from planners.ising.sharing.bundles import SharingFailure
from planners.ising.sharing.clusters import coarsen, expand_candidates
from planners.ising.sharing.node_sets import intern
from planners.ising.sharing.stage_steps import (COARSE, FAILED_SPLIT, NO_ROOM, REFUSED_STAGE, SPLITS,
                                                STAGES, STATES, StageBook, StoreArrays, expand_states, set_nodes,
                                                solve_splits, todo_groups)
from planners.ising.sharing.submission import stage_refusal

__all__ = ["SplitStages", "SharingStop", "CandidateStore"]



class SharingStop(SharingFailure):
    """The search stopped where it could not go on (the message names why); the caller records the
    counters so far and reports the failure."""


class CandidateStore:
    """Each split problem's distinct valid candidates, best cut first: ``arrays`` the
    :class:`~.stage_steps.StoreArrays`, grown by rows as problems come."""

    def __init__(self, width: int, rows: int = 16):
        self.arrays = StoreArrays(cut=np.zeros((rows, width)), side0=np.zeros((rows, width), dtype=np.int64),
                                  side1=np.zeros((rows, width), dtype=np.int64), count=np.zeros(rows, dtype=np.int64))

    def reserve(self, n: int) -> None:
        """Room for ``n`` problems (rows kept)."""
        rows = self.arrays.cut.shape[0]
        if n > rows:
            cap = max(n, 2 * rows)
            grown = []
            for a in self.arrays:
                b = np.zeros((cap,) + a.shape[1:], dtype=a.dtype)
                b[:rows] = a
                grown.append(b)
            self.arrays = StoreArrays(*grown)


class SplitStages:
    """The split stages of one sharing call on one chip session (module docstring).

    ``solver``: the call's :class:`~.submission.StageSolver`; ``machine``: the session's record;
    ``counters`` / ``mapping``: the call's counters (indexed as :data:`.stage_steps.COUNTERS`) and per-rule
    candidates / valid / wins, updated in place; ``calls`` / ``seconds`` list each submission's chip
    calls and emulation seconds for the session's ``settle``."""

    def __init__(self, solver, machine, pool, rng, limit: int, store: CandidateStore, counters, mapping):
        self.solver = solver
        self.machine = machine
        self.pool = pool
        self.rng = rng
        self.limit = limit
        self.store = store
        self.counters = counters
        self.mapping = mapping
        self.retries = solver.config.retries
        self.n_spins = solver.n_spins
        self.program = solver.program()
        # the compiled step's counters and per-submission charges (one row per submission of a call)
        self._book = StageBook(mapping=mapping, counters=counters, calls=np.zeros(self.retries + 1, dtype=np.int64),
                               emu=np.zeros(self.retries + 1))
        self.n_prob = 0
        self.memo: dict = {}
        self.calls: list[int] = []
        self.seconds: list[float] = []

    # ------------------------------------------------------------ submissions

    def solve(self, ws, R, groups, balance: float, reject: bool, rows) -> None:
        """Solve the splits of ``groups`` on the weights ``ws (S, n, n)`` into store ``rows`` (problem
        ``i * S + s``: group ``i``, weights ``s``) -- :func:`.stage_steps.solve_splits`, charged and
        counted; where it cannot go on a :class:`SharingStop` naming why."""
        book = self._book
        status, what, subs = solve_splits(ws, R, groups, balance, reject, rows, self.rng, self.program, self.machine,
                                          book, self.store.arrays, self.pool)
        self.calls.extend(book.calls[:subs].tolist())
        self.seconds.extend(book.emu[:subs].tolist())
        if status == FAILED_SPLIT:
            nodes = set_nodes(self.pool, what).tolist()
            raise SharingStop(f"every chip candidate for the split of group {nodes} was invalid after {subs} "
                              "submissions")
        if status == REFUSED_STAGE:
            raise SharingStop(stage_refusal(what))
        if status == NO_ROOM:
            raise SharingStop("internal error: a split has more candidates than the sharing made room for")

    def coarse_split(self, w, R, g, reject, balance, row, scratch) -> None:
        """The split of group ``g`` (beyond the chip) on target clusters into store row ``row``
        (``scratch``: a free row for the coarse split) -- ``coarse_split`` of the oracle."""
        n_spins = self.n_spins
        nodes = set_nodes(self.pool, g)
        robots = int(np.searchsorted(nodes, R))
        clustered = 0
        if n_spins + 2 - robots < max(1, n_spins // 2):
            # more robots than leave half the chip to target clusters: neighbouring robots are clustered too
            clustered = max(2, (n_spins + 2) // 2)
            if robots < 2 or n_spins + 2 - clustered < 1:
                raise SharingStop(f"a group of {robots} robots and {nodes.shape[0] - robots} targets cannot be "
                                  f"coarsened onto the chip: its split needs at least {clustered - 1} free spins, "
                                  f"the chip has {n_spins}")
        n_clusters = n_spins + 2 - (robots if clustered == 0 else min(robots, clustered))
        members, start, wc = coarsen(w, nodes, R, n_clusters, clustered)
        coarse_robots = int((members[start[:-1]] < R).sum())
        self.counters[STAGES] += 1  # the coarse split is a stage of one split
        self.counters[SPLITS] += 1
        cg = np.array([intern(self.pool, np.arange(start.shape[0] - 1))], dtype=np.int64)
        self.store.reserve(max(row, scratch) + 1)
        self.solve(wc[None], coarse_robots, cg, balance, reject, np.array([scratch], dtype=np.int64))
        expand_candidates(w, self.pool, self.store.arrays, scratch, row, members, start)
        self.counters[COARSE] += 1

    # ----------------------------------------------------------------- stages

    def stage(self, w, R, todo, sizes, kind: int, reject_robots: bool, balance: float) -> np.ndarray:
        """The store rows of the splits of groups ``todo`` (``SplitSearch.stage``, the oracle): the
        groups met before (any state, any stage of this ``kind``) reuse their row; the others are
        solved in one submission (plus retries), groups beyond the chip on clusters first.  ``sizes``:
        the groups' node counts."""
        n_prob = self.n_prob
        rows = np.empty(todo.shape[0], dtype=np.int64)
        fresh: list[int] = []
        big: list[bool] = []
        for t, (g, z) in enumerate(zip(todo.tolist(), sizes.tolist())):
            key = (g, kind)
            if key not in self.memo:
                self.memo[key] = n_prob + len(fresh)
                fresh.append(g)
                big.append(z - 2 > self.limit)
            rows[t] = self.memo[key]
        nf = len(fresh)
        fresh = np.array(fresh, dtype=np.int64)
        big = np.array(big, dtype=bool)
        self.store.reserve(n_prob + nf + 1)
        bal = balance if kind == 0 else 0.0
        reject = reject_robots and kind == 0
        for i in np.flatnonzero(big).tolist():  # groups beyond the chip split on clusters first, in order
            self.coarse_split(w, R, int(fresh[i]), reject, bal, n_prob + i, n_prob + nf)
        self.counters[STAGES] += 1
        self.counters[SPLITS] += nf
        normal = np.flatnonzero(~big)
        if normal.shape[0]:
            self.solve(w[None], R, fresh[normal], bal, reject, n_prob + normal)
        self.n_prob = n_prob + nf
        return rows

    def split_all(self, w, R, cfg):
        """``SplitSearch.split_all`` (the oracle): ``(groups (S, G), ng (S,))``, the candidate partial
        solutions as rows of group ids, best summed cut first, under the sharing's configuration ``cfg``
        (beams, states, stages, sizes, balance)."""
        beam, refine_beam, max_states, refine_stages = cfg.beam, cfg.refine_beam, cfg.max_states, cfg.refine_stages
        base_max, above, reject_robots = cfg.resolved_base_max, cfg.refine_above, int(cfg.reject_empty_robot_side)
        balance = float(cfg.balance)
        n = w.shape[0]
        score = np.zeros(1)
        groups = np.zeros((1, n), dtype=np.int64)
        groups[0, 0] = intern(self.pool, np.arange(n))
        ng = np.ones(1, dtype=np.int64)
        stage = 0
        while True:
            kind = 0 if stage == 0 else 1
            ts, tg, sizes = todo_groups(groups, ng, R, kind, base_max, above, self.pool)
            if ts.shape[0] == 0:
                if stage == 0:  # robot stages done: the refinement stages
                    stage = 1
                    continue
                break
            if stage > refine_stages:
                break
            rows = self.stage(w, R, groups[ts, tg], sizes, kind, bool(reject_robots), balance)
            score, groups, ng = expand_states(score, groups, ng, ts, tg, rows, beam if kind == 0 else refine_beam,
                                              max_states, self.store.arrays)
            if stage:
                stage += 1
        self.counters[STATES] += groups.shape[0]
        return groups, ng
