"""The machine step of ``pibt-ising``: PIBT's congested groups re-choose their next cells on an Ising machine.

:class:`JointMovesStep` runs decision class ``joint-moves`` (:mod:`planners.mapf.chip.joint_moves`) after PIBT's
pass, one submission per step; ``accept`` says whose answer a group keeps. Measured: fewer tasks than plain
``pibt`` on every instance tried, so it stays a negative result and a harness; ``pibt`` is the default executor.
Design notes: docs/design/lifelong_turning.md#the-joint-moves-executor.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from ising_backend import CallLedger, integer_program
from ising_backend.audit.host_rule import host_rule_classes
from planners.compute import ComputeReport
from planners.mapf.common import GroupBatch, machine_for, mix
from planners.mapf.chip.joint_moves import (
    CELL, CONFLICT, MAX_OPTIONS, NOT_ONE_HOT, HostStep, build_qubo, claims_to_actions, decode_reads, group_options,
    group_spread, objective, program_batch, robot_options, select_groups, solve_exact,
)
from planners.options import Options, option

__all__ = ["JointMovesStep", "JointMovesOptions", "ACCEPT"]

ACCEPT = ("better", "chip", "host")



@dataclass(frozen=True)
class JointMovesOptions(Options):
    """The joint moves' decisions' options (the planner ``pibt-ising`` turns lanes off by default: the option costs
    and the QUBO's weights were tuned on plain distances)."""

    max_robots: int = option(11, int, 1, 45, meaning="robots per group")
    max_spins: int | None = option(None, int, MAX_OPTIONS, 1 << 16, none=True, meaning="options per group (null: the "
                                   "machine's usable spins, also the upper limit)")
    levels: int = option(3, int, 1, 7, meaning="priority weight tiers inside a group (1 = every robot weighs 1)")
    push: int = option(2, int, 0, 2, meaning="a forward claim whose robot ahead does not move forward counts push / "
                       "2 of its cost (0: as a wait; 2: in full, PIBT's own view; 2 the least harmful of 0, 1, 2)")
    penalty: int | None = option(10, int, 1, 1 << 20, none=True, meaning="one-hot and conflict penalty of the QUBO "
                                 "(10 measured against 4, 7 and null = 1 + the group's widest spread of one robot's "
                                 "option costs); infeasible reads are repaired")
    num_reads: int = option(32, int, 1, 64, meaning="reads per group program (32: 4 batches of the 8 cores)")
    accept: str = option("better", str, words=ACCEPT, meaning="whose answer a group takes (module docstring)")
    audit: bool = option(False, bool, meaning="record every decision with its exact optimum (slow: benchmarks, tests)")


class JointMovesStep:
    """The chip's joint next moves for PIBT's congested groups (module docstring).

    Args:
        opts: :class:`JointMovesOptions`.
        machine: any Ising machine (``session``, ``spec``, ``usable_spins``); default
            ``ising_backend.EmulatedChip(seed=seed)``.
        seed: the machine's seed; ``cells``: the map's free cells.
    """

    Options = JointMovesOptions

    def __init__(self, opts: JointMovesOptions, machine, seed: int, cells: int) -> None:
        self.machine = machine_for(machine, seed)
        usable = int(self.machine.usable_spins)
        if opts.max_spins is not None and opts.max_spins > usable:
            raise ValueError(f"max_spins = {opts.max_spins} must be an integer in [{MAX_OPTIONS}, {usable}] (the "
                             f"machine's usable spins)")
        self.max_robots = opts.max_robots
        self.max_spins = usable if opts.max_spins is None else opts.max_spins
        self.levels, self.push, self.penalty = opts.levels, opts.push, opts.penalty
        self.num_reads, self.accept = opts.num_reads, opts.accept
        self.audit: list[dict[str, int]] | None = [] if opts.audit else None
        self.ledger = CallLedger()
        self.last_compute = ComputeReport()
        self.decisions = 0
        self.changed = 0  # groups whose chip answer was applied and differs from the host rule's
        self.repaired = np.zeros(2, dtype=np.int64)  # reads not one-hot, reads with a conflict repaired
        self.host_s = 0.0  # host seconds of the decision class (group building, mapping, decode; no emulation)
        self._claim = np.full(cells, -1, dtype=np.int64)
        #: a list to collect every group as ``(pos, ostart, opt, host)`` instead of deciding (benchmarks)
        self.sample = None

    def groups(self, decider, pc, orient, gc, rows, order, nxt, act):
        """This step's groups (a :class:`~planners.mapf.common.GroupBatch`, kernels of
        :mod:`planners.mapf.chip.joint_moves`; compact cells) and ``decider``'s (PIBT's) choice per slot."""
        r = len(pc)
        nbr, occ_now = decider.site.nbr, decider.occ_now
        cand = np.empty((r, MAX_OPTIONS), dtype=np.int64)
        cost = np.empty((r, MAX_OPTIONS), dtype=np.int64)
        robot_options(decider.source.move_grid, (decider.source.fields.fields, rows), (pc, orient, gc), cand, cost)
        gid = np.empty(r, dtype=np.int64)
        members = np.empty(r, dtype=np.int64)
        gstart = np.empty(r + 1, dtype=np.int64)
        step = HostStep(pc, orient, nxt, act)
        ng = select_groups(nbr, step, (cand, cost), order, (self.max_robots, self.max_spins), occ_now,
                           (gid, members, gstart))
        rank = np.empty(r, dtype=np.int64)
        rank[order] = np.arange(r)
        m = gstart[ng]
        ostart = np.zeros(m + 1, dtype=np.int64)
        opt = np.empty((m * MAX_OPTIONS, 5), dtype=np.int64)
        host = np.empty(m, dtype=np.int64)
        if ng:
            group_options(nbr, step, (cand, cost), rank, (gid, members, gstart), ng,
                          (self.levels, self.push), (self._claim, occ_now), (ostart, opt, host))
        return GroupBatch(ng, gstart, members, ostart, opt), host

    def refine(self, decider, pc, orient, gc, rows, order, nxt, act) -> None:
        """The step's groups decided on the machine, ``decider``'s claims ``nxt`` and actions ``act`` changed in
        place where a group takes the chip's answer (module docstring)."""
        t0 = time.perf_counter()
        self.last_compute = ComputeReport()
        if "joint_moves" in host_rule_classes():  # the ablation: PIBT's answer stands
            return
        t = decider.prio.t
        batch, host = self.groups(decider, pc, orient, gc, rows, order, nxt, act)
        ng, gstart, members, ostart, opt = batch.ng, batch.gstart, batch.members, batch.ostart, batch.opt
        if self.sample is not None:  # a benchmark collecting decisions on the host rule's trajectory
            for g in range(ng):
                a, b = gstart[g], gstart[g + 1]
                self.sample.append((pc[members[a:b]].copy(), ostart[a:b + 1] - ostart[a],
                                    opt[ostart[a]:ostart[b]].copy(), host[a:b].copy()))
            return
        if ng == 0:
            self.host_s += time.perf_counter() - t0
            return
        sizes, q, H, J = program_batch(ng, gstart, ostart)
        for g in range(ng):
            a, b = gstart[g], gstart[g + 1]
            pen = 1 + group_spread(a, b, ostart, opt) if self.penalty is None else self.penalty
            k = build_qubo(pc, members, a, b, ostart, opt, pen, pen, q)
            integer_program(q, k, H[g, :k], J[g, :k, :k], self.machine.spec.coefficient_limits)
        seed = int(mix(decider.prio.seed, t, 0x15, 0)) & ((1 << 63) - 1)
        t1 = time.perf_counter()
        call = CallLedger()
        with self.machine.session(call, decision="joint_moves") as link:
            host_rule = None if link.audit is None else self._host_rule(H, J, batch, host, decider.kernel_s / len(pc))
            spins, energies = link.anneal(H, J, num_reads=self.num_reads, seed=seed, host=host_rule)
        t2 = time.perf_counter()
        self.ledger = self.ledger + call
        stats = np.zeros(2, dtype=np.int64)
        choice = np.empty(self.max_robots, dtype=np.int64)
        hostc = np.empty(self.max_robots, dtype=np.int64)
        exact = np.empty(self.max_robots, dtype=np.int64)
        audit_s = 0.0
        for g in range(ng):
            a, b = gstart[g], gstart[g + 1]
            before = stats.copy()
            e_chip = decode_reads(pc, members, a, b, ostart, opt, host, spins[g], choice, stats)
            hostc[:b - a] = host[a:b]
            e_host = objective(a, b, ostart, opt, hostc)
            use = self.accept == "chip" or (self.accept == "better" and e_chip < e_host)
            if use and (choice[:b - a] != host[a:b]).any():
                self.changed += 1
                nxt[members[a:b]] = opt[ostart[a:b] + choice[:b - a], CELL]
            if self.audit is not None:
                ta = time.perf_counter()
                e_opt = solve_exact(pc, members, a, b, ostart, opt, exact)
                self.audit.append({"t": t, "robots": int(b - a), "spins": int(sizes[g]), "host": int(e_host),
                                   "chip": int(e_chip), "exact": int(e_opt),
                                   "not_one_hot": int(stats[NOT_ONE_HOT] - before[NOT_ONE_HOT]),
                                   "conflict": int(stats[CONFLICT] - before[CONFLICT])})
                audit_s += time.perf_counter() - ta
        self.decisions += ng
        self.repaired += stats
        claims_to_actions(decider.site.nbr, pc, orient, nxt, act, decider.occ_now)
        t3 = time.perf_counter() - audit_s
        emul = float(call.emulation_s)
        self.host_s += (t3 - t0) - emul
        self.last_compute = replace(ComputeReport.from_ledger(call), cpu_s=t3 - t0)
        self.last_times = (t1 - t0, t2 - t1, t3 - t2, emul, ng)  # build, anneal, decode + apply, emulation, groups

    @staticmethod
    def _host_rule(H, J, batch, host, robot_s: float) -> tuple:
        """The host rule beside this step's programs in an open decision audit (class ``joint_moves``): PIBT's
        cells as spins of the same programs, their energies, and its seconds (this step's PIBT kernel time per
        robot, ``robot_s``, times a group's robots)."""
        from ising_backend.faults.health import program_energy

        gstart, ostart = batch.gstart, batch.ostart
        hs = -np.ones(H.shape, dtype=np.int8)
        secs = np.empty(batch.ng)
        for g in range(batch.ng):
            a, b = gstart[g], gstart[g + 1]
            hs[g, ostart[a:b] - ostart[a] + host[a:b]] = 1
            secs[g] = robot_s * (b - a)
        return program_energy(H.astype(np.float64), J.astype(np.float64), hs), float(secs.mean()), "pibt"
