"""Rounds of neighbourhood-group decisions (class ``lns_groups``) on a joint plan, decided on an Ising machine or by
the host rule: the component ``epibt-ising`` and ``epibt-chain-ising`` share.  Design notes:
docs/design/lifelong_turning.md#the-group-rounds.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from ising_backend import CallLedger
from ising_backend.audit.host_rule import host_rule_classes
from planners.compute import ComputeReport
from planners.mapf.chip.group_kernels import (NO_CHOICE, GroupShape, apply_choices, decode_choices, group_programs,
                                              host_choices, select_groups)
from planners.mapf.common import GroupBatch, machine_for, mix
from planners.mapf.epibt.plans import DEADLINE_MARGIN_S
from planners.options import Options, option

__all__ = ["GroupRounds", "RoundLimits", "GroupOptions", "build_rounds", "delegated", "rounds_option", "grow_option",
           "DECIDERS"]

DECIDERS = ("chip", "host")

_ROUND_SALT = 0x2D0  # a round's seed beyond the first: mix(seed, t, round, salt)


@dataclass(frozen=True)
class RoundLimits:
    """The shape and budget of a call's group decisions."""

    groups: int       # decisions per round
    max_robots: int   # robots per group
    max_options: int  # options per robot
    max_spins: int    # spins per program (the machine's usable spins)
    num_reads: int    # reads per program
    penalty: int      # the at-most-one penalty (group_qubo)
    min_gain: int     # a group takes the decided choice when it lowers its cost by this much
    rounds: int       # rounds per call
    grow: bool = False  # groups grow through their members' blockers (GroupShape)


def rounds_option(default: int):
    """The ``rounds`` option (a planner sets its own default)."""
    return option(default, int, 1, 4096, meaning="rounds of decisions per call, each on fresh groups; under a clock "
                  "they stop before the deadline on the step's charged time")


def grow_option(default: bool):
    """The ``grow`` option (a planner sets its own default)."""
    return option(default, bool, meaning="groups grow through the robots in the way of each member's first "
                  "max_options operations (a push chain's robots decided at once), not only the first robot's")


def delegated(name: str, doc: str, holder: str = "rounds_") -> property:
    """A planner's read-only view of attribute ``name`` of the component it holds as ``holder`` (default its
    :class:`GroupRounds`, ``rounds_``)."""
    return property(lambda self: getattr(getattr(self, holder), name), doc=doc)


@dataclass(frozen=True)
class GroupOptions(Options):
    """The group decisions' options, as a planner with them lists them after its own."""

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
    rounds: int = rounds_option(1)
    grow: bool = grow_option(False)


def build_rounds(machine, opts: GroupOptions, seed: int) -> "GroupRounds":
    """The :class:`GroupRounds` of a planner's options: with ``decider="chip"`` on ``machine`` (default: the emulated
    chip seeded with ``seed``); with ``"host"`` no machine is built or called, a machine given only shapes the groups
    as it would for the chip.  ``ValueError`` when ``max_robots`` exceeds the machine's spins."""
    shape = machine_for(machine, seed) if opts.decider == "chip" or machine is not None else None
    spins, nominal = (45, 45) if shape is None else (int(shape.usable_spins), int(shape.spec.n_spins))
    robots = min(22, max(2, nominal // opts.max_options)) if opts.max_robots is None else opts.max_robots
    if spins < robots:
        raise ValueError(f"max_robots = {robots} needs {robots} spins; the machine has {spins}")
    limits = RoundLimits(opts.groups, robots, opts.max_options, spins, opts.num_reads, opts.penalty, opts.min_gain,
                         opts.rounds, opts.grow)
    return GroupRounds(shape if opts.decider == "chip" else None, limits, seed)


class GroupRounds:
    """Rounds of group decisions on a joint plan (module docstring)."""

    def __init__(self, machine, limits: RoundLimits, seed: int) -> None:
        self.machine, self.limits, self.seed = machine, limits, seed
        self.ledger = CallLedger()
        self.last_compute = ComputeReport()
        self.last_groups = 0  # groups the latest round posed
        #: decisions so far; taken (the decided choice applied); the chip's cost below / above the host rule's;
        #: the rounds' host seconds (not the emulation's); rounds run
        self.stats = {"decisions": 0, "applied": 0, "chip_better": 0, "chip_worse": 0, "host_s": 0.0, "rounds": 0}

    def improve(self, state, res, t: int, deadline: float | None = None, seeds=None) -> None:
        """Up to ``limits.rounds`` rounds on ``state`` at step ``t`` (``seeds``: the robots that may start a group,
        default all), the machine's charges summed into :attr:`last_compute`."""
        self.last_compute = ComputeReport()
        seeds = np.ones(len(state.ncand), dtype=np.int8) if seeds is None else seeds
        spent = CallLedger()  # this call's machine charges: its emulation is not the step's, its own time is
        longest = 0.0
        for k in range(self.limits.rounds):
            t0 = time.perf_counter()
            if k and deadline is not None and t0 - spent.emulation_s + spent.chip_time_parallel_s + longest \
                    > deadline - DEADLINE_MARGIN_S:
                break
            call = self.round(state, res, (t, k), seeds)
            self.stats["rounds"] += 1
            wall = time.perf_counter() - t0
            if call is not None:
                spent = spent + call
                self.last_compute = self.last_compute + replace(ComputeReport.from_ledger(call), cpu_s=wall)
                wall += call.chip_time_parallel_s - call.emulation_s
            longest = max(longest, wall)
            if self.last_groups == 0:  # no robot off its best operation with others in the way: none later
                break

    def round(self, state, res, when: tuple, seeds):
        """One round of decisions on ``state`` at ``when = (t, k)`` (round ``k`` of the call: round 0 keeps the seeds of
        a single round); returns its machine charges, ``None`` when the machine was not called."""
        t, k = when
        lim = self.limits
        t0 = time.perf_counter()
        seed = self.seed if k == 0 else int(mix(self.seed, t, k, _ROUND_SALT) & np.uint64((1 << 62) - 1))
        r = len(state.ncand)
        members = np.empty(r, dtype=np.int64)
        gstart = np.empty(lim.groups + 1, dtype=np.int64)
        ostart = np.empty(r + 1, dtype=np.int64)
        opt = np.empty(r * lim.max_options, dtype=np.int64)
        taken = np.zeros(r, dtype=np.int8)
        shape = GroupShape(lim.groups, lim.max_robots, lim.max_options, lim.max_spins, lim.grow)
        ng = select_groups(state, res, shape, (seed, t), taken, GroupBatch(0, gstart, members, ostart, opt), seeds)
        self.last_groups = ng
        if ng == 0:
            return None
        batch = GroupBatch(ng, gstart, members, ostart, opt)
        m = gstart[ng]
        host = np.zeros(m, dtype=np.int64)
        host_cost = np.empty(ng, dtype=np.int64)
        th = time.perf_counter()
        host_choices(state, batch, (seed, t), host, host_cost)
        host_s = time.perf_counter() - th
        choice, cost, call = host, host_cost, None
        if self.machine is not None and "lns_groups" not in host_rule_classes():
            choice, cost, call = self._ask(state, batch, (seed, t), (host, host_cost, host_s))
        self.stats["applied"] += apply_choices(state, res, batch, choice, cost, lim.min_gain)
        self.stats["decisions"] += ng
        emul = 0.0 if call is None else float(call.emulation_s)
        self.stats["host_s"] += time.perf_counter() - t0 - emul
        return call

    def _ask(self, state, batch, stamp, greedy):
        """The machine's choices for ``batch`` (one program per group, in one call) and their costs, and the call's
        charges; the chip's answers counted against the host rule's ``greedy = (choice, cost, seconds)``."""
        ng, gstart, ostart = batch.ng, batch.gstart, batch.ostart
        seed, t = stamp
        host_cost = greedy[1]
        n = int((ostart[gstart[1:ng + 1]] - ostart[gstart[:ng]] - np.diff(gstart[:ng + 1])).max())
        H, J = np.zeros((ng, n), np.int64), np.zeros((ng, n, n), np.int64)
        group_programs(state, batch, self.limits.penalty, self.machine.spec.coefficient_limits, H, J)
        chip_seed = int(mix(seed, t, 0x1A5, 0)) & ((1 << 63) - 1)
        call = None
        if n == 0:  # no robot of any group has an option besides its operation now: nothing to ask
            spins = np.zeros((ng, 1, 0), np.int8)
        else:
            call = CallLedger()
            with self.machine.session(call, decision="lns_groups") as link:
                host_rule = None if link.audit is None else self._host_rule(H, J, batch, greedy)
                spins, _ = link.anneal(H, J, num_reads=self.limits.num_reads, seed=chip_seed, host=host_rule)
            self.ledger = self.ledger + call
        choice = np.zeros(gstart[ng], dtype=np.int64)
        cost = np.empty(ng, dtype=np.int64)
        decode_choices(state, batch, spins, choice, cost)
        better, worse = cost < host_cost, cost > host_cost  # NO_CHOICE above every cost
        self.stats["chip_better"] += int(better.sum())
        self.stats["chip_worse"] += int(worse.sum())
        return choice, cost, call

    @staticmethod
    def _host_rule(H, J, batch, greedy) -> tuple:
        """The host rule beside this step's programs in an open decision audit (class ``lns_groups``): the search's
        greedy choice ``greedy = (choice, cost, seconds)`` as spins of the same programs (a group it leaves without
        a choice: its plan now, option 0), their energies, and its seconds per program."""
        from ising_backend.faults.health import program_energy

        ng, gstart, ostart = batch.ng, batch.gstart, batch.ostart
        host, host_cost, host_s = greedy
        hs = -np.ones(H.shape, dtype=np.int8)
        for g in range(ng):
            for i in range(gstart[g], gstart[g + 1]):
                c = host[i] if host_cost[g] != NO_CHOICE else 0
                if c > 0:
                    hs[g, ostart[i] - ostart[gstart[g]] - (i - gstart[g]) + c - 1] = 1
        e_host = program_energy(H.astype(np.float64), J.astype(np.float64), hs)
        return e_host, host_s / ng, "greedy"
