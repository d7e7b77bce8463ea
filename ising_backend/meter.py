"""Metering: the one way a planner charges a solver call to its own compute report.

Contract: :class:`MeteredSolver` wraps a solver (anything with ``spec``, ``ledger`` and ``anneal_batch``)
for one planning call, forwards the calls, checks that every answer is a ``(programs, reads, spins)``
array of +-1 (else :class:`SolverOutputError`) and adds exactly what each call charged to
:attr:`MeteredSolver.charged`, also what a call spent before a
:class:`~ising_backend.faults.health.ChipUnavailableError`.  Design notes: docs/design/machine_link.md.
"""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np

from ising_backend.audit.record import active_audit
from ising_backend.audit.host_rule import host_answer, host_rule_classes
from ising_backend.faults.health import ChipUnavailableError, SolverOutputError
from ising_backend.ledger import CallLedger

__all__ = ["MeteredSolver", "SolverOutputError"]


class MeteredSolver:
    """A solver seen through one planning call (see the module docstring)."""

    def __init__(self, solver, charged: CallLedger | None = None, decision: str = "unlabelled"):
        self.solver = solver
        self.decision = decision  # the decision class its calls are recorded under while an audit is open
        self.spec = getattr(solver, "spec", None)
        self.budget = getattr(solver, "budget", None if self.spec is None else self.spec.n_spins)
        self.charged = CallLedger() if charged is None else charged

    @property
    def usable_spins(self) -> int:
        """The wrapped machine's usable spins (around the stuck spins a faulty chip's probe found)."""
        return int(self.solver.usable_spins)

    def _charge(self, before) -> CallLedger:
        last = getattr(self.solver, "last_call", None)
        # the call's own charge adds up exactly; a difference of running float totals would not
        charge = last if last is not None else self.solver.ledger.since(before)
        self.charged._add_in_place(charge)
        return charge

    def _audit(self, h, J, spins, energies, charge, logical: bool) -> None:
        audit = active_audit()
        if audit is not None:
            audit.record(self.decision, h, J, spins, energies, charge, logical=logical, spec=self.spec)

    @contextmanager
    def _charged_if_unavailable(self, before):
        try:
            yield
        except ChipUnavailableError:
            self._charge(before)
            raise

    def anneal_batch(self, h, J, num_reads: int = 1, seed: int | None = None):
        """``solver.anneal_batch`` with the answer checked and its charge metered."""
        if self.decision in host_rule_classes():  # an ablation: the host rule answers, nothing is charged
            return host_answer(h, J, num_reads)
        before = None if hasattr(self.solver, "last_call") else self.solver.ledger.snapshot()
        with self._charged_if_unavailable(before):
            spins, energies = self.solver.anneal_batch(h, J, num_reads=num_reads, seed=seed)
        charge = self._charge(before)
        spins = np.asarray(spins)
        want = (np.shape(h)[0], num_reads, np.shape(h)[1]) if np.ndim(h) == 2 else (num_reads, np.shape(h)[0])
        if spins.shape != want or not ((spins == 1) | (spins == -1)).all():
            raise SolverOutputError(f"got shape {spins.shape}, expected {want} spins in {{-1, +1}}")
        self._audit(h, J, spins, energies, charge, logical=False)
        return spins, energies

    def solve_many(self, models, num_reads: int = 1, seed: int | None = None):
        """``solver.solve_many`` (logical solvers) with the answers checked and the charge metered."""
        if self.decision in host_rule_classes():
            from ising_backend.machines.logical import LogicalResult
            from ising_backend.machines.programs import stack_programs

            out = []
            for m in models:
                h, J = stack_programs([m])
                spins, energies = host_answer(h, J, num_reads)
                out.append(LogicalResult(spins[0, :, :m.n], energies[0] + m.offset))
            return out
        before = None if hasattr(self.solver, "last_call") else self.solver.ledger.snapshot()
        with self._charged_if_unavailable(before):
            out = self.solver.solve_many(models, num_reads=num_reads, seed=seed)
        if models:
            charge = self._charge(before)
        for m, r in zip(models, out):
            s = np.asarray(r.spins)
            if s.shape != (num_reads, m.n) or not ((s == 1) | (s == -1)).all():
                raise SolverOutputError(f"got shape {s.shape}, expected {(num_reads, m.n)} spins in {{-1, +1}}")
        if models and active_audit() is not None:
            from ising_backend.machines.programs import stack_programs

            h, J = stack_programs(models)
            spins = np.zeros((len(models), num_reads, h.shape[1]), dtype=np.int8)
            for b, r in enumerate(out):
                spins[b, :, : models[b].n] = np.asarray(r.spins).reshape(num_reads, -1)
            self._audit(h, J, spins, None, charge, logical=True)
        return out

    def solve_stack(self, h, J, num_reads: int = 1, seed: int | None = None):
        """``solver.solve_stack`` (:class:`LogicalIsingSolver`) with the answer checked and metered."""
        if self.decision in host_rule_classes():  # (host_answer takes a J shared by the B programs too)
            return host_answer(h, J, num_reads)[0]
        with self._charged_if_unavailable(None):
            spins = self.solver.solve_stack(h, J, num_reads=num_reads, seed=seed)
        charge = self._charge(None)
        want = (np.shape(h)[0], num_reads, np.shape(h)[1])
        if spins.shape != want or not ((spins == 1) | (spins == -1)).all():
            raise SolverOutputError(f"got shape {spins.shape}, expected {want} spins in {{-1, +1}}")
        self._audit(h, np.broadcast_to(J, (np.shape(h)[0],) + np.shape(J)[-2:]), spins, None, charge, logical=True)
        return spins

    def anneal_models(self, models, num_reads: int = 1, seed: int | None = None):
        """Chip-legal models in one batch: ``[(spins (reads, n_b), energies + offset)]``."""
        from ising_backend.machines.programs import stack_programs

        h, J = stack_programs(models)
        spins, energies = self.anneal_batch(h, J, num_reads=num_reads, seed=seed)
        return [(spins[b, :, : m.n], energies[b] + m.offset) for b, m in enumerate(models)]
