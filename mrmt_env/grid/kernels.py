"""Compiled, batched grid dynamics for the native vector env of ``mrmt_env/MRMT-v0``.

The same rules as :class:`mrmt_env.core.MRMTCore` (moves, blocked moves,
visits, vertex and swap conflicts, reward), on arrays over ``B`` envs with
flat cells ``r * W + c``.  ``tests/test_vector_envs.py`` steps both side by
side.  Counters per env: ``steps, route_cost, visited, invalid, vertex
conflicts, swap conflicts``.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from mrmt_env.distances import bfs_flat

__all__ = ["GridArrays", "grid_load", "grid_step", "grid_masks", "nearest_field"]


class GridArrays(NamedTuple):
    """The vector env's arrays every kernel call takes, read by name (``B`` envs, ``R`` robots, ``N`` targets)."""

    succ: np.ndarray      # (B, H*W, 5): the cell each action leads to
    tgt_at: np.ndarray    # (B, H*W): the target on each cell, -1 none
    pos: np.ndarray       # (B, R): robot cells
    visited: np.ndarray   # (B, N): targets visited
    moves: np.ndarray     # (B, R): moves per robot
    counters: np.ndarray  # (B, ...): episode counters
    obs: np.ndarray       # (B, 2 + R, H*W): the observation planes

_DR = (-1, 1, 0, 0)
_DC = (0, 0, -1, 1)


@numba.njit(cache=True, nogil=True)
def nearest_field(grid, width, targets, visited, field) -> None:
    """``field[p]``: BFS moves from cell ``p`` to the nearest unvisited target (-1 if none)."""
    field[:] = -1
    queue = np.empty(grid.shape[0], dtype=np.int64)
    tail = 0
    for j in range(targets.shape[0]):
        if not visited[j]:
            field[targets[j]] = 0
            queue[tail] = targets[j]
            tail += 1
    bfs_flat(grid, width, field, queue, tail)


@numba.njit(cache=True, nogil=True)
def grid_load(b, grid, width, robots, targets, state, field, dense) -> None:
    """Start env ``b`` on a world (flat grid, robot and target cells); ``state`` the vector env's
    :class:`GridArrays`."""
    succ, tgt_at, pos, visited = state.succ, state.tgt_at, state.pos, state.visited
    moves, counters, obs = state.moves, state.counters, state.obs
    n = grid.shape[0]
    h = n // width
    for p in range(n):
        r, c = p // width, p % width
        succ[b, p, 0] = p
        for m in range(4):
            nr, nc = r + _DR[m], c + _DC[m]
            if 0 <= nr < h and 0 <= nc < width and not grid[nr * width + nc]:
                succ[b, p, m + 1] = nr * width + nc
            else:
                succ[b, p, m + 1] = p
        tgt_at[b, p] = -1
    ob = obs[b]
    ob[:, :] = 0
    for p in range(n):
        ob[0, p] = 1 if grid[p] else 0
    counters[b, :] = 0
    for j in range(targets.shape[0]):
        tgt_at[b, targets[j]] = j
        visited[b, j] = False
    for k in range(robots.shape[0]):
        pos[b, k] = robots[k]
        moves[b, k] = 0
        ob[2 + k, robots[k]] = 1
        t = tgt_at[b, robots[k]]
        if t >= 0 and not visited[b, t]:
            visited[b, t] = True
            counters[b, 2] += 1
    for j in range(targets.shape[0]):
        if not visited[b, j]:
            ob[1, targets[j]] = 1
    if dense:
        nearest_field(grid, width, targets, visited[b], field[b])


@numba.njit(cache=True, nogil=True)
def _potential(field_b, pos_b) -> float:
    s = 0.0
    for k in range(pos_b.shape[0]):
        d = field_b[pos_b[k]]
        if d > 0:
            s += d
    return -s


@numba.njit(cache=True, nogil=True)
def grid_step(actions, live, state, target_reward, grids, width, targets, field, dense, rewards, terminated) -> None:
    """Apply the joint action of every live env (``actions (B, R)`` in 0..4, already checked); ``state``
    as in :func:`grid_load`."""
    succ, tgt_at, pos, visited = state.succ, state.tgt_at, state.pos, state.visited
    moves, counters, obs = state.moves, state.counters, state.obs
    n_robots = pos.shape[1]
    n_targets = visited.shape[1]
    frm = np.empty(n_robots, dtype=np.int64)
    to = np.empty(n_robots, dtype=np.int64)
    for b in range(actions.shape[0]):
        if not live[b]:
            rewards[b] = 0.0
            terminated[b] = False
            continue
        phi = _potential(field[b], pos[b]) if dense > 0 else 0.0
        attempted = 0
        made = 0
        new = 0
        ob = obs[b]
        for k in range(n_robots):
            a = actions[b, k]
            frm[k] = -1
            if a == 0:
                continue
            attempted += 1
            p = pos[b, k]
            q = succ[b, p, a]
            if q == p:
                continue
            pos[b, k] = q
            made += 1
            moves[b, k] += 1
            ob[2 + k, p] = 0
            ob[2 + k, q] = 1
            frm[k] = p
            to[k] = q
            t = tgt_at[b, q]
            if t >= 0 and not visited[b, t]:
                visited[b, t] = True
                new += 1
                ob[1, q] = 0
        counters[b, 0] += 1
        counters[b, 1] += made
        counters[b, 3] += attempted - made
        counters[b, 2] += new
        for i in range(n_robots):
            for j in range(i + 1, n_robots):
                if pos[b, i] == pos[b, j]:
                    counters[b, 4] += 1
                if frm[i] >= 0 and frm[j] >= 0 and frm[i] == to[j] and to[i] == frm[j]:
                    counters[b, 5] += 1
        reward = new * target_reward - attempted
        if dense > 0:
            if new:
                nearest_field(grids[b], width, targets[b], visited[b], field[b])
            reward += dense * (_potential(field[b], pos[b]) - phi)
        rewards[b] = reward
        terminated[b] = counters[b, 2] == n_targets


@numba.njit(cache=True, nogil=True)
def grid_masks(succ, pos, out) -> None:
    """``out (B, 5 * R)``: per robot, stay and every move that is not blocked."""
    n_robots = pos.shape[1]
    for b in range(pos.shape[0]):
        for k in range(n_robots):
            p = pos[b, k]
            out[b, 5 * k] = True
            for a in range(1, 5):
                out[b, 5 * k + a] = succ[b, p, a] != p
