"""Ising target sharing (paper 5.3) from split stages to the final sets in one compiled call.

Contract: :func:`assign_kernel` does what :meth:`~.search.IsingSharing.assign` does for a finite
world of ``R >= 2`` robots and ``N >= 1`` targets (``R + N <= 62``): the split stages, with the
balance term when set (:mod:`.compiled_stages`), bundle placement in every state
(:func:`~.bundles.assign_bundles`), the choice of state and the boundary refinement
(:func:`~.boundary.refine_boundaries`), with the same rng draws.  Bundles are priced as
:class:`~.bundles.BundlePricer` prices them, one memo per call: with the pricing tour ``"auto"``
by the Held-Karp kernel up to 13 targets and the host 3-opt tour's kernel beyond, with any other
by a callback into the call's pricer (:func:`_price_callback`).
It returns ``ok = False`` with the reason in ``book[4]`` (see :mod:`.compiled_stages`); the caller
names it.
"""

from __future__ import annotations

import weakref

import numba
import numpy as np
from numba import types
from numba.typed import Dict

from planners.ising.sharing.config import BUNDLE_ORDERS
from planners.ising.sharing.compiled_stages import (
    BUNDLES, OUTSIDE, PAIR_ACCEPTED, PAIR_RESPLITS, SPLITS, TOUR_SOLVES, mask_nodes, mask_nodes_into, popcount,
    problems_of, reserve, solve_problems, split_states,
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
def _price(dist, k, mask, memo, counters, pricing):
    """:meth:`~.bundles.BundlePricer.cost_mask`: with the pricing tour ``"auto"`` (``pricing < 0``)
    Held-Karp up to 13 targets, the host 3-opt tour beyond; else the pricer registered as
    ``PRICERS[pricing]`` (a callback)."""
    if mask == 0:
        return 0.0
    key = mask | k  # target bits start at R > k
    if key in memo:
        return memo[key]
    n = popcount(mask)
    nodes = np.empty(n + 1, dtype=np.int64)  # k, then the targets ascending
    nodes[0] = k
    mask_nodes_into(mask, nodes, 1)
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
def _place_bundles(dist, R, groups, ng, order_id, memo, counters, failure, pricing):
    """:func:`~.bundles.assign_bundles` on masks: ``(ok, sets (R,))``."""
    robots = (np.int64(1) << R) - 1
    sets = np.zeros(R, dtype=np.int64)
    bundles = np.empty(ng, dtype=np.int64)
    nb = 0
    for gi in range(ng):
        g = groups[gi]
        nr = popcount(g & robots)
        if nr == 1:
            sets[mask_nodes(g & robots)[0]] |= g & ~robots
        elif nr == 0:
            if g:
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
            key[i] = -popcount(bundles[i])
        elif order_id != 0:
            near = np.inf
            for t in mask_nodes(bundles[i]):
                for k in range(R):
                    near = min(near, dist[k, t])
            key[i] = -near if order_id == 1 else near
        else:
            key[i] = i
    inc = np.empty(R)
    for i in np.argsort(key, kind="mergesort"):
        b = bundles[i]
        for k in range(R):
            inc[k] = (_price(dist, k, sets[k] | b, memo, counters, pricing)
                      - _price(dist, k, sets[k], memo, counters, pricing))
        sets[np.argmin(inc)] |= b  # the first robot of least increase
    return True, sets


@numba.njit(cache=True)
def _neighbour_pairs(dist, sets, R, per_robot):
    """:func:`~.boundary.neighbour_pairs` on masks: ``near (R, R)`` bool, pair ``(k, l)`` for ``k < l``."""
    near = np.zeros((R, R), dtype=np.bool_)
    if per_robot >= R - 1:
        near[:, :] = True
        return near
    gap = np.full((R, R), np.inf)
    for k in range(R):
        nk = mask_nodes(sets[k] | (np.int64(1) << k))
        for l in range(k + 1, R):
            nl = mask_nodes(sets[l] | (np.int64(1) << l))
            v = np.inf
            for i in nk:
                for j in nl:
                    v = min(v, dist[i, j])
            gap[k, l] = v
            gap[l, k] = v
    for k in range(R):
        order = np.argsort(gap[k], kind="mergesort")
        for l in order[:per_robot]:
            if l != k and np.isfinite(gap[k, l]):
                near[min(k, l), max(k, l)] = True
    return near


@numba.njit(cache=True)
def _refine(dist, pair_w, R, sets, rng, chip, retries, limit, rounds, per_robot, memo, book, store, n_prob, pricing):
    """:func:`~.boundary.refine_boundaries` on masks.  Returns ``(ok, store, n_prob)``;
    ``sets`` is updated in place."""
    counters = book[1]
    robots = (np.int64(1) << R) - 1
    S = pair_w.shape[0]
    tried = Dict.empty(key_type=_PAIR_KEY, value_type=types.boolean)
    pk = np.empty(R * R, dtype=np.int64)
    pl = np.empty(R * R, dtype=np.int64)
    for _ in range(rounds):
        near = _neighbour_pairs(dist, sets, R, per_robot)
        n_pairs = 0
        for k in range(R):
            for l in range(k + 1, R):
                key = (k, l, sets[k], sets[l])
                if near[k, l] and (sets[k] | sets[l]) and key not in tried:
                    tried[key] = True
                    pk[n_pairs] = k
                    pl[n_pairs] = l
                    n_pairs += 1
        if n_pairs == 0:
            break
        P = n_pairs * S
        groups = np.empty(n_pairs, dtype=np.int64)
        for j in range(n_pairs):
            groups[j] = sets[pk[j]] | sets[pl[j]] | (np.int64(1) << pk[j]) | (np.int64(1) << pl[j])
            if popcount(groups[j]) - 2 > limit:  # a coarse split: outside the contract
                book[4][0], book[4][1] = OUTSIDE, 3
                return False, store, n_prob
        f = 0
        for j in range(n_pairs):
            f = max(f, popcount(groups[j]) - 2)
        q = np.zeros((P, f))
        Q = np.zeros((P, f, f))
        free = np.zeros((P, f), dtype=np.int64)
        sizes = np.empty(P, dtype=np.int64)
        anchors = np.empty((P, 2), dtype=np.int64)
        for s in range(S):  # problem j * S + s: pair j, shift s
            qs, Qs, fs, zs, As = problems_of(pair_w[s], groups, R, 0.0)
            for j in range(n_pairs):
                p = j * S + s
                n = zs[j]
                sizes[p] = n
                anchors[p] = As[j]
                free[p, :n] = fs[j, :n]
                q[p, :n] = qs[j, :n]
                Q[p, :n, :n] = Qs[j, :n, :n]
        counters[SPLITS] += P
        store = reserve(store, n_prob + P)
        rows = n_prob + np.arange(P)
        n_prob += P
        masks = np.empty(P, dtype=np.int64)
        for p in range(P):
            masks[p] = groups[p // S]
        if not solve_problems(q, Q, free, sizes, anchors, np.zeros(P, dtype=np.bool_), rows, masks, pair_w[0], R,
                              rng, chip, retries, book, store):
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
            old = _price(dist, k, sets[k], memo, counters, pricing) + _price(dist, l, sets[l], memo, counters, pricing)
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
                    mine, theirs = (m0, m1) if (m0 >> k) & 1 else (m1, m0)
                    tk, tl = mine & ~robots, theirs & ~robots
                    new = (_price(dist, k, tk, memo, counters, pricing)
                           + _price(dist, l, tl, memo, counters, pricing))
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
def assign_kernel(dist, powered, mean, R, rng, chip, retries, limit, opts, weights, pair_shifts, pair_opts, book):
    """The sharing of one world (module docstring): ``(ok, sets (R,) target masks)``.

    ``weights = (weight_shift, robot_weight, balance)``, ``opts`` as :func:`.compiled_stages.split_states`,
    ``pair_opts = (bundle order id, pair_rounds, pair_neighbours, pricing handle or -1)``."""
    shift, robot_weight, balance = weights
    order_id, rounds, per_robot, pricing = pair_opts
    counters = book[1]
    # C-contiguous like _refine's pair weights, so the stage kernels compile for one layout only
    w = np.ascontiguousarray(split_weights_kernel(powered, mean, shift, R, robot_weight))
    C = chip[0].shape[0] * chip[4]  # distinct candidates per split: rules x reads
    store = (np.zeros((16, C)), np.zeros((16, C), dtype=np.int64), np.zeros((16, C), dtype=np.int64),
             np.zeros(16, dtype=np.int64))
    ok, groups, ng, store, n_prob = split_states(w, R, rng, chip, retries, limit, opts, balance, book, store)
    sets = np.zeros(R, dtype=np.int64)
    if not ok:
        return False, sets
    memo = Dict.empty(key_type=types.int64, value_type=types.float64)
    S = groups.shape[0]
    best = np.inf
    for si in range(S):
        ok, placed = _place_bundles(dist, R, groups[si], ng[si], order_id, memo, counters, book[4], pricing)
        if not ok:
            return False, sets
        if S == 1:
            sets = placed
            break
        total = 0.0
        for k in range(R):
            total += _price(dist, k, placed[k], memo, counters, pricing)
        if si == 0 or total < best - 1e-9:  # ties: the state with the larger cuts
            best = total
            sets = placed
    if rounds:
        pair_w = np.empty((pair_shifts.shape[0],) + w.shape)
        for s in range(pair_shifts.shape[0]):
            pair_w[s] = split_weights_kernel(powered, mean, pair_shifts[s], R, robot_weight)
        ok, store, n_prob = _refine(dist, pair_w, R, sets, rng, chip, retries, limit, rounds, per_robot, memo, book,
                                    store, n_prob, pricing)
        if not ok:
            return False, sets
    return True, sets
