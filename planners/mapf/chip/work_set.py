"""Who stays at work, decided on an Ising machine (decision class ``work_set``; issue 57, item 3):
``epibt-chain-work``.

Contract: as :class:`~planners.mapf.epibt.chain_planner.ChainEPIBT`; its host rule keeps the ``active`` share of the
team of least way at work (:mod:`planners.mapf.guides.focus`), and the machine then decides which of those stay.
Two robots at work meet when one's way falls through the other's cell and back (``head_on``) or both fall through
one cell (``shared``); the robots that meet are the spins of programs (:func:`conflict_pairs`,
:func:`pack_programs`: the meeting graph's components, packed into the machine's usable spins, a larger one split in
breadth-first order and its cut pairs counted) minimising ``-sum u_i x_i + sum c_ij x_i x_j``: keeping robot ``i``
is worth ``u_i`` (1 plus how far its way is below the last robot the host rule kept, at most its pairs' sum plus 1,
which leaves the optimum as it is), keeping a meeting pair costs its weight.  The machine's read of least energy
decides; a robot it takes off keeps its own cell as its goal this step (waits unless pushed).  ``decider="host"``
is the twin: the host rule's set (every spin up), no call, the plans of ``epibt-chain`` with the same options.
Charges: :attr:`WorkSet.ledger`, the planner's ``last_compute``; the planner's clock moves by the emulation's
seconds less the machine's own.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ising_backend import CallLedger, integer_program
from ising_backend.audit.host_rule import host_rule_classes
from planners.compute import ComputeReport
from planners.mapf.chip.group_rounds import delegated
from planners.mapf.common import machine_for, mix
from planners.mapf.epibt.chain_planner import ChainEPIBT, ChainOptions
from planners.options import Options, option

__all__ = ["WorkChainEPIBT", "WorkOptions", "WorkSet", "conflict_pairs", "pack_programs", "keep_values"]

_SALT = 0x3B7  # the machine's seed of a step: mix(seed, t, salt, 0)


@dataclass(frozen=True)
class WorkOptions(Options):
    """The work-set decision's options, as a planner with them lists them after its own."""

    decider: str = option("chip", str, words=("chip", "host"), meaning="the machine decides who of the host rule's "
                          "robots at work stay, or the host rule keeps them all (no machine call)")
    head_on: int = option(8, int, 0, 1000, meaning="the cost of keeping two robots at work whose ways run through "
                          "each other's cells (moves of way)")
    shared: int = option(4, int, 0, 1000, meaning="the cost of keeping two robots at work whose ways fall through "
                         "one cell")
    num_reads: int = option(16, int, 1, 64, meaning="reads per program")


def conflict_pairs(nbr, pc, down, head_on: int, shared: int):
    """``(a, b, c)`` (``a < b`` indices into ``pc``, their weight) of the robots at compact cells ``pc`` whose moves
    ``down`` (``(m, 4)`` bool: robot ``k``'s way falls by moving to ``nbr[pc[k], d]``) meet: ``head_on`` when each
    falls through the other's cell, ``shared`` for each cell both fall through; a pair's weights summed, pairs
    of weight 0 left out, sorted by ``(a, b)``."""
    m = len(pc)
    cells = nbr[pc]
    occ = np.full(nbr.shape[0], -1, dtype=np.int64)
    occ[pc] = np.arange(m)
    a, d = np.nonzero(down & (cells >= 0))
    to = cells[a, d]
    b = occ[to]
    on = b >= 0
    ha, hb = a[on], b[on]
    back = ((cells[hb] == pc[ha][:, None]) & down[hb]).any(axis=1)
    ha, hb = ha[back], hb[back]
    keep = ha < hb  # each head-on pair found from both ends: once
    firsts, seconds, weights = [ha[keep]], [hb[keep]], [np.full(int(keep.sum()), head_on, dtype=np.int64)]
    order = np.argsort(to, kind="stable")
    st, sa = to[order], a[order]
    for k in range(1, 4):  # at most four robots fall through one cell
        same = st[:-k] == st[k:] if len(st) > k else np.zeros(0, dtype=bool)
        x, y = sa[:-k][same], sa[k:][same]
        firsts.append(np.minimum(x, y))
        seconds.append(np.maximum(x, y))
        weights.append(np.full(len(x), shared, dtype=np.int64))
    fa, fb, fw = np.concatenate(firsts), np.concatenate(seconds), np.concatenate(weights)
    key, inv = np.unique(fa * max(m, 1) + fb, return_inverse=True)
    w = np.bincount(inv.ravel(), weights=fw, minlength=len(key)).astype(np.int64)
    nz = w > 0
    return key[nz] // max(m, 1), key[nz] % max(m, 1), w[nz]


def pack_programs(m: int, a, b, spins: int):
    """The programs of the meeting graph on ``m`` robots with edges ``(a, b)``: lists of robot indices, each a
    component's (robots in no pair belong to none) or, for a component of more than ``spins`` robots, a piece of
    ``spins`` of it in breadth-first order; components packed whole into programs of at most ``spins`` in order of
    their least robot.  Returns ``(programs, cut)``, ``cut`` the pairs split across programs."""
    adj: list[list[int]] = [[] for _ in range(m)]
    for x, y in zip(a.tolist(), b.tolist()):
        adj[x].append(y)
        adj[y].append(x)
    seen = np.zeros(m, dtype=bool)
    pieces: list[list[int]] = []
    for s in sorted(set(a.tolist()) | set(b.tolist())):
        if seen[s]:
            continue
        seen[s] = True
        comp, head = [s], 0
        while head < len(comp):
            for v in sorted(adj[comp[head]]):
                if not seen[v]:
                    seen[v] = True
                    comp.append(v)
            head += 1
        pieces += [comp[i:i + spins] for i in range(0, len(comp), spins)]
    programs: list[list[int]] = []
    for p in pieces:
        if programs and len(programs[-1]) + len(p) <= spins:
            programs[-1] = programs[-1] + p
        else:
            programs.append(list(p))
    where = np.full(m, -1, dtype=np.int64)
    for g, p in enumerate(programs):
        where[p] = g
    cut = int((where[a] != where[b]).sum()) if len(a) else 0
    return programs, cut


def keep_values(way, a, b, c):
    """``u``: keeping each robot at work is worth 1 plus how far its ``way`` is below the largest, at most the sum
    of its pairs' weights ``c`` plus 1 (beyond that no pair can take it off: the optimum is unchanged)."""
    top = int(way.max()) if len(way) else 0
    load = np.bincount(a, weights=c, minlength=len(way)) + np.bincount(b, weights=c, minlength=len(way))
    return np.minimum(1 + top - way, load.astype(np.int64) + 1).astype(np.int64)


class WorkSet:
    """The work-set decisions of a planner (module docstring): on ``machine``, or by the host rule (``None``), in
    programs of at most ``spins``."""

    def __init__(self, machine, opts: WorkOptions, seed: int, spins: int = 45) -> None:
        self.machine, self.opts, self.seed, self.spins = machine, opts, seed, int(spins)
        self.ledger = CallLedger()
        self.last_compute = ComputeReport()
        #: programs posed; robots taken off by the decisions; meeting pairs; pairs cut between programs; the
        #: machine's answer of lower / higher energy than the host rule's (every spin up); host seconds
        self.stats = {"decisions": 0, "taken_off": 0, "pairs": 0, "cut": 0, "chip_better": 0, "chip_worse": 0,
                      "host_s": 0.0}

    def decide(self, way, pairs, t: int) -> np.ndarray:
        """Which of ``len(way)`` robots at work stay (bool), their meeting ``pairs = (a, b, c)``, at step ``t``."""
        t0 = time.perf_counter()
        self.last_compute = ComputeReport()
        a, b, c = pairs
        m = len(way)
        stay = np.ones(m, dtype=bool)
        self.stats["pairs"] += len(a)
        if len(a) == 0 or self.machine is None or "work_set" in host_rule_classes():
            self.stats["host_s"] += time.perf_counter() - t0
            return stay
        programs, cut = pack_programs(m, a, b, self.spins)
        self.stats["cut"] += cut
        u = keep_values(way, a, b, c)
        ng, n = len(programs), max(len(p) for p in programs)
        slot = np.full(m, -1, dtype=np.int64)
        prog = np.full(m, -1, dtype=np.int64)
        for g, p in enumerate(programs):
            slot[p], prog[p] = np.arange(len(p)), g
        q = np.zeros((ng, n, n), dtype=np.int64)
        for g, p in enumerate(programs):
            q[g, np.arange(len(p)), np.arange(len(p))] = -u[p]
        inside = prog[a] == prog[b]
        ia, ib = slot[a[inside]], slot[b[inside]]
        q[prog[a[inside]], np.minimum(ia, ib), np.maximum(ia, ib)] += c[inside]
        H, J = np.zeros((ng, n), np.int64), np.zeros((ng, n, n), np.int64)
        limits = self.machine.spec.coefficient_limits
        for g, p in enumerate(programs):
            integer_program(q[g].astype(np.float64), len(p), H[g, :len(p)], J[g, :len(p), :len(p)], limits)
        call = CallLedger()
        seed = int(mix(self.seed, t, _SALT, 0)) & ((1 << 63) - 1)
        with self.machine.session(call, decision="work_set") as link:
            host = None if link.audit is None else self._host_rule(H, J, programs)
            spins, _ = link.anneal(H, J, num_reads=self.opts.num_reads, seed=seed, host=host)
        self.ledger = self.ledger + call
        x = (np.asarray(spins) > 0).astype(np.int64)  # (ng, reads, n)
        energy = np.einsum("gri,gij,grj->gr", x, q, x)  # q upper-triangular, linear terms on its diagonal
        host_e = q.sum(axis=(1, 2))  # every robot's spin up (padding slots hold no terms)
        best = energy.argmin(axis=1)
        for g, p in enumerate(programs):
            stay[p] = x[g, best[g], :len(p)] > 0
        chip_e = energy[np.arange(ng), best]
        self.stats["chip_better"] += int((chip_e < host_e).sum())
        self.stats["chip_worse"] += int((chip_e > host_e).sum())
        self.stats["decisions"] += ng
        self.stats["taken_off"] += int((~stay).sum())
        wall = time.perf_counter() - t0
        self.last_compute = ComputeReport.from_ledger(call)
        self.stats["host_s"] += wall - float(call.emulation_s)
        return stay

    @staticmethod
    def _host_rule(H, J, programs) -> tuple:
        """The host rule beside the programs in an open decision audit: every robot's spin up (padding down), its
        energies, and its seconds per program (none: the rank that made the set is the rule, run before any
        program)."""
        from ising_backend.faults.health import program_energy

        hs = -np.ones(H.shape, dtype=np.int8)
        for g, p in enumerate(programs):
            hs[g, :len(p)] = 1
        return program_energy(H.astype(np.float64), J.astype(np.float64), hs), 0.0, "rank"


@dataclass(frozen=True)
class WorkChainOptions(WorkOptions, ChainOptions):
    """:class:`WorkChainEPIBT`'s options: :class:`~planners.mapf.epibt.chain_planner.ChainOptions`, then the work
    set's (:class:`WorkOptions`)."""


class WorkChainEPIBT(ChainEPIBT):
    """EPIBT by push chains whose robots at work an Ising machine chooses (module docstring).

    Args:
        grid, seed: as :class:`~planners.mapf.epibt.chain_planner.ChainEPIBT`.
        machine: any Ising machine; default ``ising_backend.EmulatedChip(seed=seed)`` (not built with
            ``decider="host"``; a machine given there sets the programs' size, as it would for the chip, and is not
            called).
        options: the fields of :class:`WorkChainOptions`.
    """

    name = "epibt-chain-work"
    Options = WorkChainOptions
    decides_work = True

    def __init__(self, grid, seed: int = 0, machine=None, **options) -> None:
        super().__init__(grid, seed=seed, **options)
        opts = self.options
        shape = machine_for(machine, self.seed) if opts.decider == "chip" or machine is not None else None
        self.work = WorkSet(shape if opts.decider == "chip" else None, opts, self.seed,
                            45 if shape is None else int(shape.usable_spins))
        self.machine = self.work.machine

    ledger = delegated("ledger", "Every machine call's charges.", "work")
    last_compute = delegated("last_compute", "The last call's machine charges.", "work")
    steer_compute = delegated("last_compute", "The machine's charges of this call's steer: the work set's.", "work")
    stats = delegated("stats", "The work-set decisions' counts (WorkSet).", "work")

    def keep_at_work(self, pos, goals, pc, rows, way) -> np.ndarray:
        """``goals`` with the robots the machine takes off the host rule's set given their own cells."""
        at = np.flatnonzero(goals != pos)
        if len(at) == 0:
            self.work.last_compute = ComputeReport()
            return goals
        gc = self.cid[goals[at]]
        cells = self.nbr[pc[at]]
        here = self.field_distance(pc[at], gc, rows[at])
        there = np.stack([self.field_distance(np.maximum(cells[:, d], 0), gc, rows[at]) for d in range(4)], axis=1)
        down = (cells >= 0) & (there < here[:, None])
        o = self.options
        pairs = conflict_pairs(self.nbr, pc[at], down, o.head_on, o.shared)
        stay = self.work.decide(way[at], pairs, self.t)
        out = goals.copy()
        out[at[~stay]] = pos[at[~stay]]
        return out
