"""EPIBT by push chains: the 2024 League winner's construction and annealed search (issue 57), compiled.

Robots choose, in order of least task still to go, their first free operation or one that pushes exactly one robot
(a *push chain*), kept when the plan's score does not fall; a seeded annealed search of chains follows. Operations
are five actions, of which only the first runs.
Design notes (the score, the choices): docs/design/lifelong_turning.md#push-chains-the-kernels.
"""

from __future__ import annotations

import itertools
from typing import NamedTuple

import numba
import numpy as np

from ising_backend import splitmix
from planners.mapf.common import mix
from planners.mapf.epibt.plans import _to_go, _walk
from planners.mapf.epibt.search import conflict, reserve
from planners.mapf.pibt.turning import CLOCKWISE, COUNTER, FORWARD, WAIT

__all__ = ["STEPS", "SEARCH_PUSHES", "chain_operations", "Candidates", "ChainPlan", "ChainRobots", "ChainKnobs",
           "new_plan", "chain_candidates", "chain_build", "chain_search", "chain_finish", "score_of", "stamp_seed"]

STEPS = 5  # actions per operation
_VISIT = 50  # value scale of a cost-to-go step
_MIN_DEPTH = 3  # operations reaching at most this far count as this deep
SEARCH_PUSHES = 1000  # by default a search chain pushing more is refused (the winner's cap)
_DEEP_PUSHES = 3000  # beyond this many, the construction pushes no deeper than 6 robots
_BUILD_PUSHES = 20000  # and a construction chain pushing more is refused


def chain_operations() -> tuple[np.ndarray, np.ndarray]:
    """``(ops, depth)``: the 129 operations (``(129, 5)`` int8, index 0 the five waits) and each one's depth
    (its last action that is not a wait, at least 3)."""
    steps = ((0, 1), (1, 0), (0, -1), (-1, 0))  # (row, col) per orientation: east, south, west, north
    kept: dict = {}
    for op in itertools.product((FORWARD, CLOCKWISE, COUNTER, WAIT), repeat=STEPS):
        if _turns_wasted(op):
            continue
        r = c = o = 0
        seen, cells, again = {(0, 0)}, [], False
        for a in op:
            if a == FORWARD:
                r, c = r + steps[o][0], c + steps[o][1]
                again |= (r, c) in seen
            elif a != WAIT:
                o = (o + (1 if a == CLOCKWISE else 3)) & 3
            seen.add((r, c))
            cells.append((r, c))
        if not again:
            kept.setdefault((tuple(cells), o), op)  # the first of equal moves: turns as early as they go
    ops = [(WAIT,) * STEPS] + [op for op in kept.values() if any(a != WAIT for a in op)]
    arr = np.array(ops, dtype=np.int8)
    last = np.array([max([t + 1 for t in range(STEPS) if op[t] != WAIT], default=0) for op in ops])
    return arr, np.maximum(last, _MIN_DEPTH).astype(np.int64)


def _turns_wasted(op) -> bool:
    """A turn after the last forward move, R and C between two forward moves, or three equal turns there."""
    tail = len(op)
    while tail > 0 and op[tail - 1] != FORWARD:
        tail -= 1
    if any(a in (CLOCKWISE, COUNTER) for a in op[tail:]):
        return True
    run: list = []
    for a in op + (FORWARD,):
        if a != FORWARD:
            run.append(a)
            continue
        if (CLOCKWISE in run and COUNTER in run) or run.count(CLOCKWISE) >= 3 or run.count(COUNTER) >= 3:
            return True
        run = []
    return False


class ChainRobots(NamedTuple):
    """The robots of one call (:func:`chain_candidates`), in compact cells."""

    pos: np.ndarray     # (R,) each robot's cell
    orient: np.ndarray  # (R,) its orientation
    goals: np.ndarray   # (R,) its goal's cell (its own cell: no goal)
    rows: np.ndarray    # (R,) its goal's distance row (-1: Manhattan distance)


class ChainKnobs(NamedTuple):
    """The chains' two chances and the search chain's push cap (:class:`~planners.mapf.epibt.chain_planner.ChainOptions`
    ``push_built``, ``skip``, ``pushes``)."""

    push_built: float  # the construction pushes a robot that has already chosen
    skip: float        # a search chain passes over a robot in its way
    pushes: int = SEARCH_PUSHES  # a search chain pushing more is refused


class Candidates(NamedTuple):
    """Each robot's operations, best first (:func:`chain_candidates`); read-only for the plans."""

    cells: np.ndarray  # (R, M, 6) the cells of each candidate (start first)
    op: np.ndarray     # (R, M) the operation it is
    value: np.ndarray  # (R, M) its value (lower better)
    depth: np.ndarray  # (R, M) its depth (3..5; the planner fills it from the operations')
    n: np.ndarray      # (R,) how many
    still: np.ndarray  # (R, 6) the cells of waiting (the robot's own, six times)
    wait_value: np.ndarray  # (R,) the value of waiting
    idle_act: np.ndarray    # (R,) the first action of a robot left waiting (a turn towards its goal, or W)
    to_go: np.ndarray       # (R,) the cost-to-go now


class ChainPlan(NamedTuple):
    """One joint plan: ``choice[k]`` robot ``k``'s candidate (-1: waiting), the table ``res[t, cell]``."""

    choice: np.ndarray      # (R,)
    res: np.ndarray         # (6, cells)
    score: np.ndarray       # (1,) int64, the plan's score
    rng: np.ndarray         # (1,) uint64, the plan's random stream
    best: np.ndarray        # (R,) the construction's choices
    best_score: np.ndarray  # (1,) and their score
    cap: np.ndarray         # (1,) the deepest operations the chains try now
    temp: np.ndarray        # (1,) float64, the search's temperature now
    work: np.ndarray        # (1,) int64, the search's work so far: its chains and their pushes


def new_plan(r: int, n_cells: int, seed: int, temp: float) -> ChainPlan:
    """An empty :class:`ChainPlan` for ``r`` robots on ``n_cells`` cells, its search starting at ``temp``."""
    return ChainPlan(np.full(r, -1, np.int64), np.full((STEPS + 1, n_cells), -1, np.int64), np.zeros(1, np.int64),
                     np.array([seed], dtype=np.uint64), np.full(r, -1, np.int64), np.zeros(1, np.int64),
                     np.full(1, STEPS, np.int64), np.array([temp]), np.zeros(1, np.int64))


@numba.njit(cache=True, nogil=True)
def _cost_to_go(grid, heuristic, goal, row, c, o) -> int | np.int64:
    """Cost-to-go from compact ``c`` facing ``o``: read from a field over (cell, orientation) when ``heuristic =
    (fields, far, per_cell)`` has four entries a cell and the robot a row, else :func:`_to_go`'s first turn."""
    fields, far, per_cell = heuristic
    if per_cell == 4 and row >= 0:
        return 0 if c == goal else np.int64(fields[row, c * 4 + o])
    return _to_go(grid, (fields, far), goal, row, c, o)


@numba.njit(cache=True, nogil=True)
def chain_candidates(grid, heuristic, robots, ops, ranks, out) -> None:
    """Fill ``out`` (a :class:`Candidates`) for ``robots`` (a :class:`ChainRobots`) on ``grid`` (a
    :class:`~planners.mapf.common.MoveGrid`), ``heuristic = (fields, far, per_cell)`` (:func:`_cost_to_go`);
    ``ranks = (idle, quiet)``: each operation's tie rank for a robot with a goal and its order for one without (least
    moving first)."""
    nbr = grid.nbr
    pc, orient, gc, rows = robots.pos, robots.orient, robots.goals, robots.rows
    idle, quiet = ranks
    n_ops = ops.shape[0]
    tmp = np.empty((n_ops, STEPS + 1), np.int64)
    keys = np.empty(n_ops, np.int64)
    for k in range(pc.shape[0]):
        p, o, g, row = pc[k], orient[k], gc[k], rows[k]
        busy = p != g
        out.to_go[k] = _cost_to_go(grid, heuristic, g, row, p, o) if busy else 0
        out.still[k, :] = p
        out.wait_value[k] = _VISIT * out.to_go[k] + idle[0] if busy else quiet[0]
        m = 0
        for i in range(1, n_ops):
            end = _walk(nbr, p, o, ops[i], tmp[i])
            if end < 0:
                continue
            if busy:
                v = _VISIT * _cost_to_go(grid, heuristic, g, row, tmp[i, STEPS], end) + idle[i]
                for s in range(1, STEPS + 1):
                    if tmp[i, s] == g:
                        v = -_VISIT * (STEPS + 1 - s) + idle[i]
                        break
            else:
                v = quiet[i]
            keys[m] = v * 256 + i
            m += 1
        srt = np.sort(keys[:m])
        for j in range(m):
            i = srt[j] & 255
            out.cells[k, j] = tmp[i]
            out.op[k, j] = i
            out.value[k, j] = srt[j] >> 8
        out.n[k] = m
        out.idle_act[k] = WAIT
        if busy:
            here = out.to_go[k]
            right = _cost_to_go(grid, heuristic, g, row, p, (o + 1) & 3)
            left = _cost_to_go(grid, heuristic, g, row, p, (o + 3) & 3)
            if min(right, left) < here:
                out.idle_act[k] = CLOCKWISE if right <= left else COUNTER


@numba.njit(cache=True, nogil=True)
def _draw(rng) -> float:
    rng[0] += np.uint64(0x9E3779B97F4A7C15)
    return float(splitmix(rng[0]) >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@numba.njit(cache=True, nogil=True)
def _path(cand, k, c):
    return cand.still[k] if c < 0 else cand.cells[k, c]


@numba.njit(cache=True, nogil=True)
def _gain(gain, k, c) -> int:
    return 0 if c < 0 else gain[k, c]


@numba.njit(cache=True, nogil=True)
def _keep(score, old, temp, rng) -> bool:
    if score >= old:
        return True
    return temp > 0.0 and old > 0 and _draw(rng) < np.exp(-((old - score) / old) / temp)


@numba.njit(cache=True, nogil=True)
def _move(plan, cand, gain, k, c, on) -> None:
    """Put robot ``k`` on candidate ``c`` (``on``) or take it off its current one."""
    if on:
        plan.choice[k] = c
        reserve(plan.res, _path(cand, k, c), k, k)
        plan.score[0] += _gain(gain, k, c)
    else:
        c = plan.choice[k]
        reserve(plan.res, _path(cand, k, c), k, -1)
        plan.score[0] -= _gain(gain, k, c)


@numba.njit(cache=True, nogil=True)
def _chain(root, cid, search, temp, cap, plan, cand, gain, knobs, stack) -> bool:
    """One push chain from ``root`` (module docstring; ``cid`` the chain's number, > 0, marking the robots it
    pushed; ``search``: the search's rules, else the construction's; ``cap`` the deepest operations tried;
    ``knobs`` a :class:`ChainKnobs`); True when kept."""
    choice, rng = plan.choice, plan.rng
    st_a, st_j, st_old, st_lo, st_lo_old, mark = stack.robot, stack.option, stack.old, stack.pushed, stack.pushed_old, \
        stack.mark
    push_built, skip = knobs.push_built, knobs.skip
    old = plan.score[0]
    _move(plan, cand, gain, root, 0, False)
    mark[root] = cid
    top, pushes, ret = 0, 0, -1  # ret: -1 none, 0 nothing found, 1 kept, 2 refused
    st_a[0], st_j[0], st_old[0], st_lo[0] = root, 0, choice[root], -1
    while top >= 0:
        a = st_a[top]
        if ret >= 0:  # the robot a pushed has answered
            if ret == 1:
                top -= 1
                continue
            lo = st_lo[top]
            _move(plan, cand, gain, a, 0, False)
            choice[a] = st_old[top]
            _move(plan, cand, gain, lo, st_lo_old[top], True)
            st_lo[top] = -1
            if ret == 2:
                top -= 1
                continue
            ret = -1
        elif st_j[top] == 0 and pushes > (knobs.pushes if search else _BUILD_PUSHES):
            ret = 2
            top -= 1
            continue
        pushed = False
        while st_j[top] < cand.n[a]:
            c = st_j[top]
            st_j[top] += 1
            if cand.depth[a, c] > cap:
                continue
            path = cand.cells[a, c]
            lo = conflict(plan.res, path, a)
            if lo == -2:
                continue
            if lo == -1:
                _move(plan, cand, gain, a, c, True)
                if _keep(plan.score[0], old, temp if search else 0.0, rng):
                    ret = 1
                else:
                    _move(plan, cand, gain, a, 0, False)
                    choice[a] = st_old[top]
                    ret = 2
                break
            if search:
                if mark[lo] == cid or _draw(rng) < skip:
                    continue
            elif (pushes > _DEEP_PUSHES and top >= 6) or (choice[lo] >= 0 and _draw(rng) >= push_built):
                continue
            pushes += 1
            if search:
                plan.work[0] += 1
            st_lo[top], st_lo_old[top] = lo, choice[lo]
            _move(plan, cand, gain, lo, 0, False)
            _move(plan, cand, gain, a, c, True)
            top += 1
            st_a[top], st_j[top], st_old[top], st_lo[top] = lo, 0, choice[lo], -1
            mark[lo] = cid
            pushed = True
            break
        if pushed:
            continue
        if ret < 0:  # a found nothing
            choice[a] = st_old[top]
            mark[a] = 0
            ret = 0
        top -= 1
    if ret != 1:
        _move(plan, cand, gain, root, choice[root], True)
        return False
    return True


@numba.njit(cache=True, nogil=True)
def chain_build(cand, gain, order, depth_draw, knobs, span, plan) -> None:
    """The construction into ``plan`` for the robots ``order[span[0]:span[1]]`` (from ``span[0] == 0``: every robot
    put waiting first, the table empty on entry), so that spans in turn make the one construction; ``depth_draw``
    the operation depths a plan draws from (here and every 128 search chains); ``knobs`` a :class:`ChainKnobs`."""
    r = order.shape[0]
    if span[0] == 0:
        for k in range(r):
            _move(plan, cand, gain, k, -1, True)
        plan.score[0] = 0
        plan.cap[0] = depth_draw[int(_draw(plan.rng) * depth_draw.shape[0])]
    stack = _stack(r)
    for idx in range(span[0], min(span[1], r)):
        k = order[idx]
        if plan.choice[k] < 0:
            _chain(k, idx + 1, False, 0.0, plan.cap[0], plan, cand, gain, knobs, stack)
    plan.best[:] = plan.choice
    plan.best_score[0] = plan.score[0]


@numba.njit(cache=True, nogil=True)
def chain_search(cand, gain, depth_draw, knobs, chains, budget, plan) -> int:
    """Search chains ``chains = (first, count)`` (numbered on from the call's earlier ones) on ``plan`` after
    :func:`chain_build`, none started once ``plan.work`` (chains and pushes so far) reaches ``budget``; returns how
    many ran.  The temperature, depth and work carry over in ``plan``, so batches make the one long search."""
    r = plan.choice.shape[0]
    first, count = chains
    stack = _stack(r)
    rng = plan.rng
    it = first
    while it < first + count and r > 0 and plan.work[0] < budget:
        if it > 0 and it % 128 == 0:
            plan.cap[0] = depth_draw[int(_draw(rng) * depth_draw.shape[0])]
        k = min(int(_draw(rng) * r), r - 1)
        _chain(k, r + 1 + it, True, plan.temp[0], plan.cap[0], plan, cand, gain, knobs, stack)
        plan.temp[0] *= 0.999
        plan.work[0] += 1
        it += 1
    return it - first


@numba.njit(cache=True, nogil=True)
def chain_finish(cand, gain, plan) -> None:
    """Back to the construction's plan when the search ended below it."""
    if plan.score[0] < plan.best_score[0]:
        for k in range(plan.choice.shape[0]):
            _move(plan, cand, gain, k, 0, False)
        for k in range(plan.choice.shape[0]):
            _move(plan, cand, gain, k, plan.best[k], True)


class ChainStack(NamedTuple):
    """:func:`_chain`'s explicit stack, one level per robot on it, and the robots' marks."""

    robot: np.ndarray       # the robot choosing at this level
    option: np.ndarray      # its next candidate to try
    old: np.ndarray         # its choice before the chain
    pushed: np.ndarray      # the robot its current try pushed (-1: none)
    pushed_old: np.ndarray  # that robot's choice before the push
    mark: np.ndarray        # (R,) the chain that last pushed the robot


@numba.njit(cache=True, nogil=True)
def _stack(r):
    deep = r + _DEEP_PUSHES + 8  # a construction chain may push a robot twice
    return ChainStack(np.empty(deep, np.int64), np.empty(deep, np.int64), np.empty(deep, np.int64),
                      np.full(deep, -1, np.int64), np.empty(deep, np.int64), np.zeros(r, np.int64))


def score_of(plan: ChainPlan, gain: np.ndarray) -> int:
    """A plan's score recounted from its choices (the kernels keep it incrementally)."""
    c = plan.choice
    rows = np.flatnonzero(c >= 0)
    return int(gain[rows, c[rows]].sum())


def stamp_seed(seed: int, t: int, k: int) -> int:
    """Plan ``k``'s random stream at step ``t``."""
    return int(mix(np.uint64(seed), t, k, 0xC4A1))
