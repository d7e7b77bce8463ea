"""EPIBT's records, reservation table and large-neighbourhood search over a joint plan (compiled).

:class:`Fleet`, :class:`SearchStamp` and :class:`PlanState` are the kernels' records, read by name; the table
``res[t, cell]`` holds the robot on ``cell`` at time ``t`` (-1 free); :func:`lns_search` re-chooses small groups
while their costs-to-go fall (or, annealing, rise with a falling probability).
Design notes: docs/design/lifelong_turning.md#epibts-records-and-search.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from planners.mapf.common import mix

__all__ = ["Fleet", "SearchStamp", "PlanState", "new_state", "reserve", "conflict", "blockers", "more_blockers",
           "lns_search"]


class Fleet(NamedTuple):
    """The robots of one call, as :func:`~planners.mapf.epibt.plans.epibt_kernel` reads them (compact cells)."""

    pos: np.ndarray        # (R,) cell now
    orient: np.ndarray     # (R,) orientation
    goals: np.ndarray      # (R,) goal cell
    rows: np.ndarray       # (R,) row of the heuristic's fields (-1: Manhattan)
    prio: np.ndarray       # (R,) priority (higher first; elapsed steps + tie)
    inherited: np.ndarray  # (R, op_len) fallback operation, jointly conflict-free
    weight: np.ndarray     # (R,) multiplies the robot's costs-to-go


class SearchStamp(NamedTuple):
    """One plan's seed and search budget."""

    seed: int      # the plan's seed (:func:`~planners.mapf.epibt.plans.portfolio_seed`)
    t: int         # the call's step
    revisits: int  # choices a robot may make per call
    lns: int       # large-neighbourhood iterations
    group: int     # robots per neighbourhood
    anneal: float = 0.0  # the search's starting temperature (share of a neighbourhood's cost); 0: descent


class PlanState(NamedTuple):
    """One call's joint plan, filled by :func:`~planners.mapf.epibt.plans.epibt_kernel` (numba compiles it as a tuple)."""

    cells: np.ndarray     # (R, n_ops, op_len + 1): each robot's ranked operations' cells
    which: np.ndarray     # (R, n_ops): the operation each candidate is
    costs: np.ndarray     # (R, n_ops): its (weighted) cost-to-go
    ncand: np.ndarray     # (R,): how many candidates
    cur: np.ndarray       # (R, op_len + 1): the robot's cells now
    src: np.ndarray       # (R,): the candidate they are (-1: inherited)
    inh: np.ndarray       # (R, op_len + 1): its inherited operation's cells
    inh_cost: np.ndarray  # (R,): their cost-to-go


def new_state(r: int, ops: np.ndarray) -> PlanState:
    """An empty :class:`PlanState` for ``r`` robots and the operations ``ops``."""
    n_ops, length = ops.shape
    return PlanState(np.empty((r, n_ops, length + 1), np.int64), np.empty((r, n_ops), np.int64),
                     np.empty((r, n_ops), np.int64), np.empty(r, np.int64), np.empty((r, length + 1), np.int64),
                     np.full(r, -1, np.int64), np.empty((r, length + 1), np.int64), np.empty(r, np.int64))


@numba.njit(cache=True, nogil=True)
def reserve(res, path, a, who) -> None:
    """Put robot ``a`` (``who`` = a) on ``path`` in the table, or take it off (``who`` = -1)."""
    for t in range(path.shape[0]):
        if who >= 0:
            res[t, path[t]] = a
        elif res[t, path[t]] == a:
            res[t, path[t]] = -1


@numba.njit(cache=True, nogil=True)
def conflict(res, path, a) -> int:
    """The one robot ``path`` collides with (vertex or swap, times 1..), -1 none, -2 more than one."""
    found = -1
    for t in range(1, path.shape[0]):
        v, u = path[t], path[t - 1]
        for b in (res[t, v], res[t - 1, v] if u != v and res[t, u] == res[t - 1, v] else -1):
            if b < 0 or b == a:
                continue
            if found == -1:
                found = b
            elif found != b:
                return -2
    return found


@numba.njit(cache=True, nogil=True)
def blockers(k, cells, top, res, size, members, mark) -> int:
    """``members[:n]``: robot ``k``, then the robots in the way of its first ``top`` operations (at most
    ``size`` in all); ``mark`` set for them."""
    members[0] = k
    mark[k] = 1
    return more_blockers(k, cells, top, res, size, members, 1, mark)


@numba.njit(cache=True, nogil=True)
def more_blockers(k, cells, top, res, size, members, n, mark) -> int:
    """After ``members[:n]``, the unmarked robots in the way of robot ``k``'s first ``top`` operations (at most
    ``size`` in all), marked; returns the new ``n``."""
    for c in range(top):
        path = cells[k, c]
        for s in range(1, path.shape[0]):
            v, u = path[s], path[s - 1]
            for b in (res[s, v], res[s - 1, v] if u != v and res[s, u] == res[s - 1, v] else -1):
                if b >= 0 and mark[b] == 0 and n < size:
                    members[n] = b
                    mark[b] = 1
                    n += 1
    return n


@numba.njit(cache=True, nogil=True)
def _uniform(seed, t, it, salt) -> float:
    return float(mix(seed, t, it, salt) >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@numba.njit(cache=True, nogil=True)
def lns_search(state, res, stamp) -> None:
    """Large-neighbourhood search over ``state`` (a :class:`PlanState`) by ``stamp`` (a :class:`SearchStamp`):
    ``lns`` times, a robot not on its best operation and the robots in the way of its better ones (at most
    ``group``) choose again in a seeded order, each its best operation colliding with no one (or its inherited
    one); kept when their summed ``costs`` fall, or by the annealing rule of the module docstring."""
    cells, costs, ncand = state.cells, state.costs, state.ncand
    cur, src, inh, inh_cost = state.cur, state.src, state.inh, state.inh_cost
    seed, t, iters, group, temp0 = stamp.seed, stamp.t, stamp.lns, stamp.group, stamp.anneal
    r = cur.shape[0]
    if r == 0:
        return
    members = np.empty(group, dtype=np.int64)
    mark = np.zeros(r, dtype=np.int8)
    keys = np.empty(group, dtype=np.uint64)
    old_src = np.empty(group, dtype=np.int64)
    old_cur = np.empty((group, cur.shape[1]), dtype=np.int64)
    start = np.int64(mix(seed, t, r, 0) % np.uint64(max(r, 1)))
    anneal = temp0 > 0.0
    best_src = src.copy()  # the best plan met, saved when the search leaves it for a worse one
    best_cur = cur.copy()
    # numba's int64 throughout; mypy tells numpy's int64 from int (local annotations make no bytecode)
    after: int | np.int64
    total: int | np.int64
    best: int | np.int64
    total, best, at_best = 0, 0, True
    for it in range(iters):
        k = (start + it) % r
        if src[k] == 0 or ncand[k] == 0:
            continue
        temp = temp0 * (1.0 - it / iters)
        top = src[k] if src[k] > 0 else ncand[k]
        n = blockers(k, cells, top, res, group, members, mark)
        before = 0
        for j in range(n):
            i = members[j]
            mark[i] = 0
            before += costs[i, src[i]] if src[i] >= 0 else inh_cost[i]
            old_src[j] = src[i]
            old_cur[j] = cur[i]
            reserve(res, cur[i], i, -1)
            keys[j] = mix(seed, t, it, i)
        cutoff = before if not anneal else before + np.int64(20.0 * temp * max(before, 1))
        idx = np.argsort(keys[:n])
        after = 0
        placed = 0
        for j in idx:
            i = members[j]
            pick = -2
            for c in range(ncand[i]):
                if conflict(res, cells[i, c], i) == -1:
                    pick = c
                    break
            if pick == -2 and conflict(res, inh[i], i) == -1:
                pick = -1
            if pick == -2 or after >= cutoff:
                after = cutoff
                break
            cur[i] = cells[i, pick] if pick >= 0 else inh[i]
            src[i] = pick
            reserve(res, cur[i], i, i)
            after += costs[i, pick] if pick >= 0 else inh_cost[i]
            placed += 1
        keep = placed == n and after < before
        if anneal and placed == n and not keep and temp > 0.0 and after < cutoff:
            keep = _uniform(seed, t, it, r + 7) < np.exp(-(after - before) / (temp * max(before, 1)))
        if keep:
            if after >= before and at_best:
                best_src[:] = src
                best_cur[:] = cur
                for j in range(n):  # the saved plan is the one before this move
                    best_src[members[j]] = old_src[j]
                    best_cur[members[j]] = old_cur[j]
                at_best = False
            total += after - before
            if total < best:
                best, at_best = total, True
            continue
        for j in idx[:placed]:
            reserve(res, cur[members[j]], members[j], -1)
        for j in range(n):
            i = members[j]
            src[i] = old_src[j]
            cur[i] = old_cur[j]
            reserve(res, cur[i], i, i)
    if not at_best:  # back to the best plan met
        for i in range(r):
            reserve(res, cur[i], i, -1)
        for i in range(r):
            src[i] = best_src[i]
            cur[i] = best_cur[i]
            reserve(res, cur[i], i, i)
