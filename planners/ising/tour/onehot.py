"""The one-hot and max-cut programs of the clustered Ising tour (paper 5.2): the tour's solver component.

``OneHotSolver(config, chip, solver)``: :meth:`solve_path` solves one open-path subproblem
(cluster order, local TSP, refinement patch) in one compiled call (:func:`.engine.solve_order`:
spin-budget branching, the logical solver or, for ``backend="chip-onehot"``, quantized programs on
the chip); :meth:`sample` draws the reads of one max-cut program (the clustering's splits).  Every
call is charged to the solve's ledger.
"""

from __future__ import annotations

import numpy as np

from ising_backend import (
    QUANTIZE_RULE_IDS, IsingModel, LogicalIsingSolver, add_counts, as_logical_solver, quantize,
)
from ising_backend.mapping.branching import branch_stack, frozen_spins
from planners.ising.tour.cluster import TourFailure, _Run
from planners.ising.tour.engine import TOO_MANY_BITS, UNQUANTIZABLE, OrderOptions, solve_order
from planners.ising.tour.kernels import expand_branches

__all__ = ["OneHotSolver"]


class OneHotSolver:
    """The logical solver and the chip as the clustered tour uses them (module docstring)."""

    def __init__(self, config, chip, solver=None):
        self.config = config
        self.spec = chip.spec
        self.budget = int(self.spec.n_spins)
        self.solver = as_logical_solver(solver) if solver is not None else LogicalIsingSolver(
            spec=self.spec, ledger=chip.ledger, health=chip.health, **config.solver_options)
        self.chip = chip  # the compiled subproblem solve reaches one of them through a session per call

    def sample(self, h, J, off, run: _Run) -> np.ndarray:
        """Bits ``(m, n)`` uint8 of every read of every branch of one program issue (logical Ising
        ``h``, ``J``, ``off``: the max-cut splits of the clustering) on the logical solver, or quantized
        on the chip for ``backend="chip-onehot"``; models above the spin budget are branched (``2^k``
        programs)."""
        cfg = self.config
        n = h.shape[0]
        if n > self.budget:
            k = n - self.budget
            if k > cfg.max_branch_bits:
                raise TourFailure(f"a {n}-spin program needs {k} frozen spins > max_branch_bits = {cfg.max_branch_bits}")
            frozen = frozen_spins(h, J, k)
        else:
            frozen = np.zeros(0, dtype=np.int64)
        free, hb, Jb, offs = branch_stack(h, J, float(off), frozen)
        seed = int(run.rng.integers(0, 2**63 - 1))
        physical = cfg.backend != "logical"
        if not physical and isinstance(run.solver.solver, LogicalIsingSolver):
            spins = run.solver.solve_stack(hb, Jb, num_reads=cfg.num_reads, seed=seed)
        else:
            programs = [IsingModel.trusted(hb[m], Jb.copy(), float(offs[m])) for m in range(len(hb))]
            if physical:  # quantized by chip_quantize, on the chip
                hr, jr = self.spec.h_range, self.spec.j_range
                progs = [quantize(m, cfg.chip_quantize, hr, jr) for m in programs]
                out = [sp for sp, _e in run.chip.anneal_models(progs, num_reads=cfg.num_reads, seed=seed)]
            else:
                out = [r.spins for r in run.solver.solve_many(programs, num_reads=cfg.num_reads, seed=seed)]
            spins = np.stack([np.asarray(sp).reshape(cfg.num_reads, -1) for sp in out])
        return expand_branches(spins, free, frozen, n)

    def solve_path(self, d, entry, ex, run: _Run, kind: str):
        """Best valid order of an open-path one-hot QUBO, or ``None`` after retries, in one compiled
        call (:func:`.engine.solve_order`: spin-budget branching, the logical solver or, for
        ``backend="chip-onehot"``, the chip), charged to the machine attempt by attempt."""
        cfg = self.config
        s = d.shape[0]
        physical = cfg.backend != "logical"
        width = min(s * s, self.budget)
        with (self.chip if physical else self.solver).session(run.charged, decision="tour_order") as link:
            Lh, Lj = (float(v) for v in self.spec.coefficient_limits)
            options = OrderOptions(margin_factor=cfg.penalty_factor, max_retries=cfg.max_retries,
                                   num_reads=cfg.num_reads, budget=self.budget, max_bits=cfg.max_branch_bits,
                                   rule=QUANTIZE_RULE_IDS[cfg.chip_quantize], Lh=Lh, Lj=Lj)
            out = solve_order(
                run.rng, np.ascontiguousarray(d, dtype=np.float64), np.ascontiguousarray(entry, dtype=np.float64),
                np.ascontiguousarray(ex, dtype=np.float64), options,
                None if physical else link.args_for(width), link.args if physical else None)
            link.settle(out.calls, out.emu)
        st = out.stats
        if out.status == TOO_MANY_BITS:
            raise TourFailure(f"a {s * s}-spin program needs {int(st.programs)} frozen spins > max_branch_bits = "
                              f"{cfg.max_branch_bits}")
        if out.status == UNQUANTIZABLE:
            raise TourFailure("a one-hot program could not be quantized: a coefficient is not finite")
        # the one choice: each solved model is its win
        add_counts(run.stats["mapping"]["tour"][cfg.choices[0]], programs=int(st.programs), reads=int(st.reads),
                   valid=int(st.valid_reads), wins=int(st.valid_subproblems))
        add_counts(run.stats, valid_programs=int(st.valid_programs), subproblems=int(st.subproblems),
                   valid_subproblems=int(st.valid_subproblems))
        run.stats["retries"] += int(st.retries)
        if st.unsolved:
            run.stats["unsolved"][kind] += 1
            return None
        return [int(i) for i in out.order]
