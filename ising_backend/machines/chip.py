"""The emulated CMOS Ising chip (paper sections 2.2, 3 and 6.1).

Contract: :class:`EmulatedChip` is a :class:`~ising_backend.machines.base.MachineBase` (so a ``dimod.Sampler``)
with :meth:`EmulatedChip.anneal_batch`.  It refuses a program that does not fit its ``spec`` with a
:class:`ChipProgramError` naming the coefficient, its value and the limit (never clips or rescales) and
charges every call to its ``ledger``; with a fault model it probes its cores at bring-up and dispatches
through :mod:`ising_backend.faults.health`.  Design notes: docs/design/emulated_chip.md, docs/design/faults.md.
"""

from __future__ import annotations

import time
import numpy as np

from ising_backend.machines.anneal import NO_CLAMP, NO_CORES, anneal_kernel
from ising_backend.machines.base import MachineBase
from ising_backend.faults.model import FaultMap
from ising_backend.faults.health import HealthMonitor, dispatch
from ising_backend.ledger import CallLedger
from ising_backend.machines.link import MachineSession
from ising_backend.machines.programs import (MAX_READS, ChipProgramError, check_call_seed, check_num_reads, check_program,  # noqa: F401
                       programs_fit, sample_bqm, seeded_rng, stack_programs)
from ising_backend.spec import ChipSpec

__all__ = ["EmulatedChip", "ChipProgramError", "check_program", "stack_programs", "kernel_capable", "programs_fit"]


def kernel_capable(chip) -> bool:
    """Whether ``chip`` is an :class:`EmulatedChip` whose annealing is its own, so a compiled planner
    loop may call its kernel (:meth:`EmulatedChip.kernel_args`) and charge it
    (:meth:`EmulatedChip.charge`); subclasses that override ``anneal_batch`` (e.g. to inject faults),
    chips with a fault model (their calls need the fault-tolerant dispatch) and other solvers go
    through ``anneal_batch``."""
    return (isinstance(chip, EmulatedChip) and type(chip).anneal_batch is EmulatedChip.anneal_batch
            and type(chip)._anneal is EmulatedChip._anneal and chip.health is None)



def _mismatch_matrices(spec: ChipSpec) -> np.ndarray:
    if spec.coupling_mismatch == 0.0:
        return np.zeros((0, 0, 0))
    rng = np.random.default_rng(spec.seed)
    N = spec.n_spins
    out = np.empty((spec.n_cores, N, N))
    for c in range(spec.n_cores):
        g = np.triu(rng.standard_normal((N, N)), 1)
        out[c] = 1.0 + spec.coupling_mismatch * (g + g.T)
    return out


class EmulatedChip(MachineBase):
    """An emulated multi-core CMOS Ising chip (a :class:`~ising_backend.machines.base.MachineBase` whose anneal is
    the compiled kernel of :mod:`ising_backend.machines.anneal`).

    Args:
        spec: hardware limits, accounting numbers, emulation knobs and fault model.
        seed: seed of the sampling randomness.  Calls without their own ``seed``
            draw one from this generator, so a chip built with the same seed
            replays the same sequence of calls identically.
        probe: with a fault model on, run the bring-up health probe (charged to
            :attr:`ledger` as ``probe_calls``, to no planning call).  ``False`` gives
            a raw faulty chip: detectable failures are still re-dispatched, but dead
            cores answering garbage and stuck spins go unnoticed.

    Example:
        >>> chip = EmulatedChip(seed=1)
        >>> sampleset = chip.sample_ising({0: 1, 1: -1}, {(0, 1): -2}, num_reads=4)
        >>> float(sampleset.first.energy)
        -2.0
    """

    _native = True
    _emulates_faults = True

    def __init__(self, spec: ChipSpec | None = None, seed: int | None = None, probe: bool = True):
        super().__init__(spec, seed)
        self._kernel = None  # the session's kernel record, once worked out
        self._mismatch = _mismatch_matrices(self.spec)
        #: the fault-tolerant driver's view of the cores (``None`` without a fault model)
        self.health: HealthMonitor | None = None
        if self.spec.faulty:
            self.faults = FaultMap.from_spec(self.spec)
            self._clamp = self.faults.clamp if self.faults.clamp.any() else np.zeros((0, 0), dtype=np.int8)
            self.health = HealthMonitor(self.spec, self.faults, self._mismatch)
            if probe:
                self.health.probe(self._run_cores, self._charge_probe)

    def _anneal(self, hf, Jf, num_reads, seed, t0):
        """The kernel on a checked stack; on a faulty chip the fault-tolerant dispatch, which charges
        each round itself."""
        B, n = hf.shape
        if self.health is not None and B and n:
            return (*self._dispatch(hf, Jf, num_reads, seed, t0), True)
        spins = np.empty((B, num_reads, n), dtype=np.int8)
        energies = np.empty((B, num_reads), dtype=np.float64)
        if B:
            hot, cold = (-1.0, -1.0) if self.spec.beta_range is None else self.spec.beta_range
            anneal_kernel(hf, Jf, num_reads, np.uint64(seed), self.spec.sweeps, self.spec.schedule == "geometric",
                          hot, cold, self._mismatch, float(self.spec.readout_flip_prob), (NO_CORES, NO_CLAMP),
                          (spins, energies))
        return spins, energies, False

    @property
    def usable_spins(self) -> int:
        """Spins a program may use without touching a stuck spin the health probe found
        (``spec.n_spins`` without faults)."""
        return self.spec.n_spins if self.health is None else self.health.usable_spins

    def session(self, ledger: CallLedger, decision: str = "unlabelled"):
        """A :class:`~ising_backend.machines.link.MachineSession` charging ``ledger``: compiled loops run this
        chip's kernel themselves when it is healthy and its own (:func:`kernel_capable`), else they
        call back into :meth:`anneal_batch`."""
        kernel = self._kernel
        if kernel is None:  # the spec and the mismatch are fixed at construction: worked out once
            kernel = self._kernel = self.kernel_args() if kernel_capable(self) else ()
        return MachineSession(self, ledger, kernel or None, decision=decision)

    def _dispatch(self, hf, Jf, num_reads, seed, t0):
        """The anneal on a faulty chip: :func:`ising_backend.faults.health.dispatch`, each round charged
        the seconds since the last (the first from the call's start: the check and the driver's own
        bookkeeping are the machine's time too)."""
        total = CallLedger()  # the rounds added up in order, as they are charged
        mark = [t0]

        def charge(calls, seconds, retries, probe):
            now = time.perf_counter()
            total._add_in_place(self.ledger.record_physical(calls, self.spec, now - mark[0],
                                                            cores=len(self.health.healthy), retries=retries))
            mark[0] = now

        try:
            return dispatch(self.health, hf, Jf, num_reads, seed, self._run_cores, charge)
        finally:
            charge(0, 0.0, 0, 0)  # the driver's seconds after the last round: no call, the machine's time
            self.last_call = total

    def _run_cores(self, h, J, reads, seed, cores, raw):
        """The annealing kernel with each read's core given (``raw``: physical placement, for the probe)."""
        M, n = h.shape
        spins = np.empty((M, reads, n), dtype=np.int8)
        energies = np.empty((M, reads), dtype=np.float64)
        hot, cold = (-1.0, -1.0) if self.spec.beta_range is None else self.spec.beta_range
        clamp = self._clamp if raw or not self._clamp.size else self.health.clamp
        mismatch = self._mismatch if raw else self.health.mismatch
        anneal_kernel(np.ascontiguousarray(h), np.ascontiguousarray(J), reads, np.uint64(seed), self.spec.sweeps,
                      self.spec.schedule == "geometric", hot, cold, mismatch, float(self.spec.readout_flip_prob),
                      (np.asarray(cores, dtype=np.int64), clamp), (spins, energies))
        return spins, energies

    def _charge_probe(self, calls, seconds, retries, probe):
        self.ledger.record_physical(calls, self.spec, seconds, cores=self.spec.n_cores, retries=retries,
                                    probe_calls=probe)

    def kernel_args(self) -> tuple:
        """``(sweeps, geometric, beta_hot, beta_cold, mismatch, flip_prob)``: this chip's arguments of
        :func:`~ising_backend.machines.anneal.anneal_kernel` after the seed.

        For compiled planners that anneal chip-legal programs inside their own loops with the
        very kernel, seeds and padding :meth:`anneal_batch` would use; they charge the calls
        with :meth:`charge`.
        """
        if self.health is not None:
            raise RuntimeError("kernel_args() bypasses the fault-tolerant dispatch of a chip with a fault model; "
                               "use anneal_batch")
        hot, cold = (-1.0, -1.0) if self.spec.beta_range is None else self.spec.beta_range
        return (int(self.spec.sweeps), self.spec.schedule == "geometric", float(hot), float(cold), self._mismatch,
                float(self.spec.readout_flip_prob))

    def charge(self, calls, seconds) -> list[CallLedger]:
        """Charge submissions made through :meth:`kernel_args`: ``calls[i]`` physical calls and
        ``seconds[i]`` emulation seconds each, in order, exactly as :meth:`anneal_batch` charges one
        submission; returns each submission's ledger (the last is :attr:`last_call`)."""
        out = self.ledger.record_each(calls, seconds, self.spec)
        if out:
            self.last_call = out[-1]
        return out

    def charge_into(self, calls, seconds, into: CallLedger) -> None:
        """:meth:`charge`, each submission's ledger added in order to ``into`` (the caller's ledger)
        without a ledger object per submission: the same totals, bit for bit."""
        last = self.ledger.record_into(calls, seconds, self.spec, into)
        if last is not None:
            self.last_call = last
