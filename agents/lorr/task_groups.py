"""``lorr-ising``: the winner's measure at scale, with the chip deciding who takes which task in contested groups.

Each step :class:`~agents.lorr.weighted.WeightedScheduler`'s greedy matching assigns the free robots; then up to
``groups`` decisions of class ``task_groups`` let contested groups re-choose their tasks on the chip, a group
taking the chip's answer when its cost falls by at least ``min_gain``. Measurements: docs/lorr.md.
Design notes: docs/design/lorr_runs.md#lorr-ising-task-groups-on-the-chip.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import NamedTuple, cast

import numba
import numpy as np

from agents.lorr.weighted import Matched, WeightedOptions, WeightedScheduler
from ising_backend import CallLedger, integer_program
from ising_backend.audit.host_rule import host_rule_classes
from planners.compute import ComputeReport
from planners.mapf.chip.choice_qubo import read_choices, reduce_to_reference
from planners.mapf.common import GroupBatch, machine_for, mix
from planners.options import Options, option, record

__all__ = ["IsingWeightedScheduler", "TaskGroupOptions", "GroupLimits", "select_task_groups", "task_qubo",
           "group_cost", "task_programs", "decode_task_groups"]

# cost of a cut-off option; an np.int64 for the kernels, typed int (cast: no change) as numba's int64 is their int
_NONE = cast(int, np.int64(1) << 50)


class GroupLimits(NamedTuple):
    """How large one step's decisions may grow."""

    groups: int  # decisions per step
    max_robots: int  # robots per group
    max_options: int  # options per robot, its task now included
    max_spins: int  # the machine's usable spins: options less one per robot, per group
    max_gap: int  # an option costs its robot at most this much more than its task now


@numba.njit(cache=True, nogil=True)
def _cost(m, cell_of, load, i, s) -> int:
    """Robot ``i`` on slot ``s`` of matching ``m`` with block loads ``load``."""
    c = cell_of[s]
    if m.way[i, c] < 0:
        return _NONE
    return m.weight * np.int64(m.way[i, c]) + m.length[s] + m.crowd.weight * load[m.crowd.block[c]]


@numba.njit(cache=True, nogil=True)
def _add(pool, k, s, taken_s) -> int:
    """``s`` appended to ``pool[:k]`` unless there or taken by another group; the new size."""
    if s < 0 or taken_s[s]:
        return k
    for j in range(k):
        if pool[j] == s:
            return k
    pool[k] = s
    return k + 1


@numba.njit(cache=True, nogil=True)
def select_task_groups(m, cell_of, owner, head, limits, seed, t, taken_r, taken_s, batch) -> int:
    """This step's groups (module docstring) into ``batch`` (a :class:`~planners.mapf.common.GroupBatch` of empty
    arrays: ``opt`` holds slots, option 0 of each robot its slot now); ``cell_of[s]`` slot ``s``'s cell,
    ``owner[s]`` its robot (-1 free), ``head[c]`` cell ``c``'s first free slot; ``seed``, ``t`` the order's; ``taken_r``
    (robots) and ``taken_s`` (slots) all 0 on entry.  Returns the number of groups."""
    members, gstart, ostart, opt = batch.members, batch.gstart, batch.ostart, batch.opt
    load = m.crowd.load
    n = m.out.shape[0]
    ncell = m.cell_start.shape[0] - 1
    gstart[0] = 0
    ostart[0] = 0
    if n == 0:
        return 0
    pool = np.empty(5 * limits.max_robots, dtype=np.int64)  # at most 2 a joining robot and 3 a member
    pcost = np.empty(pool.shape[0], dtype=np.int64)
    ng, a = 0, 0
    first = np.int64(mix(seed, t, n, 0x7A5) % np.uint64(n))
    for j in range(n):
        if ng == limits.groups:
            break
        k = (first + j) % n
        if taken_r[k] or m.out[k] < 0:
            continue
        cur = _cost(m, cell_of, load, k, m.out[k])
        size = 1
        members[a] = k
        np_ = 0
        for c in range(ncell):  # the cells whose tasks are cheaper for k than its own: their robots join
            if size == limits.max_robots:
                break
            for s in range(m.cell_start[c], head[c]):
                if _cost(m, cell_of, load, k, s) >= cur or size == limits.max_robots:
                    break
                r = owner[s]
                if r < 0 or r == k or taken_r[r] or taken_s[s]:
                    continue
                members[a + size] = r
                size += 1
                np_ = _add(pool, np_, s, taken_s)
                np_ = _add(pool, np_, head[c] if head[c] < m.cell_start[c + 1] else -1, taken_s)
        if size < 2:  # no one holds what k would rather take
            continue
        for i in range(a, a + size):  # each member's task, the free head of its cell, its cheapest free task
            r = members[i]
            np_ = _add(pool, np_, m.out[r], taken_s)
            c = cell_of[m.out[r]]
            np_ = _add(pool, np_, head[c] if head[c] < m.cell_start[c + 1] else -1, taken_s)
            best, best_cost = -1, _NONE
            for c2 in range(ncell):
                if head[c2] < m.cell_start[c2 + 1] and not taken_s[head[c2]]:
                    v = _cost(m, cell_of, load, r, head[c2])
                    if v < best_cost:
                        best, best_cost = head[c2], v
            np_ = _add(pool, np_, best, taken_s)
        per = min(limits.max_options, limits.max_spins // size + 1)
        for i in range(a, a + size):  # option 0 the task now, then the cheapest of the pool
            r = members[i]
            for x in range(np_):
                pcost[x] = _cost(m, cell_of, load, r, pool[x])
            order = np.argsort(pcost[:np_], kind="mergesort")
            x = ostart[i]
            opt[x] = m.out[r]
            x += 1
            top = _cost(m, cell_of, load, r, m.out[r]) + limits.max_gap
            for y in order:
                if x - ostart[i] >= per or pcost[y] > top:
                    break
                if pool[y] != m.out[r]:
                    opt[x] = pool[y]
                    x += 1
            ostart[i + 1] = x
        for i in range(a, a + size):
            taken_r[members[i]] = 1
        for x in range(np_):
            taken_s[pool[x]] = 1
        a += size
        ng += 1
        gstart[ng] = a
    return ng


@numba.njit(cache=True, nogil=True)
def _outside(m, cell_of, members, a, b) -> np.ndarray:
    """The block loads with the group's own robots (their slots now) taken out."""
    load = m.crowd.load.copy()
    for i in range(a, b):
        load[m.crowd.block[cell_of[m.out[members[i]]]]] -= 1
    return load


@numba.njit(cache=True, nogil=True)
def group_cost(m, cell_of, members, a, b, ostart, opt, choice) -> int:
    """The group's cost under ``choice`` (an option per robot): each robot's cost with the loads from outside the
    group, ``jam`` per pair of robots in one block; -1 when two robots take one slot."""
    return _cost_with(m, cell_of, _outside(m, cell_of, members, a, b), members, a, b, ostart, opt, choice)


@numba.njit(cache=True, nogil=True)
def _cost_with(m, cell_of, load, members, a, b, ostart, opt, choice) -> int:
    """:func:`group_cost` with the loads from outside the group given (``load``)."""
    total = 0
    for i in range(a, b):
        s = opt[ostart[i] + choice[i - a]]
        total += _cost(m, cell_of, load, members[i], s)
        for i2 in range(i + 1, b):
            s2 = opt[ostart[i2] + choice[i2 - a]]
            if s2 == s:
                return -1
            if m.crowd.block[cell_of[s2]] == m.crowd.block[cell_of[s]]:
                total += m.crowd.weight
    return total


@numba.njit(cache=True, nogil=True)
def task_qubo(m, cell_of, members, a, b, ostart, opt, q, penalty=2) -> int:
    """Upper-triangular integer QUBO ``q[:n, :n]`` of the group ``members[a:b]`` (``n``, returned: its options less
    one per robot; a robot's task now is all its spins down).  The one-hot objective is :func:`group_cost` with
    ``P`` on a pair of options of one slot; with ``s = 1 +`` the widest gap of an option's cost to its robot's
    task now ``+ jam x`` (robots - 1), ``penalty x s`` on each pair of one robot's spins and ``P`` half that."""
    load = _outside(m, cell_of, members, a, b)
    base = ostart[a]
    n = ostart[b] - base
    jam = m.crowd.weight
    spread = 0
    for i in range(a, b):
        c0 = _cost(m, cell_of, load, members[i], opt[ostart[i]])
        for x in range(ostart[i] + 1, ostart[i + 1]):
            spread = max(spread, abs(_cost(m, cell_of, load, members[i], opt[x]) - c0))
    amo = penalty * (spread + jam * (b - a - 1) + 1)
    pen = (amo + 1) // 2
    full = np.zeros((n, n), dtype=np.int64)
    for i in range(a, b):
        for x in range(ostart[i], ostart[i + 1]):
            s = opt[x]
            full[x - base, x - base] = _cost(m, cell_of, load, members[i], s)
            for i2 in range(i + 1, b):
                for y in range(ostart[i2], ostart[i2 + 1]):
                    if opt[y] == s:
                        full[x - base, y - base] = pen
                    elif m.crowd.block[cell_of[opt[y]]] == m.crowd.block[cell_of[s]]:
                        full[x - base, y - base] = jam
    return reduce_to_reference(full, ostart[a:b + 1] - base, np.zeros(b - a, dtype=np.int64), amo, q)


@numba.njit(cache=True, nogil=True)
def task_programs(m, cell_of, batch, penalty, limits, H, J) -> None:
    """Every group's chip program (:func:`task_qubo`, then :func:`~ising_backend.integer_program` scaled to the
    machine's ``limits``) into ``H[g]``, ``J[g]`` (zeroed past its spins): a step's programs in one call."""
    q = np.empty((H.shape[1], H.shape[1]), dtype=np.int64)
    for g in range(batch.ng):
        k = task_qubo(m, cell_of, batch.members, batch.gstart[g], batch.gstart[g + 1], batch.ostart, batch.opt, q,
                      penalty)
        integer_program(q, k, H[g, :k], J[g, :k, :k], limits)
        H[g, k:] = 0
        J[g, k:, :] = 0
        J[g, :k, k:] = 0


@numba.njit(cache=True, nogil=True)
def decode_task_groups(m, cell_of, batch, spins, choice, cost, now) -> None:
    """The chip's answers for every group of ``batch`` (``spins[g]`` its reads, as :func:`task_qubo`'s): its
    cheapest read that gives no slot twice into ``choice[a:b]`` (a robot with no spin up, or more than one, keeps its
    task now in that read), its cost into ``cost[g]`` (-1 when every read gives a slot twice; a cost is a sum of
    distances, never below zero) and the group's cost now into ``now[g]``."""
    members, gstart, ostart, opt = batch.members, batch.gstart, batch.ostart, batch.opt
    zero = np.zeros(ostart.shape[0], dtype=np.int64)
    for g in range(batch.ng):
        a, b = gstart[g], gstart[g + 1]
        load = _outside(m, cell_of, members, a, b)
        now[g] = _cost_with(m, cell_of, load, members, a, b, ostart, opt, zero)
        reads = read_choices(spins[g], ostart[a:b + 1] - ostart[a])
        best = -1
        for rd in range(reads.shape[0]):
            e = _cost_with(m, cell_of, load, members, a, b, ostart, opt, reads[rd])
            if e >= 0 and (best < 0 or e < best):
                best = e
                choice[a:b] = reads[rd]
        cost[g] = best


@dataclass(frozen=True)
class TaskDecisionOptions(Options):
    """The group decisions' options."""

    groups: int = option(64, int, 0, 1 << 16, meaning="decisions per step")
    max_robots: int = option(6, int, 2, 22, meaning="robots per group")
    max_options: int = option(4, int, 2, 16, meaning="options per robot, its task now included")
    max_gap: int = option(64, int, 0, 1 << 20, meaning="an option costs its robot at most this much more than its "
                          "task now (the chip's few levels go to the gaps that can pay)")
    num_reads: int = option(32, int, 1, 64, meaning="reads per program")
    penalty: int = option(2, int, 1, 64, meaning="the at-most-one penalty in units of 1 + the widest cost gap; "
                          "a task taken twice half that")
    min_gain: int = option(1, int, 1, 1 << 20, meaning="a group takes the decided choice when it lowers the "
                           "group's cost by at least this much")


TaskGroupOptions = record("TaskGroupOptions", "lorr-ising's options: the winner's measure's "
                          "(:class:`~agents.lorr.weighted.WeightedOptions`) and its decisions'.", WeightedOptions,
                          TaskDecisionOptions, module=__name__)


class IsingWeightedScheduler(WeightedScheduler):
    """:class:`~agents.lorr.weighted.WeightedScheduler` plus the chip's group decisions (module docstring).

    Args:
        seed: the groups' order and the machine's seeds.
        machine: any Ising machine; default ``ising_backend.EmulatedChip(seed=seed)``.
        options: the fields of :class:`TaskGroupOptions`.
    """

    name = "lorr-ising"
    accelerated = True
    Options = TaskGroupOptions

    def __init__(self, seed: int = 0, machine=None, **options) -> None:
        super().__init__(**options)
        opts = self.options
        self.seed = int(seed)
        self.machine = machine_for(machine, self.seed)
        self.limits = GroupLimits(opts.groups, opts.max_robots, opts.max_options, int(self.machine.usable_spins),
                                  opts.max_gap)
        if self.limits.max_spins < opts.max_robots:
            raise ValueError(f"max_robots = {opts.max_robots} needs {opts.max_robots} spins; the machine has "
                             f"{self.limits.max_spins}")
        self.ledger = CallLedger()
        self._pinned: dict[int, int] = {}  # robot -> the task a group decision gave it, kept until opened
        #: decisions posed; groups that took the chip's choice; their cost lowered in all; the host's seconds
        self.stats = {"decisions": 0, "applied": 0, "gain": 0, "host_s": 0.0}

    def schedule(self, sim, deadline: float | None = None) -> np.ndarray:
        """This step's proposal: the matching, then the group decisions (skipped when the matching used half the
        time to ``deadline``)."""
        t0 = time.perf_counter()
        proposal, m = self.match(sim, deadline)
        call = None
        if m is not None:
            if deadline is None or time.perf_counter() < t0 + (deadline - t0) / 2:
                call = self.decide(m, sim.t)
            got = m.out >= 0
            proposal[m.robots[got]] = m.ids[m.out[got]]
        wall = time.perf_counter() - t0
        self.last_compute = ComputeReport(cpu_s=wall) if call is None else \
            replace(ComputeReport.from_ledger(call), cpu_s=wall)
        return proposal

    def keep(self, sim, proposal) -> None:
        """In place: each robot a group decision moved keeps that task while it is open and not opened."""
        tasks = sim.tasks
        for r, k in list(self._pinned.items()):
            if tasks.assigned[r] == k and not tasks.is_opened(k) and proposal[r] < 0:
                proposal[r] = k
            else:
                del self._pinned[r]

    def decide(self, m: Matched, t: int):
        """The step's group decisions on ``m`` (its ``out`` changed in place where a group takes the chip's choice);
        returns the machine's charges, ``None`` when the machine was not called."""
        t0 = time.perf_counter()
        n, slots = len(m.out), len(m.ids)
        cell_of = np.repeat(np.arange(len(m.cell_start) - 1), np.diff(m.cell_start)).astype(np.int64)
        owner = -np.ones(slots, dtype=np.int64)
        owner[m.out[m.out >= 0]] = np.flatnonzero(m.out >= 0)
        head = m.cell_start[:-1] + np.bincount(cell_of[m.out[m.out >= 0]], minlength=len(m.cell_start) - 1)
        lim = self.limits
        batch = GroupBatch(0, np.empty(lim.groups + 1, np.int64), np.empty(n, np.int64), np.empty(n + 1, np.int64),
                           np.empty(n * lim.max_options, np.int64))
        ng = select_task_groups(m, cell_of, owner, head, lim, self.seed, t, np.zeros(n, np.int8),
                                np.zeros(slots, np.int8), batch)
        self.stats["decisions"] += ng
        if ng == 0 or "task_groups" in host_rule_classes():
            self.stats["host_s"] += time.perf_counter() - t0
            return None
        batch = batch._replace(ng=ng)
        gstart, members, ostart, opt = batch.gstart, batch.members, batch.ostart, batch.opt
        width = int((ostart[gstart[1:ng + 1]] - ostart[gstart[:ng]] - np.diff(gstart[:ng + 1])).max())
        H, J = np.zeros((ng, width), np.int64), np.zeros((ng, width, width), np.int64)
        task_programs(m, cell_of, batch, self.options.penalty, self.machine.spec.coefficient_limits, H, J)
        call = CallLedger()
        with self.machine.session(call, decision="task_groups") as link:
            host = None if link.audit is None else self._host_rule(H, J, ng, time.perf_counter() - t0)
            spins, _ = link.anneal(H, J, num_reads=self.options.num_reads,
                                   seed=int(mix(self.seed, t, 0x7A5, 1)) & ((1 << 63) - 1), host=host)
        self.ledger = self.ledger + call
        choice = np.zeros(gstart[ng], dtype=np.int64)
        costs, nows = np.empty(ng, np.int64), np.empty(ng, np.int64)
        decode_task_groups(m, cell_of, batch, spins, choice, costs, nows)
        for g in np.flatnonzero((costs >= 0) & (costs <= nows - self.options.min_gain)).tolist():
            a, b = gstart[g], gstart[g + 1]
            new = opt[ostart[a:b] + choice[a:b]]
            for r, s in zip(members[a:b].tolist(), new.tolist()):
                if s != m.out[r]:
                    self._pinned[int(m.robots[r])] = int(m.ids[s])
            m.out[members[a:b]] = new
            self.stats["applied"] += 1
            self.stats["gain"] += int(nows[g] - costs[g])
        self.stats["host_s"] += time.perf_counter() - t0 - call.emulation_s
        return call

    def _host_rule(self, H, J, ng: int, host_s: float) -> tuple:
        """The host rule beside the programs in an open decision audit: the matching's answer (every spin down),
        its energies, and the host's seconds per program."""
        from ising_backend.faults.health import program_energy

        spins = -np.ones(H.shape, dtype=np.int8)
        return program_energy(H.astype(np.float64), J.astype(np.float64), spins), host_s / ng, "greedy matching"
