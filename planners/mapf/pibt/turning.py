"""PIBT for the League of Robot Runners' action model with turning (MAPF_T), compiled.

A robot is a flat cell ``row * W + col`` and an orientation (0 east, 1 south, 2 west, 3 north); actions are 0 F,
1 R, 2 C, 3 W. :meth:`PIBTStep.decide` (the decider of ``pibt``, ``pibt-flow`` and ``pibt-ising``) returns one
joint action, valid by construction: PIBT picks next cells, a robot moves ahead or turns towards its cell, and a
vacate check keeps a forward move only into a cell that empties.
Design notes: docs/design/lifelong_turning.md#the-decider-pibtstep.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numba
import numpy as np

from planners.mapf.common import TurnRobots, mix, pibt_core, sort_options
from planners.options import Options, option

__all__ = ["PIBTStep", "PIBTOptions", "turning_kernel", "vacate_check", "FORWARD", "CLOCKWISE", "COUNTER", "WAIT"]

FORWARD, CLOCKWISE, COUNTER, WAIT = 0, 1, 2, 3


@numba.njit(cache=True, nogil=True)
def _distance(fields, row, goal, v, cell_of, width) -> int:
    """Moves from compact ``v`` to compact ``goal``: its field, or Manhattan distance without one."""
    if row >= 0:
        return fields[row, v]
    a, b = cell_of[v], cell_of[goal]
    return abs(a // width - b // width) + abs(a % width - b % width)


@numba.njit(cache=True, nogil=True)
def _candidates(grid, robots, heuristic, stamp, a, out, buf) -> int:
    """Robot ``a``'s cells from its compact cell (itself first, then the free neighbours) into ``out``,
    sorted by (distance, turns to face the cell, ``mix(seed, t, a, flat cell)``); records as
    :func:`turning_kernel`, ``buf = (keys, turns, ties)`` scratch."""
    nbr, cell_of, width = grid.nbr, grid.cell_of, grid.width
    pos, orient, goals = robots.pos, robots.orient, robots.goals
    fields, rows = heuristic
    seed, t = stamp
    keys, turns, ties = buf
    p, o, row, goal = pos[a], orient[a], rows[a], goals[a]
    out[0], turns[0] = p, 0
    keys[0] = _distance(fields, row, goal, p, cell_of, width)
    ties[0] = mix(seed, t, a, cell_of[p])
    n = 1
    for d in range(4):
        v = nbr[p, d]
        if v < 0:
            continue
        out[n] = v
        keys[n] = _distance(fields, row, goal, v, cell_of, width)
        turns[n] = 0 if d == o else (2 if d == (o + 2) % 4 else 1)
        ties[n] = mix(seed, t, a, cell_of[v])
        n += 1
    sort_options(n, out, keys, turns, ties)
    return n


@numba.njit(cache=True, nogil=True)
def _pibt(grid, robots, heuristic, order, stamp, nxt, occ):
    """PIBT (:func:`~planners.mapf.common.pibt_core`) over every robot's cells of :func:`_candidates`; a
    robot with ``nxt`` set on entry (a commitment) is neither planned nor pushed."""
    pos = robots.pos
    r = pos.shape[0]
    cand = np.empty((r, 5), dtype=np.int64)
    ncand = np.empty(r, dtype=np.int64)
    buf = (np.empty(5, dtype=np.int64), np.empty(5, dtype=np.int64), np.empty(5, dtype=np.uint64))
    for k in range(r):
        ncand[k] = _candidates(grid, robots, heuristic, stamp, k, cand[k], buf)
    pibt_core(pos, order, (cand, ncand), nxt, occ)


@numba.njit(cache=True, nogil=True)
def vacate_check(pos, nxt, act, occ_now):
    """The vacate check: a forward move (``act`` F towards ``nxt``) is kept only if the cell ahead is empty now
    (``occ_now[cell]`` the robot on it, -1 none) or its robot keeps a forward move itself (chains followed to
    their end; a closed rotation of three or more moves); otherwise it waits, with all queued behind it."""
    r = pos.shape[0]
    state = np.zeros(r, dtype=np.int8)  # 0 open, 1 on the chain being followed, 2 moves, 3 waits
    chain = np.empty(r, dtype=np.int64)
    for k in range(r):
        if act[k] != FORWARD or state[k] != 0:
            continue
        top = 0
        cur = k
        while True:
            state[cur] = 1
            chain[top] = cur
            top += 1
            j = occ_now[nxt[cur]]
            if j == -1:
                ok = True
                break
            if act[j] != FORWARD or state[j] == 3 or nxt[j] == pos[cur]:  # stays, or a swap (never from PIBT)
                ok = False
                break
            if state[j] != 0:  # moves, or closes a rotation (three or more robots)
                ok = True
                break
            cur = j
        for i in range(top):
            state[chain[i]] = 2 if ok else 3
            if not ok:
                act[chain[i]] = WAIT


@numba.njit(cache=True, nogil=True)
def turning_kernel(grid, robots, heuristic, order, stamp, out, occ):
    """One joint action into ``out = (nxt, act)``: ``nxt[k]`` robot ``k``'s PIBT cell, ``act[k]`` its action.
    ``grid`` a :class:`~planners.mapf.common.MoveGrid` (its costs unread); ``robots`` a :class:`TurnRobots`;
    ``heuristic = (fields, rows)``, ``rows[k]``
    the row of ``fields`` robot ``k`` goes by (-1: Manhattan distance to its goal); ``stamp = (seed, t)``;
    ``occ = (occ_now, occ_next)`` scratch over compact cells, all -1 on entry and on return."""
    nbr = grid.nbr
    pos, orient, commit = robots.pos, robots.orient, robots.commit
    nxt, act = out
    occ_now, occ_next = occ
    r = pos.shape[0]
    for k in range(r):
        occ_now[pos[k]] = k
        nxt[k] = -1
    for k in range(r):
        if commit[k] >= 0 and commit[k] != pos[k]:
            nxt[k] = commit[k]
            occ_next[commit[k]] = k
    _pibt(grid, robots, heuristic, order, stamp, nxt, occ)
    for k in range(r):
        p, v, o = pos[k], nxt[k], orient[k]
        act[k] = WAIT
        if v == p or occ_next[v] != k:  # staying, or a commitment a robot that could not move took back
            continue
        for d in range(4):
            if nbr[p, d] == v:
                act[k] = FORWARD if d == o else (COUNTER if d == (o + 3) % 4 else CLOCKWISE)
    vacate_check(pos, nxt, act, occ_now)
    for k in range(r):
        occ_now[pos[k]] = -1
        occ_next[nxt[k]] = -1


@dataclass(frozen=True)
class PIBTOptions(Options):
    """PIBT's own option (the goal fields' and the focus' are their parts')."""

    commits: bool = option(False, bool, meaning="a robot keeps claiming the cell it chose until it stands on it (as "
                           "in the start kit's default planner)")


class PIBTStep:
    """PIBT with turning as a planner's decider (module docstring): one pass of :func:`turning_kernel` over the
    cost-to-go of ``source`` (a :class:`~planners.mapf.guides.fields.FieldSource`) in the order of ``priorities``,
    then ``machine_step.refine(self, pc, orient, gc, rows, order, nxt, act)`` when a machine decides part of the
    step (it may change the claims ``nxt`` and actions ``act`` in place, kept distinct and swap-free)."""

    Options = PIBTOptions
    uses_rest = False  # its ranking reads no task beyond the goal

    def __init__(self, site, source, priorities, opts: PIBTOptions, machine_step=None) -> None:
        self.site, self.source, self.prio = site, source, priorities
        self.commits = opts.commits
        self.machine_step = machine_step
        self.kernel_s = 0.0  # the last pass's seconds (the host rule's own, which an audit compares)
        self.commit = np.zeros(0, dtype=np.int64)  # per robot: the compact cell it keeps claiming, -1 none
        self.targets = np.zeros(0, dtype=np.int64)  # the last call's PIBT cells (flat)
        n = len(site.cell_of)
        self.occ_now = np.full(n, -1, dtype=np.int64)
        self.occ_next = np.full(n, -1, dtype=np.int64)

    def decide(self, pos, orient, goals, deadline: float | None = None, rest=None) -> np.ndarray:
        """The joint action of robots at flat ``pos`` facing ``orient`` towards flat ``goals``; the priorities
        advanced as if it is executed."""
        r = len(pos)
        order = self.prio.order(r)
        if len(self.commit) != r:
            self.commit = np.full(r, -1, dtype=np.int64)
        cid = self.site.cid
        pc, gc = cid[pos], cid[goals]
        fields, rows = self.source.heuristic(pc, gc, order, deadline, self.kernel_s)
        nxt = np.empty(r, dtype=np.int64)
        act = np.empty(r, dtype=np.int64)
        commit = self.commit if self.commits else np.full(r, -1, dtype=np.int64)
        t0 = time.perf_counter()
        turning_kernel(self.source.move_grid, TurnRobots(pc, orient, gc, commit), (fields, rows), order,
                       (self.prio.seed, self.prio.t), (nxt, act), (self.occ_now, self.occ_next))
        self.kernel_s = time.perf_counter() - t0
        if self.machine_step is not None:
            self.machine_step.refine(self, pc, orient, gc, rows, order, nxt, act)
        self.targets = self.site.cell_of[nxt]
        moved = np.where(act == FORWARD, nxt, pc)
        if self.commits:  # a robot keeps claiming its cell until it stands on it
            self.commit = np.where(moved == nxt, -1, nxt)
        self.prio.advance(moved, gc)
        return act
