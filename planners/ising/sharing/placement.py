"""Bundle placement and pair pricing of Ising target sharing (paper 5.3, last step): compiled steps.

Contract: :func:`place_bundles` is ``assign_bundles`` of ``tests/sharing_search_reference.py`` (the oracle)
on set ids; :func:`pair_gains` prices the boundary refinement's candidate re-splits (:mod:`.refine`).  Sets
are priced as :class:`~.bundles.BundlePricer` prices them, one memo per call.  Design:
docs/design/ising_sharing.md, "Bundle placement and its pricing".
"""

from __future__ import annotations

import weakref
from typing import NamedTuple

import numba
import numpy as np
from numba import types
from numba.typed import Dict

from planners.ising.sharing.config import BUNDLE_ORDERS
from planners.ising.sharing.node_sets import EMPTY, contains, intern, nodes_of, robots_in, size, targets_of, union
from planners.ising.sharing.stage_steps import BUNDLES, TOUR_SOLVES
from planners.held_karp import MAX_BRUTE_TARGETS, _exact_route_cost
from planners.tours_classical import three_opt_cost

__all__ = ["new_memo", "place_bundles", "place_states", "neighbour_pairs", "pair_groups", "pair_gains", "PairGains",
           "flat_sets", "ORDER_IDS", "PRICERS"]

#: the bundle pricers of running sharing calls with a pricing tour other than ``"auto"``, by handle
PRICERS: "weakref.WeakValueDictionary[int, object]" = weakref.WeakValueDictionary()
ORDER_IDS = {name: i for i, name in enumerate(BUNDLE_ORDERS)}  # creation, far_first, near_first, largest_first


def _price_callback(handle: int, nodes: np.ndarray) -> float:
    """A bundle price by the sharing call's :class:`~.bundles.BundlePricer` (object mode): robot
    ``nodes[0]`` over targets ``nodes[1:]``; it counts its tour solves and sums their compute."""
    return PRICERS[handle].cost(int(nodes[0]), nodes[1:].tolist())


@numba.njit(cache=True)
def _priced_by(pricing, nodes):
    with numba.objmode(c="float64"):
        c = _price_callback(pricing, nodes)
    return c


@numba.njit(cache=True)
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
def new_memo():
    """An empty price memo (key ``set id * R + robot``)."""
    return Dict.empty(key_type=types.int64, value_type=types.float64)


@numba.njit(cache=True)
def place_bundles(dist, R, groups, order_id, memo, counters, pricing, pool, with_total):
    """``assign_bundles`` (the oracle) on set ids: ``(ok, sets (R,), total)`` -- ``ok`` False for a
    group that still holds several robots (outside the contract); ``total`` the summed route cost
    of the sets, left to right, when ``with_total`` (else 0: nothing more priced)."""
    sets = np.full(R, EMPTY, dtype=np.int64)
    bundles = np.empty(groups.shape[0], dtype=np.int64)
    nb = 0
    for g in groups:
        nr = robots_in(pool, g, R)
        if nr == 1:
            r = nodes_of(pool, g)[0]
            sets[r] = union(pool, sets[r], targets_of(pool, g, R))
        elif nr == 0:
            if g != EMPTY:
                bundles[nb] = g
                nb += 1
        else:  # cannot happen: a group of several robots after the splits
            return False, sets, 0.0
    counters[BUNDLES] += nb
    if nb > 0:
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
    total = 0.0
    for k in range(R if with_total else 0):
        total += _price(dist, k, sets[k], memo, counters, pricing, pool, R)
    return True, sets, total


@numba.njit(cache=True)
def place_states(dist, R, groups, ng, order_id, memo, counters, pricing, pool):
    """Every state's bundles placed (:func:`place_bundles`, states ``groups[si, :ng[si]]``, best summed cut
    first): ``(ok, sets)`` of the state of least route cost, ties to the earlier state."""
    S = groups.shape[0]
    sets = np.full(R, EMPTY, dtype=np.int64)
    best = np.inf
    for si in range(S):
        ok, placed, total = place_bundles(dist, R, groups[si, :ng[si]], order_id, memo, counters, pricing, pool, S > 1)
        if not ok:
            return False, sets
        if si == 0 or total < best - 1e-9:
            sets, best = placed, total
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
def neighbour_pairs(dist, sets, R, per_robot, pool):
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
def pair_groups(pool, sets, pk, pl):
    """The set id of each pair's group: robots ``pk[j]``, ``pl[j]`` and their targets."""
    groups = np.empty(pk.shape[0], dtype=np.int64)
    for j in range(pk.shape[0]):
        two = intern(pool, np.array([pk[j], pl[j]], dtype=np.int64))
        groups[j] = union(pool, union(pool, sets[pk[j]], sets[pl[j]]), two)
    return groups


class PairGains(NamedTuple):
    """:func:`pair_gains`' result: the pairs whose best re-split lowers their route cost, in pair order."""

    gain: np.ndarray
    k: np.ndarray  # the pair's robots
    l: np.ndarray
    new_k: np.ndarray  # their new target set ids
    new_l: np.ndarray


@numba.njit(cache=True)
def pair_gains(dist, pk, pl, rows, S, sets, store, memo, counters, pricing, pool, R):
    """The best re-split of each pair ``(pk[j], pl[j])`` among the candidates of its store rows
    ``rows[j * S + s]`` (one per shift; a partition several shifts propose counted once), by route
    cost: the :class:`PairGains` of the pairs it improves."""
    c_cut, c_m0, c_m1, c_n = store.cut, store.side0, store.side1, store.count
    n_pairs = pk.shape[0]
    gain = np.empty(n_pairs)
    gk = np.empty(n_pairs, dtype=np.int64)
    gl = np.empty(n_pairs, dtype=np.int64)
    new_k = np.empty(n_pairs, dtype=np.int64)
    new_l = np.empty(n_pairs, dtype=np.int64)
    n_gain = 0
    seen = np.empty(S * c_cut.shape[1], dtype=np.int64)
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
            gk[n_gain], gl[n_gain] = k, l
            n_gain += 1
    return PairGains(gain[:n_gain], gk[:n_gain], gl[:n_gain], new_k[:n_gain], new_l[:n_gain])


@numba.njit(cache=True)
def flat_sets(sets, pool):
    """``(targets (sum,), counts (R,))``: the robots' target sets (global nodes) back to back."""
    counts = np.empty(sets.shape[0], dtype=np.int64)
    for k in range(sets.shape[0]):
        counts[k] = size(pool, sets[k])
    flat = np.empty(counts.sum(), dtype=np.int64)
    i = 0
    for k in range(sets.shape[0]):
        flat[i:i + counts[k]] = nodes_of(pool, sets[k])
        i += counts[k]
    return flat, counts
