"""Ising target sharing (paper 5.3) from split stages to the final sets in one compiled call.

Contract: :func:`assign_kernel` does what :meth:`~.search.IsingSharing.assign` does for a finite
world of ``R >= 2`` robots and ``N >= 1`` targets: the split stages, with the balance term when
set, coarse splits and spin-budget branches for groups beyond the chip (:mod:`.compiled_stages`),
bundle placement in every state, the choice of state and the boundary refinement -- the decisions
and rng draws of the Python search in ``tests/sharing_search_reference.py``, its oracle.  Bundles
are priced as :class:`~.bundles.BundlePricer` prices them, one memo per call: with the pricing
tour ``"auto"`` by the Held-Karp kernel up to 13 targets and the host 3-opt tour's kernel beyond,
with any other by a callback into the call's pricer (:func:`_price_callback`).  It returns
``ok = False`` with the reason in ``book[4]`` (see :mod:`.compiled_stages`); the caller names it.
"""

from __future__ import annotations

import weakref

import numba
import numpy as np
from numba import types
from numba.typed import Dict

from planners.ising.sharing.config import BUNDLE_ORDERS
from planners.ising.sharing.compiled_stages import (
    BUNDLES, FAILED_SPLIT, OUTSIDE, PAIR_ACCEPTED, PAIR_RESPLITS, SPLITS, TOUR_SOLVES, coarse_split, problems_of,
    reserve, solve_problems, split_states,
)
from planners.ising.sharing.node_sets import (
    EMPTY, contains, intern, new_pool, nodes_of, robots_in, size, targets_of, union,
)
from planners.held_karp import MAX_BRUTE_TARGETS, _exact_route_cost
from planners.tours_classical import three_opt_cost

__all__ = ["assign_kernel", "split_weights_kernel", "ORDER_IDS", "PRICERS"]

#: the bundle pricers of running sharing calls with a pricing tour other than ``"auto"``, by handle
PRICERS: "weakref.WeakValueDictionary[int, object]" = weakref.WeakValueDictionary()
_PAIR_KEY = types.UniTuple(types.int64, 4)  # (k, l, targets of k, targets of l)
ORDER_IDS = {name: i for i, name in enumerate(BUNDLE_ORDERS)}  # creation, far_first, near_first, largest_first


@numba.njit(cache=True)
def split_weights_kernel(powered, mean, shift, R, robot_weight):
    """:meth:`~.search.IsingSharing.split_weights` from ``dist ** weight_power`` and its pair mean."""
    w = powered
    if shift:
        w = powered - shift * mean
        for i in range(w.shape[0]):
            w[i, i] = 0.0
    if robot_weight != 1.0:
        w = w.copy()
        w[:R, R:] *= robot_weight
        w[R:, :R] *= robot_weight
    return w


def _price_callback(handle: int, nodes: np.ndarray) -> float:
    """A bundle price by the sharing call's :class:`~.bundles.BundlePricer` (object mode): robot
    ``nodes[0]`` over targets ``nodes[1:]``; it counts its tour solves and sums their compute."""
    return PRICERS[handle].cost(int(nodes[0]), nodes[1:].tolist())


@numba.njit(cache=True)
def _priced_by(pricing, nodes):
    with numba.objmode(c="float64"):
        c = _price_callback(pricing, nodes)
    return c


@numba.njit(cache=True, inline="always")
def _price(dist, k, s, memo, counters, pricing, pool, R):
    """:meth:`~.bundles.BundlePricer.cost_mask`: with the pricing tour ``"auto"`` (``pricing < 0``)
    Held-Karp up to 13 targets, the host 3-opt tour beyond; else the pricer registered as
    ``PRICERS[pricing]`` (a callback)."""
    if s == EMPTY:
        return 0.0
    key = s * R + k
    if key in memo:
        return memo[key]
    t = nodes_of(pool, s)
    n = t.shape[0]
    nodes = np.empty(n + 1, dtype=np.int64)  # k, then the targets ascending
    nodes[0] = k
    nodes[1:] = t
    if pricing >= 0:
        c = _priced_by(pricing, nodes)
        memo[key] = c
        return c
    if n <= MAX_BRUTE_TARGETS:
        c = _exact_route_cost(dist, nodes)
    else:
        sub = np.empty((n + 1, n + 1))
        for i in range(n + 1):
            for j in range(n + 1):
                sub[i, j] = dist[nodes[i], nodes[j]]
        c = three_opt_cost(sub)
    counters[TOUR_SOLVES] += 1
    memo[key] = c
    return c


@numba.njit(cache=True)
def _place_bundles(dist, R, groups, ng, order_id, memo, counters, failure, pricing, pool):
    """``assign_bundles`` (the oracle) on set ids: ``(ok, sets (R,))``."""
    sets = np.full(R, EMPTY, dtype=np.int64)
    bundles = np.empty(ng, dtype=np.int64)
    nb = 0
    for gi in range(ng):
        g = groups[gi]
        nr = robots_in(pool, g, R)
        if nr == 1:
            r = nodes_of(pool, g)[0]
            sets[r] = union(pool, sets[r], targets_of(pool, g, R))
        elif nr == 0:
            if g != EMPTY:
                bundles[nb] = g
                nb += 1
        else:  # cannot happen: a group of several robots after the splits
            failure[0], failure[1] = OUTSIDE, 4
            return False, sets
    counters[BUNDLES] += nb
    if nb == 0:
        return True, sets
    key = np.empty(nb)
    for i in range(nb):
        if order_id == 3:
            key[i] = -size(pool, bundles[i])
        elif order_id != 0:
            near = np.inf
            for t in nodes_of(pool, bundles[i]):
                for k in range(R):
                    near = min(near, dist[k, t])
            key[i] = -near if order_id == 1 else near
        else:
            key[i] = i
    inc = np.empty(R)
    for i in np.argsort(key, kind="mergesort"):
        b = bundles[i]
        for k in range(R):
            inc[k] = (_price(dist, k, union(pool, sets[k], b), memo, counters, pricing, pool, R)
                      - _price(dist, k, sets[k], memo, counters, pricing, pool, R))
        k = np.argmin(inc)  # the first robot of least increase
        sets[k] = union(pool, sets[k], b)
    return True, sets


@numba.njit(cache=True)
def _gap(dist, k, tk, l, tl):
    """The least distance between robot ``k`` with its targets ``tk`` and robot ``l`` with ``tl``."""
    v = dist[k, l]
    for j in tl:
        v = min(v, dist[k, j])
    for i in tk:
        v = min(v, dist[i, l])
        for j in tl:
            v = min(v, dist[i, j])
    return v


@numba.njit(cache=True)
def _neighbour_pairs(dist, sets, R, per_robot, pool):
    """``neighbour_pairs`` (the oracle) on set ids: ``near (R, R)`` bool, pair ``(k, l)`` for ``k < l``."""
    near = np.zeros((R, R), dtype=np.bool_)
    if per_robot >= R - 1:
        near[:, :] = True
        return near
    gap = np.full((R, R), np.inf)
    for k in range(R):
        for l in range(k + 1, R):
            v = _gap(dist, k, nodes_of(pool, sets[k]), l, nodes_of(pool, sets[l]))
            gap[k, l] = v
            gap[l, k] = v
    for k in range(R):
        order = np.argsort(gap[k], kind="mergesort")
        for l in order[:per_robot]:
            if l != k and np.isfinite(gap[k, l]):
                near[min(k, l), max(k, l)] = True
    return near


@numba.njit(cache=True)
def _refine(dist, pair_w, R, sets, rng, chip, retries, limit, rounds, per_robot, memo, book, store, n_prob, pricing,
            pool):
    """``refine_boundaries`` (the oracle) on set ids.  Returns ``(ok, store, n_prob)``;
    ``sets`` is updated in place."""
    counters = book[1]
    S = pair_w.shape[0]
    tried = Dict.empty(key_type=_PAIR_KEY, value_type=types.boolean)
    pk = np.empty(R * R, dtype=np.int64)
    pl = np.empty(R * R, dtype=np.int64)
    for _ in range(rounds):
        near = _neighbour_pairs(dist, sets, R, per_robot, pool)
        n_pairs = 0
        for k in range(R):
            for l in range(k + 1, R):
                key = (k, l, sets[k], sets[l])
                if near[k, l] and (sets[k] != EMPTY or sets[l] != EMPTY) and key not in tried:
                    tried[key] = True
                    pk[n_pairs] = k
                    pl[n_pairs] = l
                    n_pairs += 1
        if n_pairs == 0:
            break
        P = n_pairs * S
        groups = np.empty(n_pairs, dtype=np.int64)
        for j in range(n_pairs):
            two = intern(pool, np.array([pk[j], pl[j]], dtype=np.int64))
            groups[j] = union(pool, union(pool, sets[pk[j]], sets[pl[j]]), two)
        store = reserve(store, n_prob + P + 1)
        rows = n_prob + np.arange(P)
        n_prob += P
        # problem j * S + s: pair j, shift s; groups beyond the chip split on clusters first, in that order
        coarse = np.zeros(n_pairs, dtype=np.bool_)
        n_normal = 0
        for j in range(n_pairs):
            coarse[j] = size(pool, groups[j]) - 2 > limit
            if not coarse[j]:
                n_normal += 1
                continue
            for s in range(S):
                ok, store = coarse_split(pair_w[s], R, groups[j], False, 0.0, rows[j * S + s], n_prob, rng, chip,
                                         retries, book, store, pool)
                if not ok:
                    return False, store, n_prob
        if n_normal:
            normal = np.empty(n_normal, dtype=np.int64)
            t = 0
            for j in range(n_pairs):
                if not coarse[j]:
                    normal[t] = groups[j]
                    t += 1
            f = 0
            for j in range(n_normal):
                f = max(f, size(pool, normal[j]) - 2)
            Pn = n_normal * S
            q = np.zeros((Pn, f))
            Q = np.zeros((Pn, f, f))
            free = np.zeros((Pn, f), dtype=np.int64)
            sizes = np.empty(Pn, dtype=np.int64)
            anchors = np.empty((Pn, 2), dtype=np.int64)
            for s in range(S):  # problem i * S + s: the i-th pair that fits, shift s
                qs, Qs, fs, zs, As = problems_of(pair_w[s], normal, R, 0.0, pool)
                for i in range(n_normal):
                    p = i * S + s
                    n = zs[i]
                    sizes[p] = n
                    anchors[p] = As[i]
                    free[p, :n] = fs[i, :n]
                    q[p, :n] = qs[i, :n]
                    Q[p, :n, :n] = Qs[i, :n, :n]
            counters[SPLITS] += Pn
            prow = np.empty(Pn, dtype=np.int64)
            gids = np.empty(Pn, dtype=np.int64)
            i = 0
            for j in range(n_pairs):
                if not coarse[j]:
                    for s in range(S):
                        prow[i * S + s] = rows[j * S + s]
                        gids[i * S + s] = groups[j]
                    i += 1
            if not solve_problems(q, Q, free, sizes, anchors, np.zeros(Pn, dtype=np.bool_), prow, gids, pair_w[0], R,
                                  rng, chip, retries, book, store, pool):
                return False, store, n_prob
        c_cut, c_m0, c_m1, c_n = store
        counters[PAIR_RESPLITS] += n_pairs
        gain = np.empty(n_pairs)
        new_k = np.empty(n_pairs, dtype=np.int64)
        new_l = np.empty(n_pairs, dtype=np.int64)
        n_gain = 0
        seen = np.empty(P * c_cut.shape[1], dtype=np.int64)
        for j in range(n_pairs):
            k, l = pk[j], pl[j]
            old = (_price(dist, k, sets[k], memo, counters, pricing, pool, R)
                   + _price(dist, l, sets[l], memo, counters, pricing, pool, R))
            best = np.inf
            found = False
            n_seen = 0
            for s in range(S):
                row = rows[j * S + s]
                for c in range(c_n[row]):
                    m1 = c_m1[row, c]
                    dup = False
                    for u in range(n_seen):  # several shifts often propose the same partition
                        dup = dup or seen[u] == m1
                    if dup:
                        continue
                    seen[n_seen] = m1
                    n_seen += 1
                    m0 = c_m0[row, c]
                    mine, theirs = (m0, m1) if contains(pool, m0, k) else (m1, m0)
                    tk, tl = targets_of(pool, mine, R), targets_of(pool, theirs, R)
                    new = (_price(dist, k, tk, memo, counters, pricing, pool, R)
                           + _price(dist, l, tl, memo, counters, pricing, pool, R))
                    if new < old - 1e-9 and (not found or new < best - 1e-9):
                        best = new
                        found = True
                        new_k[n_gain] = tk
                        new_l[n_gain] = tl
            if found:
                gain[n_gain] = old - best
                pk[n_gain], pl[n_gain] = k, l  # j >= n_gain: pairs not yet read stay in place
                n_gain += 1
        if n_gain == 0:
            break
        order = np.arange(n_gain)
        for a in range(1, n_gain):  # insertion sort: largest gain first, ties by (k, l)
            i = order[a]
            b = a
            while b > 0 and (gain[order[b - 1]] < gain[i] or (gain[order[b - 1]] == gain[i] and (
                    pk[order[b - 1]] > pk[i] or (pk[order[b - 1]] == pk[i] and pl[order[b - 1]] > pl[i])))):
                order[b] = order[b - 1]
                b -= 1
            order[b] = i
        moved = np.zeros(R, dtype=np.bool_)
        for i in order:
            k, l = pk[i], pl[i]
            if not moved[k] and not moved[l]:
                sets[k] = new_k[i]
                sets[l] = new_l[i]
                moved[k] = moved[l] = True
                counters[PAIR_ACCEPTED] += 1
    return True, store, n_prob


@numba.njit(cache=True)
def _result(ok, sets, book, pool):
    """``(ok, targets (sum,), counts (R,), failed group (nodes))``: the robots' target sets back to back,
    and the nodes of the group whose split failed (empty unless one did)."""
    counts = np.empty(sets.shape[0], dtype=np.int64)
    for k in range(sets.shape[0]):
        counts[k] = size(pool, sets[k])
    flat = np.empty(counts.sum(), dtype=np.int64)
    i = 0
    for k in range(sets.shape[0]):
        flat[i:i + counts[k]] = nodes_of(pool, sets[k])
        i += counts[k]
    failed = nodes_of(pool, book[4][1] if book[4][0] == FAILED_SPLIT else EMPTY)
    return ok, flat, counts, failed.copy()


@numba.njit(cache=True)
def assign_kernel(dist, powered, mean, R, rng, chip, retries, limit, opts, weights, pair_shifts, pair_opts, book):
    """The sharing of one world (module docstring), as :func:`_result`.

    ``weights = (weight_shift, robot_weight, balance)``, ``opts`` as :func:`.compiled_stages.split_states`,
    ``pair_opts = (bundle order id, pair_rounds, pair_neighbours, pricing handle or -1)``."""
    shift, robot_weight, balance = weights
    order_id, rounds, per_robot, pricing = pair_opts
    counters = book[1]
    pool = new_pool(R)
    # C-contiguous like _refine's pair weights, so the stage kernels compile for one layout only
    w = np.ascontiguousarray(split_weights_kernel(powered, mean, shift, R, robot_weight))
    # distinct candidates per split: rules x reads x the spin-budget branches of a split beyond the chip
    C = chip[0].shape[0] * chip[5] * (1 << max(0, min(limit - chip[3], dist.shape[0] - 2 - chip[3])))
    store = (np.zeros((16, C)), np.zeros((16, C), dtype=np.int64), np.zeros((16, C), dtype=np.int64),
             np.zeros(16, dtype=np.int64))
    ok, groups, ng, store, n_prob = split_states(w, R, rng, chip, retries, limit, opts, balance, book, store, pool)
    sets = np.full(R, EMPTY, dtype=np.int64)
    if not ok:
        return _result(False, sets, book, pool)
    memo = Dict.empty(key_type=types.int64, value_type=types.float64)
    S = groups.shape[0]
    best = np.inf
    for si in range(S):
        ok, placed = _place_bundles(dist, R, groups[si], ng[si], order_id, memo, counters, book[4], pricing, pool)
        if not ok:
            return _result(False, sets, book, pool)
        if S == 1:
            sets = placed
            break
        total = 0.0
        for k in range(R):
            total += _price(dist, k, placed[k], memo, counters, pricing, pool, R)
        if si == 0 or total < best - 1e-9:  # ties: the state with the larger cuts
            best = total
            sets = placed
    if rounds:
        pair_w = np.empty((pair_shifts.shape[0],) + w.shape)
        for s in range(pair_shifts.shape[0]):
            pair_w[s] = split_weights_kernel(powered, mean, pair_shifts[s], R, robot_weight)
        ok, store, n_prob = _refine(dist, pair_w, R, sets, rng, chip, retries, limit, rounds, per_robot, memo, book,
                                    store, n_prob, pricing, pool)
        if not ok:
            return _result(False, sets, book, pool)
    return _result(True, sets, book, pool)
