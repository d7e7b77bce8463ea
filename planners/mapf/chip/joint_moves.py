"""Joint next moves of congested robot groups as an Ising-chip decision (issue 33, item 3).

Decision class ``joint-moves``: after :class:`~planners.mapf.pibt.turning.PIBTStep` has picked every robot's next
cell, groups of up to ``max_robots`` robots in congested regions re-choose them jointly as one QUBO; a decoded
answer is repaired towards the host rule's claims, so the joint action stays valid.
The executor that uses these kernels: :mod:`planners.mapf.chip.joint_executor`.
Design notes (group, objective, QUBO, decoding): docs/design/lifelong_turning.md#joint-moves-on-the-chip.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from planners.mapf.pibt.turning import CLOCKWISE, COUNTER, FORWARD, WAIT, _distance, vacate_check

__all__ = ["HostStep", "robot_options", "select_groups", "group_options", "group_spread", "build_qubo",
           "solve_exact", "decode_reads", "claims_to_actions", "objective", "MAX_OPTIONS", "CELL", "COST", "DEP", "UNREAL", "FWD",
           "NOT_ONE_HOT", "CONFLICT"]

MAX_OPTIONS = 5  # own cell + four neighbours
#: :func:`decode_reads`' counts: reads not one-hot, reads with a conflict repaired.
NOT_ONE_HOT, CONFLICT = 0, 1
#: Columns of the option table: claimed cell, cost, the group-local member whose cell is claimed by a
#: forward move (-1: none), the cost when that member does not move forward, 1 for a forward claim.
CELL, COST, DEP, UNREAL, FWD = 0, 1, 2, 3, 4
_BIG = 1 << 40


class HostStep(NamedTuple):
    """The host rule's (PIBT's) step the groups start from, in compact cells."""

    pos: np.ndarray     # (R,) each robot's cell
    orient: np.ndarray  # (R,) its orientation
    nxt: np.ndarray     # (R,) the cell PIBT claims for it
    act: np.ndarray     # (R,) and its action there


@numba.njit(cache=True, nogil=True)
def robot_options(grid, heuristic, robots, cand, cost):
    """``cand[k, m]`` robot ``k``'s candidate compact cells (own cell first, then free neighbours east,
    south, west, north; -1 pads), ``cost[k, m]`` its unweighted cost ``2 (d(v) - d(p)) + turns``; ``grid`` a
    :class:`~planners.mapf.common.MoveGrid` (its costs unread), ``heuristic = (fields, rows)``, ``robots = (pos,
    orient, goals)``."""
    nbr, cell_of, width = grid.nbr, grid.cell_of, grid.width
    fields, rows = heuristic
    pos, orient, goals = robots
    for k in range(pos.shape[0]):
        p, o = pos[k], orient[k]
        dp = _distance(fields, rows[k], goals[k], p, cell_of, width)
        cand[k, 0], cost[k, 0] = p, 0
        m = 1
        for d in range(4):
            v = nbr[p, d]
            if v < 0:
                continue
            turns = 0 if d == o else (2 if d == (o + 2) % 4 else 1)
            cand[k, m] = v
            cost[k, m] = 2 * (_distance(fields, rows[k], goals[k], v, cell_of, width) - dp) + turns
            m += 1
        for j in range(m, MAX_OPTIONS):
            cand[k, j], cost[k, j] = -1, _BIG


@numba.njit(cache=True, nogil=True)
def select_groups(nbr, step, options, order, limits, occ, groups):
    """Groups of this step (module docstring) into ``groups = (gid, members, gstart)``:
    ``members[gstart[g]:gstart[g + 1]]`` robots of group ``g`` (BFS order from its seed), ``gid[k]``
    robot ``k``'s group or -1; returns the number of groups.  ``step`` a :class:`HostStep` (the host
    rule's claims), ``options = (cand, cost)``, ``limits = (max_robots, max_spins)``; ``occ`` is
    compact-cell scratch, all -1 on entry and on return."""
    pos, nxt, act = step.pos, step.nxt, step.act
    cand, cost = options
    max_robots, max_spins = limits
    gid, members, gstart = groups
    r = pos.shape[0]
    for k in range(r):
        occ[pos[k]] = k
        gid[k] = -1
    state = np.zeros(r, dtype=np.int8)  # 0 open, 1 grouped, 2 frozen
    ring = np.empty(20, dtype=np.int64)
    ng, m = 0, 0
    gstart[0] = 0
    for idx in range(r):
        s = order[idx]
        if state[s] != 0:
            continue
        host = 0
        best = cost[s, 0]
        for j in range(MAX_OPTIONS):
            if cand[s, j] == nxt[s]:
                host = cost[s, j]
            best = min(best, cost[s, j])
        ahead_cut = nxt[s] != pos[s] and act[s] == WAIT
        if host <= best and not ahead_cut:
            continue
        tail = m
        members[tail] = s
        tail += 1
        state[s] = 1
        spins = 0
        for j in range(MAX_OPTIONS):
            spins += cand[s, j] >= 0
        head = m
        while head < tail and tail - m < max_robots:
            a = members[head]
            head += 1
            nr = _ring(nbr, pos[a], ring)
            for q in range(nr):
                j = occ[ring[q]]
                if j < 0 or state[j] != 0 or tail - m >= max_robots:
                    continue
                nj = 0
                for t in range(MAX_OPTIONS):
                    nj += cand[j, t] >= 0
                if spins + nj > max_spins:
                    continue
                members[tail] = j
                tail += 1
                state[j] = 1
                spins += nj
        for t in range(m, tail):
            gid[members[t]] = ng
            nr = _ring(nbr, pos[members[t]], ring)
            for q in range(nr):
                j = occ[ring[q]]
                if j >= 0 and state[j] == 0:
                    state[j] = 2
        m = tail
        ng += 1
        gstart[ng] = m
    for k in range(r):
        occ[pos[k]] = -1
    return ng


@numba.njit(cache=True, nogil=True)
def _ring(nbr, p, ring) -> int:
    """Cells within two free steps of ``p`` (nearest first, repeats allowed, ``p`` left out)."""
    n = 0
    for d in range(4):
        v = nbr[p, d]
        if v >= 0:
            ring[n] = v
            n += 1
    for i in range(n):
        v = ring[i]
        for d in range(4):
            u = nbr[v, d]
            if u >= 0 and u != p:
                ring[n] = u
                n += 1
    return n


@numba.njit(cache=True, nogil=True)
def group_options(nbr, step, options, rank, groups, ng, weights, scratch, out):
    """Allowed options of every group member (module docstring) into ``out = (ostart, opt, host)``:
    member ``t``'s options are rows ``opt[ostart[t]:ostart[t + 1]]`` (columns :data:`CELL`,
    :data:`COST`, :data:`DEP`, :data:`UNREAL`, :data:`FWD`); ``host[t]`` the index of its host claim
    among them.  ``step`` a :class:`HostStep`, ``options = (cand, cost)``, ``groups`` as
    :func:`select_groups`, ``weights = (levels, push)``; ``scratch = (claim, occ)`` compact-cell
    scratch, -1 on entry and on return."""
    pos, orient, nxt, act = step.pos, step.orient, step.nxt, step.act
    cand, cost = options
    gid, members, gstart = groups
    levels, push = weights
    claim, occ = scratch
    ostart, opt, host = out
    r = pos.shape[0]
    for k in range(r):
        claim[nxt[k]] = k
        occ[pos[k]] = k
    slot = np.full(r, -1, dtype=np.int64)
    for g in range(ng):
        for t in range(gstart[g], gstart[g + 1]):
            slot[members[t]] = t - gstart[g]
    n = 0
    ostart[0] = 0
    for g in range(ng):
        a, b = gstart[g], gstart[g + 1]
        size = b - a
        for t in range(a, b):
            k = members[t]
            higher = 0  # members of higher priority: the weight tier
            for u in range(a, b):
                higher += rank[members[u]] < rank[k]
            w = levels - (levels * higher) // size
            ahead = nbr[pos[k], orient[k]]
            host[t] = -1
            for j in range(MAX_OPTIONS):
                v = cand[k, j]
                if v < 0:
                    continue
                c = claim[v]
                if c >= 0 and gid[c] != g:
                    continue  # a frozen robot's claim
                o = occ[v]
                if o >= 0 and gid[o] != g and nxt[o] == pos[k]:
                    continue  # a swap with a frozen robot
                if v == nxt[k]:
                    host[t] = n - ostart[t]
                opt[n, CELL] = v
                opt[n, COST] = w * cost[k, j]
                opt[n, UNREAL] = (push * w * cost[k, j]) // 2
                opt[n, DEP] = -1
                opt[n, FWD] = v == ahead
                if v == ahead and o >= 0:
                    if gid[o] == g:
                        opt[n, DEP] = slot[o]
                    elif act[o] != FORWARD:
                        opt[n, COST] = opt[n, UNREAL]  # the frozen robot ahead stays: no move this step
                n += 1
            ostart[t + 1] = n
    for k in range(r):
        claim[nxt[k]] = -1
        occ[pos[k]] = -1
    return n


@numba.njit(cache=True, nogil=True)
def group_spread(a, b, ostart, opt) -> int:
    """Largest spread (max - min) of one member's option costs (realised or not) in the group ``a:b``."""
    top = 0
    for t in range(a, b):
        lo, hi = opt[ostart[t], COST], opt[ostart[t], COST]
        for x in range(ostart[t], ostart[t + 1]):
            lo, hi = min(lo, opt[x, COST], opt[x, UNREAL]), max(hi, opt[x, COST], opt[x, UNREAL])
        top = max(top, hi - lo)
    return top


@numba.njit(cache=True, nogil=True)
def _conflict(v, pi, u, pj) -> bool:
    """Claims ``v`` (robot at ``pi``) and ``u`` (robot at ``pj``) of two robots cannot stand together."""
    return v == u or (v == pj and u == pi)


@numba.njit(cache=True, nogil=True)
def build_qubo(pos, members, a, b, ostart, opt, one_hot, pair, q):
    """Upper-triangular integer QUBO ``q[:n, :n]`` of the group ``members[a:b]`` (``n`` its options,
    returned); its energy plus ``one_hot * (b - a)`` is the objective on every feasible one-hot
    assignment."""
    base = ostart[a]
    n = ostart[b] - base
    q[:n, :n] = 0
    for t in range(a, b):
        for x in range(ostart[t], ostart[t + 1]):
            i = x - base
            q[i, i] += opt[x, COST] - one_hot
            for y in range(x + 1, ostart[t + 1]):
                q[i, y - base] += 2 * one_hot
            for t2 in range(t + 1, b):
                for y in range(ostart[t2], ostart[t2 + 1]):
                    if _conflict(opt[x, CELL], pos[members[t]], opt[y, CELL], pos[members[t2]]):
                        q[i, y - base] += pair
            d = opt[x, DEP]
            if d >= 0:  # the robot ahead stays (turns or waits): this forward claim does not move
                for y in range(ostart[a + d], ostart[a + d + 1]):
                    if opt[y, FWD] == 0 and opt[y, CELL] != opt[x, CELL]:
                        lo, hi = min(i, y - base), max(i, y - base)
                        q[lo, hi] += opt[x, UNREAL] - opt[x, COST]
    return n


def program_batch(ng: int, gstart: np.ndarray, ostart: np.ndarray):
    """``(sizes, q, H, J)`` for ``ng`` groups whose options are ``ostart[gstart[g]]:ostart[gstart[g + 1]]``: each
    program's spins, a QUBO scratch of the largest, and the batch's zeroed integer ``H (ng, n)``, ``J (ng, n, n)``."""
    sizes = ostart[gstart[1:ng + 1]] - ostart[gstart[:ng]]
    n = int(sizes.max())
    return sizes, np.empty((n, n), dtype=np.int64), np.zeros((ng, n), dtype=np.int64), np.zeros((ng, n, n), np.int64)


@numba.njit(cache=True, nogil=True)
def _realised(x, a, ostart, opt, choice) -> int:
    d = opt[x, DEP]
    if d < 0 or opt[ostart[a + d] + choice[d], FWD]:
        return opt[x, COST]
    return opt[x, UNREAL]


@numba.njit(cache=True, nogil=True)
def objective(a, b, ostart, opt, choice) -> int:
    """Objective of the group ``a:b``'s choice (``choice[t - a]`` option index of member ``t``)."""
    e = 0
    for t in range(a, b):
        e += _realised(ostart[t] + choice[t - a], a, ostart, opt, choice)
    return e


@numba.njit(cache=True, nogil=True)
def _bound(x, opt) -> int:
    return min(opt[x, COST], opt[x, UNREAL]) if opt[x, DEP] >= 0 else opt[x, COST]


@numba.njit(cache=True, nogil=True)
def solve_exact(pos, members, a, b, ostart, opt, choice) -> int:
    """Exact optimum of the group by depth-first branch and bound (options cheapest first; a forward
    claim whose robot ahead is not decided yet counts its lower cost until it is; bound = that + each
    remaining member's cheapest option); ``choice`` gets it, the value is returned."""
    size = b - a
    base = ostart[a]
    lo = np.zeros(size + 1, dtype=np.int64)
    for t in range(b - 1, a - 1, -1):
        c = _BIG
        for x in range(ostart[t], ostart[t + 1]):
            c = min(c, _bound(x, opt))
        lo[t - a] = lo[t - a + 1] + c
    order = np.empty(ostart[b] - base, dtype=np.int64)  # per member, option indices cheapest first
    for t in range(a, b):
        s0, s1 = ostart[t] - base, ostart[t + 1] - base
        for x in range(s0, s1):
            order[x] = x - s0
        for i in range(s0 + 1, s1):
            j = i
            while j > s0 and _bound(base + s0 + order[j - 1], opt) > _bound(base + s0 + order[j], opt):
                order[j - 1], order[j] = order[j], order[j - 1]
                j -= 1
    cur = np.zeros(size, dtype=np.int64)
    pick = np.zeros(size, dtype=np.int64)
    part = np.zeros(size + 1, dtype=np.int64)
    best = _BIG
    d = 0
    cur[0] = -1
    while d >= 0:
        t = a + d
        cur[d] += 1
        if cur[d] >= ostart[t + 1] - ostart[t]:
            d -= 1
            continue
        k = order[ostart[t] - base + cur[d]]
        x = ostart[t] + k
        ok = True
        val = part[d]
        for e in range(d):
            y = ostart[a + e] + pick[e]
            if _conflict(opt[x, CELL], pos[members[t]], opt[y, CELL], pos[members[a + e]]):
                ok = False
                break
            if opt[y, DEP] == d:  # an earlier forward claim into this robot's cell: now known
                val += (opt[y, COST] if opt[x, FWD] else opt[y, UNREAL]) - _bound(y, opt)
        if not ok:
            continue
        dx = opt[x, DEP]
        if dx >= 0 and dx < d:
            val += opt[x, COST] if opt[ostart[a + dx] + pick[dx], FWD] else opt[x, UNREAL]
        else:
            val += _bound(x, opt)
        if val + lo[d + 1] >= best:
            continue
        pick[d] = k
        part[d + 1] = val
        if d + 1 == size:
            best = val
            choice[:size] = pick[:size]
        else:
            d += 1
            cur[d] = -1
    return best


@numba.njit(cache=True, nogil=True)
def decode_reads(pos, members, a, b, ostart, opt, host, spins, choice, stats) -> int:
    """Best read of the group after repair (module docstring) into ``choice``; returns its objective.
    ``stats[NOT_ONE_HOT]`` += reads not one-hot, ``stats[CONFLICT]`` += reads with a conflict repaired."""
    size = b - a
    base = ostart[a]
    cur = np.empty(size, dtype=np.int64)
    best = _BIG
    for rd in range(spins.shape[0]):
        broken = False
        for t in range(a, b):
            set_ = -1
            cnt = 0
            for x in range(ostart[t], ostart[t + 1]):
                if spins[rd, x - base] > 0:
                    cnt += 1
                    set_ = x - ostart[t]
            if cnt != 1:
                broken = True
                set_ = host[t]
            cur[t - a] = set_
        fixed = False
        changed = True
        while changed:
            changed = False
            for i in range(size):
                for j in range(i + 1, size):
                    x = ostart[a + i] + cur[i]
                    y = ostart[a + j] + cur[j]
                    if _conflict(opt[x, CELL], pos[members[a + i]], opt[y, CELL], pos[members[a + j]]):
                        if cur[i] != host[a + i]:
                            cur[i] = host[a + i]
                            changed = True
                        if cur[j] != host[a + j]:
                            cur[j] = host[a + j]
                            changed = True
                        fixed = True
        stats[NOT_ONE_HOT] += broken
        stats[CONFLICT] += fixed
        e = objective(a, b, ostart, opt, cur)
        if e < best:
            best = e
            choice[:size] = cur
    return best


@numba.njit(cache=True, nogil=True)
def claims_to_actions(nbr, pos, orient, nxt, act, occ_now):
    """Actions of distinct, swap-free claims ``nxt`` (PIBTStep's rule: ahead F, side C / R, behind R,
    own cell W; then the vacate check).  ``occ_now`` compact-cell scratch, -1 on entry and return."""
    r = pos.shape[0]
    for k in range(r):
        occ_now[pos[k]] = k
        p, v, o = pos[k], nxt[k], orient[k]
        act[k] = WAIT
        for d in range(4):
            if v != p and nbr[p, d] == v:
                act[k] = FORWARD if d == o else (COUNTER if d == (o + 3) % 4 else CLOCKWISE)
    vacate_check(pos, nxt, act, occ_now)
    for k in range(r):
        occ_now[pos[k]] = -1
