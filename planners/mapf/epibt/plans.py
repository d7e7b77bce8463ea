"""EPIBT: PIBT over multi-action operations for the action model with turning (MAPF_T), compiled.

Each robot chooses an *operation* of ``op_len`` actions, of which only the first runs (the 2024 League winner's
core; arXiv 2511.09193): inherited operations are reserved first, then robots in priority order choose (one push
each), then a large-neighbourhood search (:mod:`planners.mapf.epibt.search`); a portfolio of ``K`` plans runs on
threads. Design notes: docs/design/lifelong_turning.md#epibts-operations-and-portfolio.
"""

from __future__ import annotations

import itertools
import os
import time
from concurrent.futures import ThreadPoolExecutor

from typing import NamedTuple

import numba
import numpy as np

from planners.mapf.common import mix
from planners.mapf.epibt.search import Fleet, PlanState, SearchStamp, conflict, lns_search, new_state, reserve
from planners.mapf.epibt.options import (AUTO_OP_LEN_FILL, DEFAULT_GROUP, DEFAULT_LNS_MAX, DEFAULT_LNS_PER_ROBOT,
                                        DEFAULT_OP_LEN, DEFAULT_REVISITS, DEFAULT_WEIGHT_POWER, MAX_OP_LEN,
                                        MAX_PORTFOLIO, EPIBTOptions)
from planners.mapf.pibt.turning import CLOCKWISE, COUNTER, FORWARD, WAIT, _distance

__all__ = ["EPIBTStep", "EPIBTOptions", "portfolio_threads", "run_waves", "operations", "epibt_kernel", "epibt_finish", "new_state", "PlanState", "Fleet",
           "SearchStamp",
           "plan_cost", "portfolio_seed",
           "DEFAULT_OP_LEN", "AUTO_OP_LEN_FILL", "DEFAULT_REVISITS", "DEFAULT_GROUP", "DEFAULT_LNS_PER_ROBOT",
           "DEFAULT_LNS_MAX", "DEFAULT_WEIGHT_POWER", "MAX_PORTFOLIO"]

#: Under a clock, a call ending closer than this to its deadline shrinks the next calls' search.
DEADLINE_MARGIN_S = 0.05
_PORTFOLIO_SALT = 0x70F7  # the portfolio's seeds: mix(seed, k, salt, 0), k >= 1
_SHIFT = 24  # key = cost-to-go << _SHIFT | idle << 16 | 16 bits of tie


class RobotAt(NamedTuple):
    """One robot's place in a joint plan (:func:`_options`)."""

    k: int  # the robot
    cell: int
    orient: int
    goal: int
    row: int  # its goal's distance row (-1: none)


class ChoiceTables(NamedTuple):
    """What :func:`_choose` works in beside the plan."""

    res: np.ndarray    # (op_len + 1, cells) the reservation table
    visit: np.ndarray  # (R,) how often each robot has chosen this call
    hit: np.ndarray    # (R,) int8 scratch marks
    stack: "ChoiceStack"


class ChoiceStack(NamedTuple):
    """:func:`_choose`'s explicit stack of pushes, one level per robot on it."""

    robot: np.ndarray  # the robot choosing at this level
    option: np.ndarray  # its next option to try
    pushed: np.ndarray  # the robot its current try pushed (-1: none)
    pushed_src: np.ndarray  # that robot's option before the push
    pushed_cells: np.ndarray  # and its cells


def operations(op_len: int = DEFAULT_OP_LEN) -> np.ndarray:
    """``(n, op_len)`` int8: every action sequence without R next to C and without three equal turns in
    a row, F-first order."""
    if isinstance(op_len, bool) or not isinstance(op_len, (int, np.integer)) or not 1 <= op_len <= MAX_OP_LEN:
        raise ValueError(f"op_len must be an integer 1..{MAX_OP_LEN} (actions per operation) or 'auto' (EPIBT), "
                         f"got {op_len!r}")
    keep = []
    for op in itertools.product((FORWARD, CLOCKWISE, COUNTER, WAIT), repeat=int(op_len)):
        pairs = zip(op, op[1:])
        if any({a, b} == {CLOCKWISE, COUNTER} for a, b in pairs):
            continue
        if any(op[i] == op[i + 1] == op[i + 2] != FORWARD and op[i] != WAIT for i in range(len(op) - 2)):
            continue
        keep.append(op)
    return np.array(keep, dtype=np.int8)


def op_idle(ops: np.ndarray, steady: bool = False) -> np.ndarray:
    """Each operation's rank among those of equal cost-to-go (lower first): 2 x (actions left) for every action
    that is not a forward move, so early moves come first, + 1 for a wait (a turn, under ``steady``)."""
    length = ops.shape[1]
    late = 2 * (length - np.arange(length))
    tie = (ops == CLOCKWISE) | (ops == COUNTER) if steady else ops == WAIT
    return ((ops != FORWARD) * late + tie).sum(axis=1).astype(np.int64)


@numba.njit(cache=True, nogil=True)
def _walk(nbr, p, o, op, cells) -> int:
    """Cells of ``op`` from compact ``p`` facing ``o`` into ``cells`` (start first); the final
    orientation, or -1 when a forward move leaves the free cells."""
    cells[0] = p
    for t in range(op.shape[0]):
        a = op[t]
        if a == FORWARD:
            p = nbr[p, o]
            if p < 0:
                return -1
        elif a == CLOCKWISE:
            o = (o + 1) & 3
        elif a == COUNTER:
            o = (o + 3) & 3
        cells[t + 1] = p
    return o


@numba.njit(cache=True, nogil=True)
def _to_go(grid, heuristic, goal, row, c, o) -> int:
    """Cost-to-go from compact ``c`` facing ``o``: 0 on the goal, else the least ``cost[c, d] + field of the
    neighbour in d + turns to face d``."""
    nbr, cell_of, width, cost = grid.nbr, grid.cell_of, grid.width, grid.cost
    fields, far = heuristic
    if c == goal:
        return 0
    best = -1
    for d in range(4):
        v = nbr[c, d]
        if v < 0:
            continue
        h = _distance(fields, row, goal, v, cell_of, width)
        if row >= 0 and h >= far:
            continue
        turns = 0 if d == o else (2 if d == ((o + 2) & 3) else 1)
        val = cost[c, d] + h + turns
        if best < 0 or val < best:
            best = val
    if best < 0:
        return _distance(fields, row, goal, c, cell_of, width)
    return best


@numba.njit(cache=True, nogil=True)
def _options(grid, heuristic, robot, ops, idle, stamp, cand, scratch) -> int:
    """The operations of robot ``robot`` (a :class:`RobotAt`), ranked and without equal cell sequences, into
    ``cand = (cells, which, costs)`` (``cells[i]`` its cells, ``which[i]`` the operation, ``costs[i]`` its
    cost-to-go); returns how many."""
    nbr = grid.nbr
    k, p, o, goal, row = robot.k, robot.cell, robot.orient, robot.goal, robot.row
    seed, t = stamp
    cells, which, costs = cand
    tmp, keys = scratch
    n_ops = ops.shape[0]
    n = 0
    for i in range(n_ops):
        end = _walk(nbr, p, o, ops[i], tmp[i])
        if end < 0:
            keys[i] = -1
            continue
        h = _to_go(grid, heuristic, goal, row, tmp[i, ops.shape[1]], end)
        keys[i] = (np.int64(h) << _SHIFT) | (np.int64(idle[i]) << 16) | np.int64(mix(seed, t, k, i) & np.uint64(0xFFFF))
        n += 1
    idx = np.argsort(keys, kind="mergesort")  # stable: equal keys by operation
    m = 0
    for j in range(n_ops - n, n_ops):
        i = idx[j]
        dup = False
        for q in range(m):
            same = True
            for s in range(1, ops.shape[1] + 1):
                if cells[q, s] != tmp[i, s]:
                    same = False
                    break
            if same:
                dup = True
                break
        if not dup:
            cells[m] = tmp[i]
            which[m] = i
            costs[m] = keys[i] >> _SHIFT
            m += 1
    return m


@numba.njit(cache=True, nogil=True)
def _choose(root, prio, state, tables, revisits) -> bool:
    """Robot ``root``'s choice with pushes, on an explicit stack (module docstring), in ``state`` (a
    :class:`PlanState`); ``tables`` a :class:`ChoiceTables`.  On failure
    ``root`` holds its inherited cells, unreserved."""
    cells, ncand, cur, src, inh = state.cells, state.ncand, state.cur, state.src, state.inh
    res, visit, hit, stack = tables.res, tables.visit, tables.hit, tables.stack
    st_a, st_i, st_l = stack.robot, stack.option, stack.pushed
    st_src, saved = stack.pushed_src, stack.pushed_cells
    p = prio[root]
    top = 0
    st_a[0], st_i[0], st_l[0] = root, 0, -1
    visit[root] += 1
    hit[root] = 1
    result = False
    returned = False
    while top >= 0:
        a = st_a[top]
        if returned:
            returned = False
            if result:
                hit[a] = 0
                top -= 1
                returned = True
                continue
            lo = st_l[top]  # the pushed robot found nothing: take back a's try, give lo its cells back
            reserve(res, cur[a], a, -1)
            cur[lo] = saved[top]
            src[lo] = st_src[top]
            reserve(res, cur[lo], lo, lo)
            st_l[top] = -1
        state = 0  # 0 nothing left, 1 chosen, 2 pushed
        while st_i[top] < ncand[a]:
            c = st_i[top]
            st_i[top] += 1
            path = cells[a, c]
            lo = conflict(res, path, a)
            if lo == -2:
                continue
            if lo >= 0 and (hit[lo] == 1 or visit[lo] >= revisits or prio[lo] >= p):
                continue
            if lo >= 0:
                saved[top] = cur[lo]
                st_src[top] = src[lo]
                reserve(res, cur[lo], lo, -1)
            cur[a] = path
            src[a] = c
            reserve(res, path, a, a)
            if lo < 0:
                state = 1
                break
            st_l[top] = lo
            top += 1
            st_a[top], st_i[top], st_l[top] = lo, 0, -1
            visit[lo] += 1
            hit[lo] = 1
            state = 2
            break
        if state == 2:
            continue
        if state == 0:
            cur[a] = inh[a]
            src[a] = -1
        hit[a] = 0
        top -= 1
        result = state == 1
        returned = True
    return result


@numba.njit(cache=True, nogil=True)
def epibt_kernel(grid, robots, heuristic, order, stamp, ops, idle, state, res):
    """One joint plan of ``robots`` (a :class:`Fleet`) into ``state`` (a :class:`PlanState`), left reserved in
    ``res`` (``(op_len + 1, cells)``, all -1 on entry; :func:`epibt_finish` clears it).  ``grid`` a
    :class:`~planners.mapf.common.MoveGrid`; ``heuristic = (fields, far)``; ``stamp`` a :class:`SearchStamp`;
    ``idle`` each operation's tie rank among those of equal cost-to-go (:func:`op_idle`)."""
    nbr = grid.nbr
    pos, orient, goals, rows = robots.pos, robots.orient, robots.goals, robots.rows
    inherited, weight = robots.inherited, robots.weight
    seed, t = stamp.seed, stamp.t
    cells, which, costs, ncand = state.cells, state.which, state.costs, state.ncand
    cur, src, inh, inh_cost = state.cur, state.src, state.inh, state.inh_cost
    r = pos.shape[0]
    n_ops, length = ops.shape
    scratch = (np.empty((n_ops, length + 1), dtype=np.int64), np.empty(n_ops, dtype=np.int64))
    for k in range(r):
        ncand[k] = _options(grid, heuristic, RobotAt(k, pos[k], orient[k], goals[k], rows[k]), ops, idle, (seed, t),
                            (cells[k], which[k], costs[k]), scratch)
        end = _walk(nbr, pos[k], orient[k], inherited[k], inh[k])
        if end < 0:  # never after a valid plan: stay
            inh[k] = pos[k]
            end = orient[k]
        inh_cost[k] = _to_go(grid, heuristic, goals[k], rows[k], inh[k, length], end) * weight[k]
        for c in range(ncand[k]):
            costs[k, c] *= weight[k]
        cur[k] = inh[k]
        src[k] = -1
        reserve(res, inh[k], k, k)
    visit = np.zeros(r, dtype=np.int64)
    hit = np.zeros(r, dtype=np.int8)
    stack = ChoiceStack(np.empty(r, dtype=np.int64), np.empty(r, dtype=np.int64), np.empty(r, dtype=np.int64),
                        np.empty(r, dtype=np.int64), np.empty((r, length + 1), dtype=np.int64))
    tables = ChoiceTables(res, visit, hit, stack)
    for idx in range(r):
        k = order[idx]
        if visit[k] != 0:
            continue
        reserve(res, cur[k], k, -1)
        if not _choose(k, robots.prio, state, tables, stamp.revisits):
            reserve(res, cur[k], k, k)
    if stamp.lns > 0:
        lns_search(state, res, stamp)


@numba.njit(cache=True, nogil=True)
def epibt_finish(ops, inherited, state, out, res) -> None:
    """``out = (chosen, act)``: robot ``k``'s operation (actions) and its first action; ``res`` cleared."""
    which, cur, src = state.which, state.cur, state.src
    chosen, act = out
    for k in range(cur.shape[0]):
        if src[k] >= 0:
            chosen[k] = ops[which[k, src[k]]]
        else:
            chosen[k] = inherited[k]
        act[k] = chosen[k, 0]
        reserve(res, cur[k], k, -1)


def plan_cost(state) -> int:
    """A joint plan's (:class:`PlanState`) weighted cost-to-go: each robot's chosen operation's, or its inherited
    one's."""
    costs, src, inh_cost = state.costs, state.src, state.inh_cost
    r = src.shape[0]
    return int(np.where(src >= 0, costs[np.arange(r), np.maximum(src, 0)], inh_cost).sum())


def portfolio_seed(seed: int, k: int) -> int:
    """Plan ``k``'s seed in a portfolio: the call's own seed for ``k = 0``, else a splitmix of it (62 bits)."""
    return int(seed) if k == 0 else int(mix(np.uint64(seed), k, _PORTFOLIO_SALT, 0)) & ((1 << 62) - 1)


def portfolio_threads(portfolio: int, threads: int | None) -> int:
    """Threads a portfolio of ``portfolio`` plans runs on: ``threads``, or (``None``) one per plan, at most the cores
    this process may use."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return min(portfolio, cores) if threads is None else threads


def run_waves(run, k_plans: int, threads: int, deadline: float | None) -> int:
    """Runs plans ``0..k-1`` (``run(k)``) in waves of ``threads`` (side by side: the kernels release the GIL), all of
    them without a ``deadline``, else while the next wave should end before it (the first always runs); returns
    ``k``."""
    width = min(threads, k_plans)
    done = 0
    pool = ThreadPoolExecutor(width) if width > 1 else None
    try:
        while done < k_plans:
            t0 = time.perf_counter()
            wave = range(done, min(done + width, k_plans))
            list(pool.map(run, wave)) if pool is not None else [run(k) for k in wave]
            done = wave.stop
            now = time.perf_counter()
            if deadline is not None and now + (now - t0) > deadline - DEADLINE_MARGIN_S:
                break
    finally:
        if pool is not None:
            pool.shutdown()
    return done


class EPIBTStep:
    """EPIBT as a planner's decider (module docstring) over the cost-to-go of ``source`` (a
    :class:`~planners.mapf.guides.fields.FieldSource`) in the order of ``priorities``; ``machine_step.improve(self,
    state, deadline)``, when a machine decides part of the step, may change the kept plan ``state`` (conflict-free in
    :attr:`res`) before its first actions are taken; its :attr:`last_compute` is the step's machine charge."""

    Options = EPIBTOptions
    uses_rest = False

    def __init__(self, site, source, priorities, opts: EPIBTOptions, machine_step=None) -> None:
        self.site, self.source, self.prio = site, source, priorities
        self.machine_step = machine_step
        self.options = opts
        self.revisits, self.lns_option, self.group = opts.revisits, opts.lns, opts.group
        self.weight_power, self.anneal = opts.weight_power, opts.anneal
        self.portfolio = opts.portfolio
        self.threads = portfolio_threads(opts.portfolio, opts.threads)
        self.kernel_s = 0.0
        self.lns = 0
        self.portfolio_costs = np.zeros(0, dtype=np.int64)  # the last call's plans' weighted costs
        self.kept = 0  # and the one kept
        self.lns_scale = 1.0  # under a clock: the share of the search's iterations the steps leave time for
        self.auto_op_len = opts.op_len == "auto"
        self.targets = np.zeros(0, dtype=np.int64)
        self._set_ops(DEFAULT_OP_LEN if self.auto_op_len else opts.op_len)
        self._expect = (np.zeros(0, np.int64), np.zeros(0, np.int64))  # where the plans put the robots

    def _set_ops(self, op_len) -> None:
        self.ops = operations(op_len)
        self.idle = op_idle(self.ops, self.options.steady)
        self.inherited = np.zeros((0, self.ops.shape[1]), dtype=np.int8)
        self.res = np.full((self.ops.shape[1] + 1, len(self.site.cell_of)), -1, dtype=np.int64)
        self.plans = np.zeros((0, self.ops.shape[1]), dtype=np.int8)  # the last call's operations

    def decide(self, pos, orient, goals, deadline: float | None = None, rest=None) -> np.ndarray:
        """The joint action (as :meth:`PIBTStep.decide <planners.mapf.pibt.turning.PIBTStep.decide>`); a robot not
        where the last call's plans put it (another planner acted, a new episode) drops every inherited operation.
        Under a ``deadline`` the portfolio's plans run in waves of :attr:`threads` while the next wave, as long as
        the last, ends before it (the first wave always runs), and the search's iterations are scaled by
        :attr:`lns_scale`, which falls by 0.7 after a call that ends within :data:`DEADLINE_MARGIN_S` of its
        deadline and grows by 1.1 (up to 1) after one that leaves a quarter of its time."""
        r = len(pos)
        site, prio = self.site, self.prio
        if self.auto_op_len:
            self.auto_op_len = False
            self._set_ops(4 if r <= AUTO_OP_LEN_FILL * len(site.cell_of) else DEFAULT_OP_LEN)
        order = prio.order(r)
        pc, gc = site.cid[pos], site.cid[goals]
        if len(self.inherited) != r or not (np.array_equal(self._expect[0], pc)
                                            and np.array_equal(self._expect[1], orient)):
            self.inherited = np.full((r, self.ops.shape[1]), WAIT, dtype=np.int8)
        fields, rows = self.source.heuristic(pc, gc, order, deadline, self.kernel_s)
        far = int(np.iinfo(fields.dtype).max)
        weight = np.empty(r, dtype=np.int64)  # (r + 1 - rank) ** weight_power, rank 0 the first in order
        weight[order] = np.arange(r + 1, 1, -1, dtype=np.int64) ** self.weight_power
        self.lns = min(r * DEFAULT_LNS_PER_ROBOT, DEFAULT_LNS_MAX) if self.lns_option is None else self.lns_option
        if deadline is not None:
            self.lns = int(self.lns * self.lns_scale)
            started = time.perf_counter()
        chosen = np.empty((r, self.ops.shape[1]), dtype=np.int8)
        act = np.empty(r, dtype=np.int64)
        t0 = time.perf_counter()
        robots = Fleet(pc, orient, gc, rows, prio.elapsed + prio.tie, self.inherited, weight)
        state = self._plans(self.source.move_grid, robots, (fields, far), order, deadline)
        self.kernel_s = time.perf_counter() - t0
        if self.machine_step is not None:
            self.machine_step.improve(self, state, deadline)
        epibt_finish(self.ops, self.inherited, state, (chosen, act), self.res)
        self.plans = chosen
        ahead = site.nbr[pc, orient].astype(np.int64)
        nxt = np.where(act == FORWARD, ahead, pc)
        turn = np.where(act == CLOCKWISE, 1, np.where(act == COUNTER, 3, 0))
        self.inherited = np.concatenate([chosen[:, 1:], np.full((r, 1), WAIT, dtype=np.int8)], axis=1)
        self._expect = (nxt, (orient + turn) % 4)
        self.targets = site.cell_of[nxt]
        prio.advance(nxt, gc)
        if deadline is not None:  # the search's share of the next steps: less when this one ended late
            c = self.machine_step.last_compute if self.machine_step is not None else None
            charged = 0.0 if c is None else c.chip_time_parallel_s - c.emulation_s  # a machine's, if any
            slack = deadline - time.perf_counter() - charged
            if slack < DEADLINE_MARGIN_S:
                self.lns_scale *= 0.7
            elif slack > 0.25 * (deadline - started):
                self.lns_scale = min(1.0, self.lns_scale * 1.1)
        return act

    def _plans(self, grid, robots, heuristic, order, deadline):
        """The portfolio's joint plans (one by default), the kept one's state returned and left reserved in
        :attr:`res`; :attr:`portfolio_costs` holds each plan's weighted cost-to-go."""
        r, k_plans = robots.pos.shape[0], self.portfolio
        states = [new_state(r, self.ops) for _ in range(k_plans)]
        tables = [self.res] + [np.full_like(self.res, -1) for _ in range(k_plans - 1)]
        seed, t = self.prio.seed, self.prio.t

        def run(k):
            stamp = SearchStamp(portfolio_seed(seed, k), t, self.revisits, self.lns, self.group, self.anneal)
            epibt_kernel(grid, robots, heuristic, order, stamp, self.ops, self.idle, states[k], tables[k])

        k_plans = run_waves(run, k_plans, self.threads, deadline)
        states = states[:k_plans]
        self.portfolio_costs = np.array([plan_cost(st) for st in states], dtype=np.int64)
        self.kept = int(np.argmin(self.portfolio_costs))  # the first of least cost
        self.res = tables[self.kept]  # the others are dropped with their reservations
        return states[self.kept]
