"""Boundary refinement of Ising target sharing (beyond paper 5.3): neighbouring robots re-split on the chip.

Contract: :func:`refine_boundaries` does what ``refine_boundaries`` of ``tests/sharing_search_reference.py``
(its oracle) does: up to ``pair_rounds`` rounds in which neighbouring robots' pairs are re-split on the
chip (once per weight shift of ``pair_shifts``, all pairs in one submission) and the re-split that lowers
a pair's route cost most is kept, largest gain first, each robot moved at most once a round.
Design notes: docs/design/ising_sharing.md.
"""

from __future__ import annotations

import numpy as np

from planners.ising.sharing.node_sets import EMPTY
from planners.ising.sharing.placement import neighbour_pairs, pair_gains, pair_groups
from planners.ising.sharing.stage_steps import PAIR_ACCEPTED, PAIR_RESPLITS, SPLITS, set_sizes

__all__ = ["refine_boundaries"]


def _split_pairs(stages, pair_w, R, groups, rows) -> None:
    """Split the pair groups into store ``rows`` (row ``j * S + s``: pair ``j``, shift ``s``): groups beyond
    the chip on clusters (per shift, in order), the others in one submission, their candidates ordered by
    the first shift's cut (the route cost decides)."""
    S = pair_w.shape[0]
    coarse = set_sizes(stages.pool, groups) - 2 > stages.limit
    for j in np.flatnonzero(coarse).tolist():
        for s in range(S):
            stages.coarse_split(pair_w[s], R, int(groups[j]), False, 0.0, int(rows[j * S + s]), stages.n_prob)
    normal = np.flatnonzero(~coarse)
    if normal.shape[0]:
        prow = rows[(normal[:, None] * S + np.arange(S)).reshape(-1)]
        stages.counters[SPLITS] += prow.shape[0]
        stages.solve(pair_w, R, groups[normal], 0.0, False, prow)


def refine_boundaries(stages, dist, pair_w, R, sets, rounds: int, per_robot: int, prices) -> None:
    """Refine ``sets`` (each robot's target set id, updated in place) by ``rounds`` rounds of pair
    re-splits (module docstring) on the split weights ``pair_w (shifts, n, n)``; ``stages``: the call's
    :class:`~.stages.SplitStages`; ``prices = (memo, pricing handle)`` of :mod:`.placement`."""
    memo, pricing = prices
    counters = stages.counters
    S = pair_w.shape[0]
    tried: set = set()
    for _ in range(rounds):
        near = neighbour_pairs(dist, sets, R, per_robot, stages.pool)
        pairs = []
        for k in range(R):
            for l in range(k + 1, R):
                key = (k, l, int(sets[k]), int(sets[l]))
                if near[k, l] and (sets[k] != EMPTY or sets[l] != EMPTY) and key not in tried:
                    tried.add(key)  # a pair seen unchanged has nothing new
                    pairs.append((k, l))
        if not pairs:
            break
        pk, pl = (np.array(side, dtype=np.int64) for side in zip(*pairs))
        groups = pair_groups(stages.pool, sets, pk, pl)
        P = len(pairs) * S
        stages.store.reserve(stages.n_prob + P + 1)
        rows = stages.n_prob + np.arange(P)
        stages.n_prob += P
        _split_pairs(stages, pair_w, R, groups, rows)
        counters[PAIR_RESPLITS] += len(pairs)
        found = pair_gains(dist, pk, pl, rows, S, sets, stages.store.arrays, memo, counters, pricing, stages.pool, R)
        gain, gk, gl, new_k, new_l = found.gain, found.k, found.l, found.new_k, found.new_l
        if gain.shape[0] == 0:
            break
        moved = np.zeros(R, dtype=bool)
        for i in sorted(range(gain.shape[0]), key=lambda i: (-gain[i], gk[i], gl[i])):  # largest gain first
            k, l = gk[i], gl[i]
            if not moved[k] and not moved[l]:
                sets[k], sets[l] = new_k[i], new_l[i]
                moved[k] = moved[l] = True
                counters[PAIR_ACCEPTED] += 1
