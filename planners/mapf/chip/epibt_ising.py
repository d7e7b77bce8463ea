"""EPIBT whose neighbourhood groups choose their operations jointly on an Ising machine (``epibt-ising``).

After :class:`~planners.mapf.epibt.plans.EPIBT`'s plan and search, each call poses up to ``groups`` decisions of
class ``lns_groups``: a robot not on its best operation and the robots in the way of its better ones (up
to ``max_robots``; robots of one group in no other), each with its operation now (option 0) and its best
others that collide with no robot outside the group (up to ``max_options``; a spin per option besides the
operation now, at most the machine's usable spins in all).  The program (:func:`group_qubo`): a robot's
operation now is all its spins down, another option one spin up; the options' costs-to-go above the
operation now as linear terms; penalties for two spins of one robot up and for each pair of options of two
robots that collide (vertex or swap at any time).
The host rule in the chip's place (``decider="host"``, or the class named by an open
:class:`ising_backend.audit.host_rule.HostRule`; no machine call): the robots in a seeded order, each its cheapest
option that collides with no one placed before (the search's own greedy).  The chip's answer is its
cheapest collision-free read, where a robot with more than one spin up keeps its operation now.  A group
takes the decided choice when it collides with no one and costs at least ``min_gain`` less than the group's
plan now; groups apply in turn, each checked against the plan as the ones before it left it.

Charges as :class:`~planners.mapf.chip.joint_executor.JointMovesPIBT` (:attr:`ledger`, :attr:`last_compute`); an
open decision audit records every program with the host rule's answer as spins of the same program.
Measurements: ``docs/design/lifelong_turning.md``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numba
import numpy as np

from ising_backend import CallLedger, integer_program
from ising_backend.audit.host_rule import host_rule_classes
from planners.compute import ComputeReport
from planners.mapf.chip.choice_qubo import read_choices, reduce_to_reference
from planners.mapf.common import GroupBatch, machine_for, mix
from planners.mapf.epibt.plans import DEADLINE_MARGIN_S, EPIBT, EPIBTOptions
from planners.mapf.epibt.search import blockers, conflict, reserve
from planners.options import option

__all__ = ["EPIBTIsing", "EPIBTIsingOptions", "select_groups", "group_qubo", "greedy_choice", "decode_choice",
           "apply_choices", "DECIDERS"]

DECIDERS = ("chip", "host")
_ROUND_SALT = 0x2D0  # a round's seed beyond the first: mix(seed, t, round, salt)


@numba.njit(cache=True, nogil=True)
def _collide(p, q) -> bool:
    """Cell sequences ``p`` and ``q`` (same times) meet in a cell or swap cells at some time."""
    for t in range(1, p.shape[0]):
        if p[t] == q[t] or (p[t] != p[t - 1] and p[t] == q[t - 1] and q[t] == p[t - 1]):
            return True
    return False


@numba.njit(cache=True, nogil=True)
def select_groups(state, res, limits, stamp, taken, out) -> int:
    """This call's groups (module docstring) into ``out = (members, gstart, ostart, opt)``: group ``g`` is
    ``members[gstart[g]:gstart[g + 1]]``, robot slot ``m``'s options ``opt[ostart[m]:ostart[m + 1]]`` (a
    candidate index, -1 its inherited operation; option 0 its operation now).  ``limits = (groups,
    max_robots, max_options, max_spins)``, ``stamp = (seed, t)``, ``taken`` (robots) all 0 on entry."""
    cells, ncand, cur, src = state.cells, state.ncand, state.cur, state.src
    n_groups, max_robots, max_options, max_spins = limits
    seed, t = stamp
    members, gstart, ostart, opt = out
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
        if src[k] == 0 or ncand[k] == 0 or taken[k]:
            continue
        a = m
        size = blockers(k, cells, src[k] if src[k] > 0 else ncand[k], res, max_robots, members[a:], taken)
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
def _path(state, q, c):
    return state.cells[q, c] if c >= 0 else state.inh[q]


@numba.njit(cache=True, nogil=True)
def _cost(state, q, c) -> int:
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
        c0 = _cost(state, members[i], opt[ostart[i]])
        for x in range(ostart[i] + 1, ostart[i + 1]):
            spread = max(spread, abs(_cost(state, members[i], opt[x]) - c0))
    amo = penalty * (spread + 1)
    pen = (amo + 1) // 2
    full = np.zeros((n, n), dtype=np.int64)
    for i in range(a, b):
        for x in range(ostart[i], ostart[i + 1]):
            full[x - base, x - base] = _cost(state, members[i], opt[x])
            px = _path(state, members[i], opt[x])
            for i2 in range(i + 1, b):
                for y in range(ostart[i2], ostart[i2 + 1]):
                    if _collide(px, _path(state, members[i2], opt[y])):
                        full[x - base, y - base] = pen
    return reduce_to_reference(full, ostart[a:b + 1] - base, np.zeros(b - a, dtype=np.int64), amo, q)


@numba.njit(cache=True, nogil=True)
def _feasible_cost(state, members, a, b, ostart, opt, choice) -> int:
    """Cost of ``choice`` (an option per robot of the group), or -1 when two chosen options collide."""
    total = 0
    for i in range(a, b):
        p = _path(state, members[i], opt[ostart[i] + choice[i - a]])
        for i2 in range(i + 1, b):
            if _collide(p, _path(state, members[i2], opt[ostart[i2] + choice[i2 - a]])):
                return -1
        total += _cost(state, members[i], opt[ostart[i] + choice[i - a]])
    return total


@numba.njit(cache=True, nogil=True)
def greedy_choice(state, members, a, b, ostart, opt, stamp, choice) -> int:
    """The host rule: robots in the order of ``mix(seed, t, g, robot)``, each its cheapest option colliding with
    none placed before; returns the cost (-1 when a robot is left without one: the group keeps its plan)."""
    seed, t, g = stamp
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
            p = _path(state, q, opt[x])
            ok = True
            for j in range(size):
                if placed[j] and _collide(p, _path(state, members[a + j], opt[ostart[a + j] + choice[j]])):
                    ok = False
                    break
            if ok and (best < 0 or _cost(state, q, opt[x]) < _cost(state, q, opt[best])):
                best = x
        if best < 0:
            return -1
        choice[i] = best - ostart[a + i]
        placed[i] = 1
        total += _cost(state, q, opt[best])
    return total


@numba.njit(cache=True, nogil=True)
def decode_choice(state, members, a, b, ostart, opt, spins, choice) -> int:
    """The chip's answer (spins as :func:`group_qubo`): the cheapest collision-free read, into ``choice``; a robot
    with no spin up, or more than one, keeps its operation now (option 0) in that read.  Its cost (-1 when no
    read is collision-free)."""
    reads = read_choices(spins, ostart[a:b + 1] - ostart[a])
    best = -1
    for rd in range(reads.shape[0]):
        e = _feasible_cost(state, members, a, b, ostart, opt, reads[rd])
        if e >= 0 and (best < 0 or e < best):
            best = e
            choice[:b - a] = reads[rd]
    return best


@numba.njit(cache=True, nogil=True)
def apply_choices(state, res, groups, choices, costs_now, min_gain=1) -> int:
    """Groups in turn take their choice (``choices[m]`` robot slot ``m``'s option; ``costs_now[g]`` -1: none)
    when it costs at least ``min_gain`` less than their plan now and collides with nothing left in the plan;
    returns how many did (``groups`` a :class:`~planners.mapf.common.GroupBatch`)."""
    cur, src = state.cur, state.src
    members, gstart, ostart, opt = groups.members, groups.gstart, groups.ostart, groups.opt
    applied = 0
    for g in range(groups.ng):
        a, b = gstart[g], gstart[g + 1]
        if costs_now[g] < 0:
            continue
        before = 0
        for i in range(a, b):
            before += _cost(state, members[i], src[members[i]])
        if costs_now[g] > before - min_gain:
            continue
        for i in range(a, b):
            reserve(res, cur[members[i]], members[i], -1)
        ok = True
        for i in range(a, b):
            if conflict(res, _path(state, members[i], opt[ostart[i] + choices[i]]), members[i]) != -1:
                ok = False
                break
            reserve(res, _path(state, members[i], opt[ostart[i] + choices[i]]), members[i], members[i])
        for i in range(a, b):
            q = members[i]
            reserve(res, _path(state, q, opt[ostart[i] + choices[i]]), q, -1)
        if ok:
            for i in range(a, b):
                q = members[i]
                src[q] = opt[ostart[i] + choices[i]]
                cur[q] = _path(state, q, src[q])
            applied += 1
        for i in range(a, b):
            reserve(res, cur[members[i]], members[i], members[i])
    return applied



@dataclass(frozen=True)
class EPIBTIsingOptions(EPIBTOptions):
    """:class:`EPIBTIsing`'s options: :class:`~planners.mapf.epibt.plans.EPIBTOptions` and its decisions'."""

    decider: str = option("chip", str, words=DECIDERS, meaning="the machine decides, or the host rule (no machine "
                          "call)")
    groups: int = option(32, int, 0, 1 << 16, meaning="decisions per round")
    max_robots: int | None = option(None, int, 2, 22, none=True, meaning="robots per group (null: the machine's "
                                    "spins // max_options, in [2, 22]: 11 on the paper's 45-spin chip)")
    max_options: int = option(4, int, 2, 8, meaning="options per robot")
    num_reads: int = option(64, int, 1, 64, meaning="reads per program")
    penalty: int = option(2, int, 1, 64, meaning="the at-most-one penalty in units of 1 + the widest gap of one "
                          "option's cost to its robot's operation now; collisions half that")
    min_gain: int = option(1, int, 1, 1000, meaning="a group takes the decided choice when it lowers the group's "
                           "cost-to-go by at least this much")
    rounds: int = option(1, int, 1, 4096, meaning="rounds of decisions per call, each on fresh groups; under a "
                         "clock they stop before the deadline on the step's charged time")


class EPIBTIsing(EPIBT):
    """EPIBT plus the joint choice of operations of neighbourhood groups (module docstring).

    Args:
        grid, seed: as :class:`~planners.mapf.epibt.plans.EPIBT`.
        machine: any Ising machine; default ``ising_backend.EmulatedChip(seed=seed)`` (not built with
            ``decider="host"``; a machine given there shapes the groups, as it would for the chip, and is not called).
        options: the fields of :class:`EPIBTIsingOptions`.  ``penalty`` 2 was chosen on RANDOM-03 and -05
            (docs/design/lifelong_turning.md).  ``rounds`` > 1 with ``lns=0`` makes the chip the search's
            annealer: each round poses fresh groups on the plan the rounds before it left; under a clock the
            rounds stop when the next, as long as the longest so far, would end past the deadline less
            :data:`~planners.mapf.epibt.plans.DEADLINE_MARGIN_S` on the step's charged time (host seconds, not
            the emulation's, plus the machine's own).
    """

    name = "epibt-ising"
    Options = EPIBTIsingOptions

    def __init__(self, grid, seed: int = 0, machine=None, **options) -> None:
        super().__init__(grid, seed=seed, **options)
        opts = self.options
        self.decider = opts.decider
        # the host rule poses the groups a given machine would (its spins), but never calls it
        shape = machine_for(machine, self.seed) if self.decider == "chip" or machine is not None else None
        self.machine = shape if self.decider == "chip" else None
        spins, nominal = (45, 45) if shape is None else (int(shape.usable_spins), int(shape.spec.n_spins))
        self.n_groups, self.max_options = opts.groups, opts.max_options
        self.max_robots = min(22, max(2, nominal // self.max_options)) if opts.max_robots is None else opts.max_robots
        self.num_reads, self.penalty = opts.num_reads, opts.penalty
        self.min_gain, self.rounds = opts.min_gain, opts.rounds
        self.max_spins = spins
        if self.max_spins < self.max_robots:
            raise ValueError(f"max_robots = {self.max_robots} needs {self.max_robots} spins; the machine has {spins}")
        self.ledger = CallLedger()
        self.last_compute = ComputeReport()
        self._last_groups = 0  # groups the latest round posed
        #: decisions so far; taken (the decided choice applied); the chip's cost below / above the host rule's;
        #: rounds run
        self.stats = {"decisions": 0, "applied": 0, "chip_better": 0, "chip_worse": 0, "host_s": 0.0, "rounds": 0}

    def _improve(self, state) -> None:
        """Up to :attr:`rounds` rounds of group decisions (class docstring), the machine's charges summed."""
        self.last_compute = ComputeReport()
        spent = CallLedger()  # this call's machine charges: its emulation is not the step's, its own time is
        longest = 0.0
        for k in range(self.rounds):
            t0 = time.perf_counter()
            if k and self.deadline is not None and t0 - spent.emulation_s + spent.chip_time_parallel_s + longest \
                    > self.deadline - DEADLINE_MARGIN_S:
                break
            call = self._round(state, k)
            self.stats["rounds"] += 1
            wall = time.perf_counter() - t0
            if call is not None:
                spent = spent + call
                self.last_compute = self.last_compute + replace(ComputeReport.from_ledger(call), cpu_s=wall)
                wall += call.chip_time_parallel_s - call.emulation_s
            longest = max(longest, wall)
            if self._last_groups == 0:  # no robot off its best operation with others in the way: none later
                break

    def _round(self, state, k: int):
        """One round of decisions on ``state`` (round ``k`` of the call: round 0 keeps the seeds of a single round);
        returns its machine charges, ``None`` when the machine was not called."""
        t0 = time.perf_counter()
        seed = self.seed if k == 0 else int(mix(self.seed, self.t, k, _ROUND_SALT) & np.uint64((1 << 62) - 1))
        r = len(state.ncand)
        members = np.empty(r, dtype=np.int64)
        gstart = np.empty(self.n_groups + 1, dtype=np.int64)
        ostart = np.empty(r + 1, dtype=np.int64)
        opt = np.empty(r * self.max_options, dtype=np.int64)
        taken = np.zeros(r, dtype=np.int8)
        ng = select_groups(state, self._res, (self.n_groups, self.max_robots, self.max_options, self.max_spins),
                           (seed, self.t), taken, (members, gstart, ostart, opt))
        self._last_groups = ng
        if ng == 0:
            return None
        batch = GroupBatch(ng, gstart, members, ostart, opt)
        m = gstart[ng]
        host = np.zeros(m, dtype=np.int64)
        host_cost = np.empty(ng, dtype=np.int64)
        th = time.perf_counter()
        for g in range(ng):
            host_cost[g] = greedy_choice(state, members, gstart[g], gstart[g + 1], ostart, opt,
                                         (seed, self.t, g), host[gstart[g]:])
        host_s = time.perf_counter() - th
        choice, cost, call = host, host_cost, None
        if self.decider == "chip" and "lns_groups" not in host_rule_classes():
            n = int((ostart[gstart[1:ng + 1]] - ostart[gstart[:ng]] - np.diff(gstart[:ng + 1])).max())
            q, H, J = np.empty((n, n), np.int64), np.zeros((ng, n), np.int64), np.zeros((ng, n, n), np.int64)
            limits = self.machine.spec.coefficient_limits
            for g in range(ng):
                k = group_qubo(state, members, gstart[g], gstart[g + 1], ostart, opt, q, self.penalty)
                integer_program(q, k, H[g, :k], J[g, :k, :k], limits)
            chip_seed = int(mix(seed, self.t, 0x1A5, 0)) & ((1 << 63) - 1)
            if n == 0:  # no robot of any group has an option besides its operation now: nothing to ask
                spins = np.zeros((ng, 1, 0), np.int8)
            else:
                call = CallLedger()
                with self.machine.session(call, decision="lns_groups") as link:
                    host_rule = None if link.audit is None else \
                        self._host_rule(H, J, batch, (host, host_cost), host_s)
                    spins, _ = link.anneal(H, J, num_reads=self.num_reads, seed=chip_seed, host=host_rule)
                self.ledger = self.ledger + call
            choice = np.zeros(m, dtype=np.int64)
            cost = np.empty(ng, dtype=np.int64)
            for g in range(ng):
                cost[g] = decode_choice(state, members, gstart[g], gstart[g + 1], ostart, opt, spins[g],
                                        choice[gstart[g]:])
            better = (cost >= 0) & ((host_cost < 0) | (cost < host_cost))
            worse = (host_cost >= 0) & ((cost < 0) | (cost > host_cost))
            self.stats["chip_better"] += int(better.sum())
            self.stats["chip_worse"] += int(worse.sum())
        self.stats["applied"] += apply_choices(state, self._res, batch, choice, cost, self.min_gain)
        self.stats["decisions"] += ng
        total = time.perf_counter() - t0
        emul = 0.0 if call is None else float(call.emulation_s)
        self.stats["host_s"] += total - emul
        return call

    def _host_rule(self, H, J, batch, greedy, host_s) -> tuple:
        """The host rule beside this step's programs in an open decision audit (class ``lns_groups``): the search's
        greedy choice ``greedy = (choice, cost)`` as spins of the same programs (a group it leaves without a choice:
        its plan now, option 0), their energies, and its seconds per program."""
        from ising_backend.faults.health import program_energy

        ng, gstart, ostart = batch.ng, batch.gstart, batch.ostart
        host, host_cost = greedy
        hs = -np.ones(H.shape, dtype=np.int8)
        for g in range(ng):
            for i in range(gstart[g], gstart[g + 1]):
                c = host[i] if host_cost[g] >= 0 else 0
                if c > 0:
                    hs[g, ostart[i] - ostart[gstart[g]] - (i - gstart[g]) + c - 1] = 1
        e_host = program_energy(H.astype(np.float64), J.astype(np.float64), hs)
        return e_host, host_s / ng, "greedy"
