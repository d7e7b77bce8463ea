"""Compiled dynamics of the lifelong envs (``mrmt_env/MRMT-Lifelong-v0`` ...), batched over ``B`` episodes.

A step: robots propose moves, conflicts are refused (``collisions="block"``) or counted (``"allow"``), a robot on
an open task serves it, new tasks arrive (``refill`` or ``poisson``) from a SplitMix64 stream keyed per episode;
counters per env in :data:`COUNTERS`. Design notes: docs/design/lifelong.md#lifelong-dynamics.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

__all__ = ["COUNTERS", "LifelongArrays", "lifelong_load", "lifelong_step", "resolve_block", "uniform01", "poisson_count"]

COUNTERS = ("steps", "route_cost", "tasks_completed", "invalid_moves", "vertex_conflicts", "swap_conflicts",
            "blocked_moves", "service_sum", "tasks_arrived", "tasks_dropped", "open_tasks")
(_STEPS, _COST, _DONE, _INVALID, _VERTEX, _SWAP, _BLOCKED, _SERVICE, _ARRIVED, _DROPPED, _OPEN) = range(11)
#: Marks of a pool cell out of the free pool: it holds an open task, or a robot stands on it.
_HAS_TASK = -2
_HAS_ROBOT = -3

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)


class LifelongArrays(NamedTuple):
    """The batch's arrays every kernel call takes, read by name (``B`` envs, ``R`` robots)."""

    succ: np.ndarray      # (B, H*W, 5): the cell each action leads to
    pos: np.ndarray       # (B, R): robot cells
    at: np.ndarray        # (B, H*W): the robot on each cell, -1 none
    task_t: np.ndarray    # (B, H*W): the step the open task on the cell arrived, -1 none
    free: np.ndarray      # (B, H*W): the pool cells a task may arrive on now, listed first
    free_idx: np.ndarray  # (B, H*W): each cell's index in ``free``, -1 none
    n_free: np.ndarray    # (B,): how many are listed
    moves: np.ndarray     # (B, R): moves per robot
    counters: np.ndarray  # (B, len(COUNTERS))
    obs: np.ndarray       # (B, 2 + R, H*W): the observation planes


@numba.njit(cache=True, nogil=True)
def uniform01(key, counter) -> float:
    """A double in [0, 1) from SplitMix64 of ``key + (counter + 1) * golden``."""
    z = key + (counter + np.uint64(1)) * _GOLDEN
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    z = z ^ (z >> np.uint64(31))
    return float(z >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@numba.njit(cache=True, nogil=True)
def poisson_count(u, rate) -> int:
    """The Poisson(``rate``) count whose CDF first exceeds ``u`` (inversion; rate <= 500)."""
    p = np.exp(-rate)
    cdf = p
    k = 0
    while u >= cdf and k < 100000:
        k += 1
        p *= rate / k
        cdf += p
        if p == 0.0 and k > rate:
            break
    return k


@numba.njit(cache=True, nogil=True)
def lifelong_load(b, grid, width, robots, tasks, pool, state) -> None:
    """Start env ``b``: flat grid, robot cells, the initial open tasks and the task pool (flat cells).
    ``state`` the batch's :class:`LifelongArrays` (:attr:`~mrmt_env.lifelong.state.LifelongBatch.state`)."""
    succ, pos, at, task_t = state.succ, state.pos, state.at, state.task_t
    free, free_idx, n_free, moves = state.free, state.free_idx, state.n_free, state.moves
    counters, obs = state.counters, state.obs
    n = grid.shape[0]
    h = n // width
    ob = obs[b]
    ob[:, :] = 0
    for p in range(n):
        r, c = p // width, p % width
        succ[b, p, 0] = p
        for m in range(4):
            nr = r + (-1, 1, 0, 0)[m]
            nc = c + (0, 0, -1, 1)[m]
            if 0 <= nr < h and 0 <= nc < width and not grid[nr * width + nc]:
                succ[b, p, m + 1] = nr * width + nc
            else:
                succ[b, p, m + 1] = p
        at[b, p] = -1
        task_t[b, p] = -1
        free_idx[b, p] = -1
        ob[0, p] = 1 if grid[p] else 0
    counters[b, :] = 0
    for k in range(robots.shape[0]):
        pos[b, k] = robots[k]
        at[b, robots[k]] = k
        moves[b, k] = 0
        ob[2 + k, robots[k]] = 1
    m = 0
    for i in range(pool.shape[0]):
        free[b, m] = pool[i]
        free_idx[b, pool[i]] = m
        m += 1
    n_free[b] = m
    for j in range(tasks.shape[0]):
        _open_task(b, tasks[j], 0, task_t, free, free_idx, n_free, ob)
        counters[b, _ARRIVED] += 1
    counters[b, _OPEN] = tasks.shape[0]


@numba.njit(cache=True, nogil=True)
def _take(b, cell, mark, free, free_idx, n_free) -> None:
    """Take a free pool cell out of the free pool (swap with the last free entry), marking why."""
    i = free_idx[b, cell]
    if i >= 0:
        last = free[b, n_free[b] - 1]
        free[b, i] = last
        free_idx[b, last] = i
        free[b, n_free[b] - 1] = cell
        free_idx[b, cell] = mark
        n_free[b] -= 1


@numba.njit(cache=True, nogil=True)
def _open_task(b, cell, t, task_t, free, free_idx, n_free, ob) -> None:
    task_t[b, cell] = t
    ob[1, cell] = 1
    _take(b, cell, _HAS_TASK, free, free_idx, n_free)


@numba.njit(cache=True, nogil=True)
def _release(b, cell, mark, free, free_idx, n_free) -> None:
    """Put a pool cell taken out with ``mark`` back into the free pool."""
    if free_idx[b, cell] == mark:
        free[b, n_free[b]] = cell
        free_idx[b, cell] = n_free[b]
        n_free[b] += 1


@numba.njit(cache=True, nogil=True)
def _refuse(k, pos, tgt, claim, stack) -> int:
    """Refuse robot ``k``'s move and every move that needed its cell (a cascade); returns the refusals."""
    top = 0
    stack[top] = k
    top += 1
    count = 0
    while top > 0:
        top -= 1
        a = stack[top]
        p = pos[a]
        if tgt[a] == p:
            continue
        if claim[tgt[a]] == a:
            claim[tgt[a]] = -1
        tgt[a] = p
        count += 1
        c = claim[p]
        if c >= 0 and c != a:  # c was moving into the cell a now keeps
            stack[top] = c
            top += 1
        claim[p] = a
    return count


@numba.njit(cache=True, nogil=True)
def resolve_block(pos, tgt, at, claim, stack) -> int:
    """Refuse conflicting moves in place (``tgt`` in, conflict-free ``tgt`` out); returns the refusals.

    Rules, deterministic: a robot that stays keeps its cell; movers claim
    their cell in index order and a later claimant is refused; two robots
    exchanging cells are both refused; a refused robot stays, so any move
    into its cell is refused in turn (cascade).  Rotations of three or more
    robots and following a robot that leaves are allowed.  ``claim`` is a
    scratch array over cells, all -1 on entry and on return; ``at[cell]`` is
    the robot on the cell (-1 none).
    """
    n = pos.shape[0]
    refused = 0
    for k in range(n):
        if tgt[k] == pos[k]:
            claim[pos[k]] = k
    for k in range(n):
        q = tgt[k]
        if q == pos[k]:
            continue
        if claim[q] == -1:
            claim[q] = k
        else:
            refused += _refuse(k, pos, tgt, claim, stack)
    for k in range(n):
        q = tgt[k]
        if q == pos[k]:
            continue
        j = at[q]
        if j >= 0 and j != k and tgt[j] == pos[k]:
            refused += _refuse(k, pos, tgt, claim, stack)
            refused += _refuse(j, pos, tgt, claim, stack)
    for k in range(n):
        claim[tgt[k]] = -1
        claim[pos[k]] = -1
    return refused


@numba.njit(cache=True, nogil=True)
def lifelong_step(actions, live, state, keys, draws, block, poisson, rate, task_reward, claim, rewards) -> None:
    """Apply the joint action (``actions (B, R)`` in 0..4, checked) of every live env; see the module docstring.
    ``state`` as in :func:`lifelong_load`."""
    succ, pos, at, task_t = state.succ, state.pos, state.at, state.task_t
    free, free_idx, n_free, moves = state.free, state.free_idx, state.n_free, state.moves
    counters, obs = state.counters, state.obs
    n_robots = pos.shape[1]
    tgt = np.empty(n_robots, dtype=np.int64)
    stack = np.empty(n_robots + 1, dtype=np.int64)
    served = np.empty(n_robots, dtype=np.int64)
    held = np.empty(n_robots, dtype=np.int64)
    for b in range(actions.shape[0]):
        if not live[b]:
            rewards[b] = 0.0
            continue
        ob = obs[b]
        pb = pos[b]
        attempted = 0
        invalid = 0
        for k in range(n_robots):
            a = actions[b, k]
            q = succ[b, pb[k], a]
            tgt[k] = q
            if a != 0:
                attempted += 1
                if q == pb[k]:
                    invalid += 1
        if block:
            counters[b, _BLOCKED] += resolve_block(pb, tgt, at[b], claim[b], stack)
        made = 0
        for k in range(n_robots):  # leave old cells first, so a follower's new cell is not cleared
            if tgt[k] != pb[k]:
                if at[b, pb[k]] == k:
                    at[b, pb[k]] = -1
                ob[2 + k, pb[k]] = 0
        vertex = 0
        swap = 0
        for k in range(n_robots):
            q = tgt[k]
            if q != pb[k]:
                moves[b, k] += 1
                made += 1
                ob[2 + k, q] = 1
        if not block:
            # vertex pairs after the move, and swaps (pairs that exchanged cells), as the one-shot envs
            for i in range(n_robots):
                for j in range(i + 1, n_robots):
                    if tgt[i] == tgt[j]:
                        vertex += 1
                    if tgt[i] != pb[i] and tgt[j] != pb[j] and tgt[i] == pb[j] and tgt[j] == pb[i]:
                        swap += 1
            counters[b, _VERTEX] += vertex
            counters[b, _SWAP] += swap
        for k in range(n_robots):
            pb[k] = tgt[k]
            at[b, tgt[k]] = k  # under "allow" the last robot on a shared cell is named; only "block" reads it
        counters[b, _STEPS] += 1
        counters[b, _COST] += made
        counters[b, _INVALID] += invalid
        step = counters[b, _STEPS]
        n_served = 0
        for k in range(n_robots):
            c = pb[k]
            t0 = task_t[b, c]
            if t0 >= 0:
                task_t[b, c] = -1
                ob[1, c] = 0
                counters[b, _SERVICE] += step - t0
                served[n_served] = c
                n_served += 1
        counters[b, _DONE] += n_served
        n_held = 0
        for k in range(n_robots):  # no task arrives under a robot
            c = pb[k]
            if free_idx[b, c] >= 0:
                _take(b, c, _HAS_ROBOT, free, free_idx, n_free)
                held[n_held] = c
                n_held += 1
        if poisson:
            n_new = poisson_count(uniform01(keys[b], draws[b]), rate)
            draws[b] += np.uint64(1)
        else:
            n_new = n_served
        for _ in range(n_new):
            if n_free[b] == 0:
                counters[b, _DROPPED] += 1
                continue
            u = uniform01(keys[b], draws[b])
            draws[b] += np.uint64(1)
            i = min(int(u * n_free[b]), n_free[b] - 1)
            _open_task(b, free[b, i], step, task_t, free, free_idx, n_free, ob)
            counters[b, _ARRIVED] += 1
        for i in range(n_served):
            _release(b, served[i], _HAS_TASK, free, free_idx, n_free)
        for i in range(n_held):
            _release(b, held[i], _HAS_ROBOT, free, free_idx, n_free)
        counters[b, _OPEN] = counters[b, _ARRIVED] - counters[b, _DONE]
        rewards[b] = n_served * task_reward - attempted
