"""The logical Ising backend (paper section 5.2, "Execution: logical Ising").

Contract: :class:`LogicalIsingSolver` obeys the chip's **spin budget** but not its coefficient range (for
layers whose coefficients do not fit, such as the paper's one-hot tour); each program solve (one read) is
one *projected* chip call (``logical_calls``).  Methods ``"tabu"`` (default: a compiled tabu search,
deterministic under the seed) and ``"dwave-tabu"``; with ``health=`` every call goes through the chip's
fault-tolerant dispatch.  Design notes: docs/design/emulated_chip.md (tabu), docs/design/faults.md.
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Sequence

import dimod
import numpy as np

from ising_backend.machines.base import MachineBase
from ising_backend.machines.link import MachineSession
from ising_backend.machines.tabu import mix_seed, tabu_kernel
from ising_backend.machines.programs import ChipProgramError, sample_bqm, stack_programs
from ising_backend.faults.health import dispatch, program_energy
from ising_backend.ledger import CallLedger
from ising_backend.models import IsingModel
from ising_backend.spec import ChipSpec

__all__ = ["LogicalIsingSolver", "LogicalResult", "LOGICAL_METHODS", "tabu_kernel"]

LOGICAL_METHODS = ("tabu", "dwave-tabu")


def _writable(a) -> np.ndarray:
    """``a`` as a C-contiguous, writable float64 array (a copy only when it is not one): the tabu kernel is
    compiled for one array type, and a read-only array would be another specialization."""
    return np.require(a, dtype=np.float64, requirements=("C", "W"))


@dataclass(frozen=True)
class LogicalResult:
    """Reads of one logical program: ``spins (reads, n) int8``, ``energies (reads,)`` (offset included)."""

    spins: np.ndarray
    energies: np.ndarray

    @property
    def best_index(self) -> int:
        return int(np.argmin(self.energies))

    @property
    def best_spins(self) -> np.ndarray:
        return self.spins[self.best_index]

    @property
    def best_energy(self) -> float:
        return float(self.energies[self.best_index])


class LogicalIsingSolver(MachineBase):
    """Spin-budget-limited Ising solver whose calls are projected as chip calls: a :class:`MachineBase` whose
    programs keep the spin budget, not the coefficient range, and whose reads are charged as logical calls.

    Args:
        budget: spin budget (default: ``spec.n_spins``, 45).
        spec: chip spec whose time/energy numbers price each projected call.
        method: ``"tabu"`` (compiled, default) or ``"dwave-tabu"``.
        restarts, iterations: ``"tabu"`` effort per read (``iterations=None``: ``50 * n``).
        tenure: ``"tabu"`` tenure (``None``: ``max(1, min(max_tenure, 2n // 3))``).
        max_tenure: cap of the default tenure (default 10: one-hot permutation models, the
            tour layer's, search better with a cap near 10-12; docs/design/emulated_chip.md).
        timeout_ms: ``"dwave-tabu"`` timeout per read.
        seed: seed of the generator that seeds calls made without their own seed.
        ledger: the :class:`CallLedger` to charge (default a new one; a pipeline passes its
            chip's ledger so physical and projected calls add up in one place).
        health: a faulty chip's :class:`~ising_backend.faults.health.HealthMonitor` (``chip.health``):
            the projected calls then run on its healthy cores (module docstring).
    """

    _logical = True
    _emulates_faults = True  # runs on a faulty chip's healthy cores (``health``)

    def __init__(self, budget: int | None = None, spec: ChipSpec | None = None, method: str = "tabu",
                 restarts: int = 4, iterations: int | None = None, tenure: int | None = None, timeout_ms: int = 5, seed: int | None = None,
                 max_tenure: int = 10, ledger: CallLedger | None = None, health=None):
        super().__init__(spec, seed)
        self.budget = self.spec.n_spins if budget is None else int(budget)
        if self.budget < 1:
            raise ValueError(f"budget = {budget!r} must be >= 1")
        if method not in LOGICAL_METHODS:
            raise ValueError(f"method = {method!r} not in {LOGICAL_METHODS}")
        if restarts < 1:
            raise ValueError(f"restarts = {restarts!r} must be >= 1")
        if iterations is not None and iterations < 1:
            raise ValueError(f"iterations = {iterations!r} must be >= 1")
        self.method = method
        self.restarts = int(restarts)
        self.iterations = iterations
        self.timeout_ms = int(timeout_ms)
        if tenure is not None and tenure < 1:
            raise ValueError(f"tenure = {tenure!r} must be >= 1")
        self.tenure = tenure
        if int(max_tenure) != max_tenure or max_tenure < 1:
            raise ValueError(f"max_tenure = {max_tenure!r} must be an integer >= 1")
        self.max_tenure = int(max_tenure)
        self.ledger = CallLedger() if ledger is None else ledger
        self.health = health
        self._rounds = CallLedger()  # a faulty chip's dispatch rounds of the running call, added up in order

    # ----------------------------------------------------------------- dimod
    @property
    def properties(self) -> dict:
        return {"num_spins": self.budget, "h_range": [-np.inf, np.inf], "j_range": [-np.inf, np.inf],
                "method": self.method, "projected_call_time_s": self.spec.solve_time_s,
                "projected_call_energy_j": self.spec.energy_per_call_j}

    def sample(self, bqm: dimod.BinaryQuadraticModel, num_reads: int = 1, seed: int | None = None,
               **kwargs) -> dimod.SampleSet:
        """Sample a BQM within the spin budget (any real coefficients; exact conversion to SPIN)."""
        self.remove_unknown_kwargs(**kwargs)
        return sample_bqm(self, bqm, num_reads, seed)

    # ------------------------------------------------------------------ core
    def check_program(self, h, J) -> tuple[np.ndarray, np.ndarray]:
        """The stack (``h (B, n)``, ``J (B, n, n)`` float64) within the spin budget with finite coefficients,
        or a :class:`ChipProgramError` naming the program, the coefficient or the budget."""
        h = np.asarray(h, dtype=np.float64)
        J = np.asarray(J, dtype=np.float64)
        if h.ndim == 1:
            h, J = h[None], J[None]
        if h.ndim != 2 or J.shape != (h.shape[0], h.shape[1], h.shape[1]):
            raise ChipProgramError(f"h must be (B, n) and J (B, n, n); got {h.shape} and {J.shape}")
        n = h.shape[1]
        if n > self.budget:
            raise ChipProgramError(f"program has {n} spins; the logical solver's spin budget is {self.budget}: "
                                   "use spin-budget branching (ising_backend.branch)")
        for arr, name in ((h, "h"), (J, "J")):
            bad = ~np.isfinite(arr)
            if bad.any():
                idx = tuple(int(v) for v in np.argwhere(bad)[0])
                raise ChipProgramError(f"{name}{list(idx[1:])} = {arr[idx]} in program {idx[0]} is not finite")
        return _writable(h), _writable(J)

    _checked = check_program

    def _anneal(self, h, J, num_reads, seed, t0):
        """The base's :meth:`~MachineBase.anneal_batch` (real coefficients allowed; ``B * num_reads`` logical
        calls; energies without offsets) runs this: tabu or dwave-tabu reads, a faulty chip's dispatch
        rounds charged as they run (then the call is charged already)."""
        with self._metering(t0):
            spins, energies = self._run(h, J, num_reads, seed)
        return spins, energies, self.health is not None

    @contextmanager
    def _metering(self, t0: float | None = None):
        """With ``health``: the call's dispatch rounds, summed into :attr:`last_call` (also on error); each
        round is charged the seconds since the call's start (``t0``, default now) or the round before."""
        if self.health is None:
            yield
            return
        self._rounds = CallLedger()
        self._mark = time.perf_counter() if t0 is None else t0
        try:
            yield
        finally:
            self._charge_round(0, 0.0, 0, 0)  # the seconds after the last round: no call, the solver's time
            self._mark = None
            self.last_call = self._rounds

    def _charge_round(self, calls, seconds, retries, probe):
        now = time.perf_counter()
        self._rounds._add_in_place(self.ledger.record_logical(calls, self.spec, now - self._mark,
                                                              cores=len(self.health.healthy), retries=retries))
        self._mark = now

    def _run(self, h, J, num_reads, seed):
        if self.health is not None and h.shape[0] and h.shape[1]:
            return dispatch(self.health, h, J, num_reads, seed, self._run_cores, self._charge_round,
                            what="logical solver")
        return self._solve(h, J, num_reads, seed)

    def _run_cores(self, h, J, reads, seed, cores, raw):
        """:meth:`_solve` with read ``k`` on core ``cores[k]``: a read whose core has stuck spins among
        the program's spins searches with them held at their values (by a field outweighing every
        coefficient), as the chip anneals them; energies are the program's."""
        clamp = self.health.faults.clamp if raw else self.health.clamp
        M, n = h.shape
        c = clamp[np.asarray(cores)][:, :n].astype(np.float64)
        if not c.any():
            return self._solve(h, J, reads, seed)
        big = 2.0 * (np.abs(h).sum(axis=1) + np.abs(J).sum(axis=(1, 2))) + 1.0
        hr = np.repeat(h, reads, axis=0)
        Jr = np.ascontiguousarray(np.repeat(J, reads, axis=0))
        spins, _ = self._solve(np.ascontiguousarray(hr - np.repeat(big, reads)[:, None] * c), Jr, 1, seed)
        energies = program_energy(hr, Jr, spins[:, 0])
        return spins.reshape(M, reads, n), energies.reshape(M, reads)

    def _solve(self, h, J, num_reads, seed):
        B, n = h.shape
        spins = np.empty((B, num_reads, n), dtype=np.int8)
        energies = np.zeros((B, num_reads))
        if B and n:
            if self.method == "tabu":
                iters = self.iterations if self.iterations is not None else 50 * n
                tabu_kernel(h, J, num_reads, np.uint64(seed), self.restarts, int(iters), self._tenure(n),
                            spins, energies)
            else:
                self._dwave(h, J, num_reads, seed, spins, energies)
        return spins, energies

    def _tenure(self, n: int) -> int:
        return self.tenure if self.tenure is not None else max(1, min(self.max_tenure, (2 * n) // 3))

    def _dwave(self, h, J, num_reads, seed, spins, energies):
        from dwave.samplers import TabuSampler

        sampler = TabuSampler()
        n = h.shape[1]
        ss = np.random.default_rng(seed).integers(0, 2**31 - 1, size=h.shape[0])
        for b in range(h.shape[0]):
            bqm = IsingModel(h[b], J[b]).to_bqm()
            res = sampler.sample(bqm, num_reads=num_reads, timeout=self.timeout_ms, seed=int(ss[b]))
            spins[b] = res.record.sample[:, [res.variables.index(v) for v in range(n)]]
            energies[b] = res.record.energy

    def solve(self, model: IsingModel, num_reads: int = 1, seed: int | None = None) -> LogicalResult:
        """Solve one model: ``num_reads`` reads, each one projected chip call."""
        return self.solve_many([model], num_reads=num_reads, seed=seed)[0]

    def solve_many(self, models: Sequence[IsingModel], num_reads: int = 1,
                   seed: int | None = None) -> list[LogicalResult]:
        """Solve several models issued together (counted as one parallel dispatch)."""
        if not models:
            return []
        for k, m in enumerate(models):
            if m.n > self.budget:
                raise ChipProgramError(f"model {k} has {m.n} spins; the logical solver's spin budget is "
                                       f"{self.budget}: use spin-budget branching (ising_backend.branch)")
        if int(num_reads) != num_reads or num_reads < 1:
            raise ValueError(f"num_reads = {num_reads!r} must be a positive integer")
        num_reads = int(num_reads)
        seed = self._draw_seed(seed)
        t0 = time.perf_counter()
        out: list[LogicalResult | None] = [None] * len(models)
        # group by size (no padding: padded spins would waste tabu moves)
        sizes = sorted({m.n for m in models})
        with self._metering():
            for size in sizes:
                idx = [k for k, m in enumerate(models) if m.n == size]
                h, J = stack_programs([models[k] for k in idx], size)
                spins, energies = self._run(h, J, num_reads, int(mix_seed(np.uint64(seed), size)))
                for row, k in enumerate(idx):
                    out[k] = LogicalResult(spins[row], energies[row] + models[k].offset)
        if self.health is None:
            calls = sum(1 for m in models if m.n) * num_reads  # programs without spins are not solved
            self.last_call = self.ledger.record_logical(calls, self.spec, time.perf_counter() - t0)
        return out  # type: ignore[return-value]


    def kernel_args(self, n: int) -> tuple:
        """``(restarts, iterations, tenure)``: this solver's arguments of :func:`tabu_kernel` for
        ``n``-spin programs (method ``"tabu"``), for compiled planners that call the kernel in their
        own loops with :func:`mix_seed` sub-seeds, as :meth:`solve_stack` does; they charge the
        calls with :meth:`charge`."""
        if self.health is not None:
            raise RuntimeError("kernel_args() bypasses the fault-tolerant dispatch of a faulty chip's cores; "
                               "use solve_stack")
        iters = self.iterations if self.iterations is not None else 50 * n
        return int(self.restarts), int(iters), int(self._tenure(n))

    @property
    def usable_spins(self) -> int:
        """Spins a program may use: the spin budget (the healthy spins of a faulty chip's cores, if fewer)."""
        return self.budget if self.health is None else min(self.budget, self.health.usable_spins)

    def session(self, ledger: CallLedger, decision: str = "unlabelled"):
        """A logical :class:`~ising_backend.machines.link.MachineSession` charging ``ledger``: compiled loops run the
        tabu kernel themselves (method ``"tabu"``, no fault model, this very class), else call back
        into :meth:`solve_stack`."""
        direct = type(self) is LogicalIsingSolver and self.method == "tabu" and self.health is None
        return MachineSession(self, ledger, self.kernel_args if direct else None, logical=True, decision=decision)

    def charge(self, calls, seconds) -> list:
        """Charge submissions made through :meth:`kernel_args`: ``calls[i]`` logical calls and
        ``seconds[i]`` emulation seconds each, in order, as :meth:`solve_stack` charges one."""
        out = self.ledger.record_each(calls, seconds, self.spec, logical=True)
        if out:
            self.last_call = out[-1]
        return out

    def charge_into(self, calls, seconds, into: CallLedger) -> None:
        """:meth:`charge`, each submission's ledger added in order to ``into`` (the caller's ledger)
        without a ledger object per submission: the same totals, bit for bit."""
        last = self.ledger.record_into(calls, seconds, self.spec, into, logical=True)
        if last is not None:
            self.last_call = last

    def solve_stack(self, h, J, num_reads: int = 1, seed: int | None = None) -> np.ndarray:
        """:meth:`solve_many` of ``B`` same-size models given as arrays (``h (B, n)``, ``J (n, n)``
        shared or ``(B, n, n)``): the same sub-seed, spins and charge, without model objects.

        Returns ``spins (B, num_reads, n)`` int8.
        """
        h = _writable(h)
        B, n = h.shape
        if n > self.budget:
            raise ChipProgramError(f"programs have {n} spins; the logical solver's spin budget is "
                                   f"{self.budget}: use spin-budget branching (ising_backend.branch)")
        if int(num_reads) != num_reads or num_reads < 1:
            raise ValueError(f"num_reads = {num_reads!r} must be a positive integer")
        num_reads = int(num_reads)
        if not B:
            return np.empty((0, num_reads, n), dtype=np.int8)
        J = np.asarray(J, dtype=np.float64)
        if J.ndim == 2:
            J = np.broadcast_to(J, (B, n, n))
        J = _writable(J)  # a broadcast of one program is read-only
        seed = self._draw_seed(seed)
        t0 = time.perf_counter()
        with self._metering():
            spins, _ = self._run(h, J, num_reads, int(mix_seed(np.uint64(seed), n)))
        if self.health is None:
            self.last_call = self.ledger.record_logical(B * num_reads if n else 0, self.spec, time.perf_counter() - t0)
        return spins
