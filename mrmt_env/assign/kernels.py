"""Compiled dynamics of the plan-level (Assign) env, batched over envs.

One copy of the dynamics: the single env runs these kernels on a batch of one, the native vector env on a batch of
``B``. Action ``a < N`` sends the deciding robot to target ``a``; action ``N`` retires it.
Design notes (the state arrays): docs/design/envs.md#plan-level-dynamics.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from mrmt_env.fast_generation import node_distances

__all__ = ["AssignArrays", "assign_load", "assign_step", "assign_masks", "assign_observe", "next_decider", "N_ROBOT_FEATURES"]

#: Feature columns before the per-target distance block (see the env docstring).
N_ROBOT_FEATURES = 8


class AssignArrays(NamedTuple):
    """The batch's arrays :func:`assign_load` fills (the module docstring), read by name."""

    dist: np.ndarray
    coords: np.ndarray
    cell: np.ndarray
    free_at: np.ndarray
    active: np.ndarray
    open_: np.ndarray
    counters: np.ndarray
    decider: np.ndarray


@numba.njit(cache=True, nogil=True)
def next_decider(cell, free_at, active, open_, dist, n_targets) -> int:
    """The active robot with the least committed time (lowest index on ties);
    -1 when no target is open or no robot is active."""
    any_open = False
    for j in range(n_targets):
        if open_[j]:
            any_open = True
            break
    if not any_open:
        return -1
    best = -1
    for k in range(cell.shape[0]):
        if active[k] and (best < 0 or free_at[k] < free_at[best]):
            best = k
    return best


@numba.njit(cache=True, nogil=True)
def assign_load(b, flat_grid, width, height, nodes, n_robots, state) -> None:
    """Start env ``b`` on a world given as a flat grid and node cells (robots, then targets);
    ``state`` the batch's :class:`AssignArrays`."""
    dist, coords, cell, free_at = state.dist, state.coords, state.cell, state.free_at
    active, open_, counters, decider = state.active, state.open_, state.counters, state.decider
    node_distances(flat_grid, width, nodes, dist[b])
    n_targets = open_.shape[1]
    for a in range(nodes.shape[0]):
        coords[b, a, 0] = (nodes[a] // width) / max(height - 1, 1)
        coords[b, a, 1] = (nodes[a] % width) / max(width - 1, 1)
    for k in range(n_robots):
        cell[b, k] = k
        free_at[b, k] = 0
        active[b, k] = True
    counters[b, :] = 0
    for j in range(n_targets):
        under = False
        for k in range(n_robots):
            if dist[b, k, n_robots + j] == 0:
                under = True
        open_[b, j] = not under
        if under:
            counters[b, 2] += 1
    decider[b] = next_decider(cell[b], free_at[b], active[b], open_[b], dist[b], n_targets)


@numba.njit(cache=True, nogil=True)
def _stop_allowed(b, k, cell, active, open_, dist, n_robots, n_targets) -> bool:
    # retiring robot k is legal when every open target stays reachable by another active robot
    for j in range(n_targets):
        if not open_[b, j]:
            continue
        ok = False
        for q in range(n_robots):
            if q != k and active[b, q] and dist[b, cell[b, q], n_robots + j] >= 0:
                ok = True
                break
        if not ok:
            return False
    return True


@numba.njit(cache=True, nogil=True)
def assign_masks(cell, active, open_, dist, decider, out) -> None:
    """Fill ``out (B, N + 1)`` bool with the legal actions of each env's decider.

    Target ``j``: open and reachable from the decider.  Stop (index ``N``):
    every open target stays reachable by another active robot.  An env whose
    episode is over (``decider < 0``) allows only stop.
    """
    n_robots = cell.shape[1]
    n_targets = open_.shape[1]
    for b in range(out.shape[0]):
        k = decider[b]
        if k < 0:
            out[b, :] = False
            out[b, n_targets] = True
            continue
        src = cell[b, k]
        for j in range(n_targets):
            out[b, j] = open_[b, j] and dist[b, src, n_robots + j] >= 0
        out[b, n_targets] = _stop_allowed(b, k, cell, active, open_, dist, n_robots, n_targets)


@numba.njit(cache=True, nogil=True)
def assign_step(actions, cell, free_at, active, open_, dist, decider, counters, rewards, terminated) -> None:
    """Apply one action per env (values already checked to lie in ``0..N``).

    ``counters[b]`` = (route_cost, steps, targets_visited, invalid_actions).
    The reward is minus the moves the action commits (0 for stop).  An
    action the mask forbids changes nothing, costs -1 and counts as invalid
    (as a blocked move does in the grid env).  ``terminated[b]`` is set when
    no target is left open.
    """
    n_robots = cell.shape[1]
    n_targets = open_.shape[1]
    for b in range(actions.shape[0]):
        a = actions[b]
        k = decider[b]
        counters[b, 1] += 1
        if k < 0:  # nothing left to take: stop is the one legal action (its mask), a no-op
            if a == n_targets:
                rewards[b] = 0.0
            else:
                counters[b, 3] += 1
                rewards[b] = -1.0
            terminated[b] = True
            continue
        legal = True
        if a < n_targets:
            d = dist[b, cell[b, k], n_robots + a]
            legal = open_[b, a] and d >= 0
        else:
            legal = _stop_allowed(b, k, cell, active, open_, dist, n_robots, n_targets)
        if not legal:
            counters[b, 3] += 1
            rewards[b] = -1.0
        elif a < n_targets:
            d = dist[b, cell[b, k], n_robots + a]
            cell[b, k] = n_robots + a
            free_at[b, k] += d
            open_[b, a] = False
            counters[b, 0] += d
            counters[b, 2] += 1
            rewards[b] = -float(d)
        else:
            active[b, k] = False
            rewards[b] = 0.0
        decider[b] = next_decider(cell[b], free_at[b], active[b], open_[b], dist[b], n_targets)
        terminated[b] = decider[b] < 0


@numba.njit(cache=True, nogil=True)
def assign_observe(cell, free_at, active, open_, dist, decider, coords, scale, far, out) -> None:
    """Write each env's observation into ``out (B, N + R, 8 + N)`` float32.

    ``coords[b]``: ``(R+N, 2)`` node cells already divided by ``(H-1, W-1)``;
    distances are divided by ``scale`` (= H + W); an unreachable distance
    reads ``far``.  Layout: see :class:`mrmt_env.assign.env.MRMTAssignEnv`.
    """
    n_robots = cell.shape[1]
    n_targets = open_.shape[1]
    f0 = N_ROBOT_FEATURES
    for b in range(out.shape[0]):
        o = out[b]
        o[:, :] = 0.0
        k = decider[b]
        now = free_at[b, k] if k >= 0 else 0
        n_open = 0
        for j in range(n_targets):
            if open_[b, j]:
                n_open += 1
        for j in range(n_targets):
            node = n_robots + j
            o[j, 0] = 1.0
            o[j, 1] = 1.0 if open_[b, j] else 0.0
            o[j, 2] = coords[b, node, 0]
            o[j, 3] = coords[b, node, 1]
            if k >= 0:
                d = dist[b, cell[b, k], node]
                o[j, 4] = far if d < 0 else d / scale
            else:
                o[j, 4] = 0.0
            best = -1.0  # earliest arrival of another active robot
            for q in range(n_robots):
                if q == k or not active[b, q]:
                    continue
                d = dist[b, cell[b, q], node]
                if d >= 0:
                    t = (free_at[b, q] - now + d) / scale
                    if best < 0 or t < best:
                        best = t
            o[j, 5] = far if best < 0 else best
            near = -1.0  # nearest other open target
            for i in range(n_targets):
                d = dist[b, node, n_robots + i]
                o[j, f0 + i] = far if d < 0 else d / scale
                if i != j and open_[b, i] and d >= 0 and (near < 0 or d / scale < near):
                    near = d / scale
            o[j, 6] = 0.0 if near < 0 else near
            o[j, 7] = n_open / n_targets
        for q in range(n_robots):
            r = n_targets + q
            o[r, 0] = 0.0
            o[r, 1] = 1.0 if active[b, q] else 0.0
            node = cell[b, q]
            o[r, 2] = coords[b, node, 0]
            o[r, 3] = coords[b, node, 1]
            o[r, 4] = max(free_at[b, q] - now, 0) / scale
            o[r, 5] = free_at[b, q] / scale
            o[r, 6] = 1.0 if q == k else 0.0
            o[r, 7] = n_open / n_targets
            for i in range(n_targets):
                d = dist[b, node, n_robots + i]
                o[r, f0 + i] = far if d < 0 else d / scale
