"""Neighbourhood groups of a joint plan choosing their operations jointly (decision class ``lns_groups``, shared by
``epibt-ising`` and ``epibt-chain-ising``), compiled: :func:`select_groups`, a round's programs
(:func:`group_programs`), the host rule (:func:`host_choices`), the chip's answers (:func:`decode_choices`) and
:func:`apply_choices`.  Design notes: docs/design/lifelong_turning.md#the-group-kernels.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from ising_backend import integer_program
from planners.mapf.chip.choice_qubo import reduce_to_reference
from planners.mapf.common import mix
from planners.mapf.epibt.search import blockers, conflict, more_blockers, reserve

__all__ = ["GroupShape", "select_groups", "group_qubo", "group_programs", "host_choices", "decode_choices",
           "apply_choices", "collide", "path_of", "cost_of", "NO_CHOICE"]


@numba.njit(cache=True, nogil=True)
def collide(state, q1, c1, q2, c2) -> bool:
    """Robot ``q1``'s candidate ``c1`` and robot ``q2``'s ``c2`` (-1: a robot's inherited operation; cells as
    :func:`path_of`'s) meet in a cell or swap cells at some time.  Reads the cells in place (no array views: the
    rounds test thousands of option pairs a round)."""
    cells, inh = state.cells, state.inh
    for t in range(1, cells.shape[2]):
        p0 = cells[q1, c1, t - 1] if c1 >= 0 else inh[q1, t - 1]
        p1 = cells[q1, c1, t] if c1 >= 0 else inh[q1, t]
        r0 = cells[q2, c2, t - 1] if c2 >= 0 else inh[q2, t - 1]
        r1 = cells[q2, c2, t] if c2 >= 0 else inh[q2, t]
        if p1 == r1 or (p1 != p0 and p1 == r0 and r1 == p0):
            return True
    return False


#: A group's cost when it has no choice (no collision-free read, a robot left without an option): above any cost.
NO_CHOICE = 1 << 62


class GroupShape(NamedTuple):
    """What a call's groups may hold."""

    groups: int       # groups at most
    max_robots: int   # robots per group
    max_options: int  # options per robot (its operation now included)
    max_spins: int    # spins per program
    grow: bool = False  # grow through the robots in the way of the members' first options, not the first robot's only


@numba.njit(cache=True, nogil=True)
def select_groups(state, res, limits, stamp, taken, out, seeds) -> int:
    """This call's groups (module docstring) into ``out`` (a :class:`~planners.mapf.common.GroupBatch`, its
    ``ng`` unread: the count is returned): group ``g`` is
    ``members[gstart[g]:gstart[g + 1]]``, robot slot ``m``'s options ``opt[ostart[m]:ostart[m + 1]]`` (a
    candidate index, -1 its inherited operation; option 0 its operation now).  ``limits`` a :class:`GroupShape`,
    ``stamp = (seed, t)``, ``taken`` (robots) all 0 on entry; only robots with ``seeds[k]`` start a group (any may
    join one).  A growing group adds, member by member, the robots in the way of each one's first ``max_options``
    operations (a push chain's robots, decided at once)."""
    cells, ncand, cur, src = state.cells, state.ncand, state.cur, state.src
    n_groups, max_robots, max_options, max_spins = limits.groups, limits.max_robots, limits.max_options, \
        limits.max_spins
    seed, t = stamp
    members, gstart, ostart, opt = out.members, out.gstart, out.ostart, out.opt
    r = cur.shape[0]
    ng = 0
    m = 0
    gstart[0] = 0
    ostart[0] = 0
    if r == 0:
        return 0
    start = np.int64(mix(seed, t, r, 0x6C) % np.uint64(r))
    for j in range(r):
        if ng == n_groups:
            break
        k = (start + j) % r
        if src[k] == 0 or ncand[k] == 0 or taken[k] or not seeds[k]:
            continue
        a = m
        size = blockers(k, cells, src[k] if src[k] > 0 else ncand[k], res, max_robots, members[a:], taken)
        i = 1
        while limits.grow and i < size < max_robots:
            q = members[a + i]
            size = more_blockers(q, cells, min(ncand[q], max_options), res, max_robots, members[a:], size, taken)
            i += 1
        m = a + size
        if size < 2:  # nothing in the way to choose with
            m = a
            continue
        per = min(max_options, max_spins // size + 1)  # a robot's operation now takes no spin
        for i in range(a, m):
            reserve(res, cur[members[i]], members[i], -1)
        for i in range(a, m):
            q = members[i]
            x = ostart[i]
            opt[x] = src[q]
            x += 1
            for c in range(ncand[q]):
                if x - ostart[i] >= per:
                    break
                if c != src[q] and conflict(res, cells[q, c], q) == -1:
                    opt[x] = c
                    x += 1
            ostart[i + 1] = x
        for i in range(a, m):
            reserve(res, cur[members[i]], members[i], members[i])
        ng += 1
        gstart[ng] = m
    return ng


@numba.njit(cache=True, nogil=True)
def path_of(state, q, c):
    return state.cells[q, c] if c >= 0 else state.inh[q]


@numba.njit(cache=True, nogil=True)
def cost_of(state, q, c) -> int:
    return state.costs[q, c] if c >= 0 else state.inh_cost[q]


@numba.njit(cache=True, nogil=True)
def group_qubo(state, members, a, b, ostart, opt, q, penalty=2) -> int:
    """Upper-triangular integer QUBO ``q[:n, :n]`` of the group ``members[a:b]``; ``n``, returned, is its options
    less one per robot: a robot's operation now (option 0) is all its spins down, another option one spin up
    (:func:`planners.mapf.chip.choice_qubo.reduce_to_reference`).  The objective: each option's cost-to-go, ``P`` on
    each pair of colliding options; with ``s = 1 +`` the widest gap of one option's cost to its robot's operation
    now, ``penalty x s`` on each pair of spins of one robot and ``P`` half that.  Among reads with at most one spin
    up per robot the energy is the cost above the plan now plus ``P`` per colliding pair; the chip's few levels
    go to the costs, not to a one-hot constraint's fields."""
    base = ostart[a]
    n = ostart[b] - base
    spread = 0
    for i in range(a, b):
        c0 = cost_of(state, members[i], opt[ostart[i]])
        for x in range(ostart[i] + 1, ostart[i + 1]):
            spread = max(spread, abs(cost_of(state, members[i], opt[x]) - c0))
    amo = penalty * (spread + 1)
    pen = (amo + 1) // 2
    full = np.zeros((n, n), dtype=np.int64)
    for i in range(a, b):
        for x in range(ostart[i], ostart[i + 1]):
            full[x - base, x - base] = cost_of(state, members[i], opt[x])
            for i2 in range(i + 1, b):
                for y in range(ostart[i2], ostart[i2 + 1]):
                    if collide(state, members[i], opt[x], members[i2], opt[y]):
                        full[x - base, y - base] = pen
    return reduce_to_reference(full, ostart[a:b + 1] - base, np.zeros(b - a, dtype=np.int64), amo, q)


@numba.njit(cache=True, nogil=True)
def group_programs(state, batch, penalty, limits, H, J) -> None:
    """Every group's chip program (:func:`group_qubo`, then :func:`~ising_backend.integer_program` scaled to the
    machine's ``limits``) into ``H[g]``, ``J[g]`` (zeroed past its spins) for the groups of ``batch`` (a
    :class:`~planners.mapf.common.GroupBatch`): a round's programs in one call."""
    q = np.empty((H.shape[1], H.shape[1]), dtype=np.int64)
    for g in range(batch.ng):
        k = group_qubo(state, batch.members, batch.gstart[g], batch.gstart[g + 1], batch.ostart, batch.opt, q, penalty)
        integer_program(q, k, H[g, :k], J[g, :k, :k], limits)
        H[g, k:] = 0
        J[g, k:, :] = 0
        J[g, :k, k:] = 0


@numba.njit(cache=True, nogil=True)
def host_choices(state, batch, stamp, choice, cost) -> None:
    """The host rule for every group of ``batch``: robots in the order of ``mix(seed, t, g, robot)``, each its
    cheapest option colliding with none placed before, into ``choice[m]`` (robot slot ``m``'s option); ``cost[g]``
    the group's cost (:data:`NO_CHOICE` when a robot is left without one: the group keeps its plan; a cost may be
    negative, as the push chains' are).  ``stamp = (seed, t)``."""
    seed, t = stamp
    members, gstart, ostart, opt = batch.members, batch.gstart, batch.ostart, batch.opt
    for g in range(batch.ng):
        a, b = gstart[g], gstart[g + 1]
        size = b - a
        keys = np.empty(size, dtype=np.uint64)
        for i in range(size):
            keys[i] = mix(seed, t, g, members[a + i])
        order = np.argsort(keys)
        placed = np.zeros(size, dtype=np.int8)
        total = 0
        for i in order:
            q = members[a + i]
            best = -1
            for x in range(ostart[a + i], ostart[a + i + 1]):
                ok = True
                for j in range(size):
                    if placed[j] and collide(state, q, opt[x], members[a + j], opt[ostart[a + j] + choice[a + j]]):
                        ok = False
                        break
                if ok and (best < 0 or cost_of(state, q, opt[x]) < cost_of(state, q, opt[best])):
                    best = x
            if best < 0:
                total = NO_CHOICE
                break
            choice[a + i] = best - ostart[a + i]
            placed[i] = 1
            total += cost_of(state, q, opt[best])
        cost[g] = total


@numba.njit(cache=True, nogil=True)
def decode_choices(state, batch, spins, choice, cost) -> None:
    """The chip's answers for every group of ``batch`` (``spins[g]`` its reads, as :func:`group_qubo`'s spins):
    the cheapest collision-free read into ``choice[m]`` (robot slot ``m``'s option); a robot with no spin up, or
    more than one, keeps its operation now (option 0) in that read.  ``cost[g]``: its cost (:data:`NO_CHOICE` when
    no read is collision-free).  Whether two options collide is computed once per group, when a read first needs
    it; a read equal to the one before it is not weighed again."""
    members, gstart, ostart, opt = batch.members, batch.gstart, batch.ostart, batch.opt
    width, size = 0, 0
    for g in range(batch.ng):
        width = max(width, ostart[gstart[g + 1]] - ostart[gstart[g]])
        size = max(size, gstart[g + 1] - gstart[g])
    clash = np.empty((width, width), dtype=np.int8)  # -1 not known yet, else whether the two options collide
    cur = np.zeros(size, dtype=np.int64)
    for g in range(batch.ng):
        a, b = gstart[g], gstart[g + 1]
        base = ostart[a]
        clash[:, :] = -1
        best = NO_CHOICE
        for rd in range(spins.shape[1]):
            same = rd > 0
            for i in range(a, b):  # robot i's spins: its options but the first, after the spins of those before it
                s0 = ostart[i] - base - (i - a)
                pick, up = 0, 0
                for j in range(ostart[i + 1] - ostart[i] - 1):
                    if spins[g, rd, s0 + j] > 0:
                        up += 1
                        pick = j + 1
                if up != 1:
                    pick = 0
                same = same and pick == cur[i - a]
                cur[i - a] = pick
            if same:
                continue
            total = 0
            free = True
            for i in range(a, b):
                x = ostart[i] + cur[i - a]
                for i2 in range(i + 1, b):
                    y = ostart[i2] + cur[i2 - a]
                    if clash[x - base, y - base] < 0:
                        clash[x - base, y - base] = collide(state, members[i], opt[x], members[i2], opt[y])
                    if clash[x - base, y - base]:
                        free = False
                        break
                if not free:
                    break
                total += cost_of(state, members[i], opt[x])
            if free and total < best:
                best = total
                choice[a:b] = cur[:b - a]
        cost[g] = best


@numba.njit(cache=True, nogil=True)
def apply_choices(state, res, groups, choices, costs_now, min_gain=1) -> int:
    """Groups in turn take their choice (``choices[m]`` robot slot ``m``'s option; ``costs_now[g]``
    :data:`NO_CHOICE`: none)
    when it costs at least ``min_gain`` less than their plan now and collides with nothing left in the plan;
    returns how many did (``groups`` a :class:`~planners.mapf.common.GroupBatch`)."""
    cur, src = state.cur, state.src
    members, gstart, ostart, opt = groups.members, groups.gstart, groups.ostart, groups.opt
    applied = 0
    for g in range(groups.ng):
        a, b = gstart[g], gstart[g + 1]
        if costs_now[g] == NO_CHOICE:
            continue
        before = 0
        for i in range(a, b):
            before += cost_of(state, members[i], src[members[i]])
        if costs_now[g] > before - min_gain:
            continue
        for i in range(a, b):
            reserve(res, cur[members[i]], members[i], -1)
        ok = True
        for i in range(a, b):
            if conflict(res, path_of(state, members[i], opt[ostart[i] + choices[i]]), members[i]) != -1:
                ok = False
                break
            reserve(res, path_of(state, members[i], opt[ostart[i] + choices[i]]), members[i], members[i])
        for i in range(a, b):
            q = members[i]
            reserve(res, path_of(state, q, opt[ostart[i] + choices[i]]), q, -1)
        if ok:
            for i in range(a, b):
                q = members[i]
                src[q] = opt[ostart[i] + choices[i]]
                cur[q] = path_of(state, q, src[q])
            applied += 1
        for i in range(a, b):
            reserve(res, cur[members[i]], members[i], members[i])
    return applied
