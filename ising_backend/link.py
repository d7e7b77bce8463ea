"""How the planners' compiled search loops reach an Ising machine.

A compiled loop anneals through :func:`anneal_submit` with the arguments of a
:class:`MachineLink` (``link.kernel_args``, spliced where the emulator's kernel arguments
go). For the healthy emulator (:func:`~ising_backend.chip.kernel_capable`) that is the
emulator's own kernel, called in the loop, and the caller charges the returned calls and
seconds afterwards with :meth:`MachineLink.settle` (bit for bit what ``anneal_batch`` would
charge). For any other :class:`~ising_backend.machine.IsingMachine` (a faulty emulator, a
dimod sampler, a device driver) the loop calls back into ``machine.anneal_batch`` (numba's
object mode, a few microseconds per submission), which refuses, anneals, times and charges
as it always does; each call's charge is also added to the ledger the caller set in
:attr:`MachineLink.charged`. So every machine runs the same compiled search: only the anneal
step differs. A machine's exception (``ChipUnavailableError``, ``ChipProgramError``)
propagates out of the compiled loop unchanged.
"""

from __future__ import annotations

import itertools
import weakref

import numba
import numpy as np

from ._clock import clock_ns
from .anneal import anneal_kernel_timed
from .chip import kernel_capable
from .ledger import CallLedger
from .logical import LogicalIsingSolver, mix_seed, tabu_kernel
from .meter import SolverOutputError
from .models import IsingModel

__all__ = ["MachineLink", "anneal_submit", "solve_submit"]

_LINKS: "weakref.WeakValueDictionary[int, MachineLink]" = weakref.WeakValueDictionary()
_IDS = itertools.count()
_NO_MISMATCH = np.zeros((0, 0, 0))


class MachineLink:
    """One machine as seen by compiled loops (module docstring).

    A callback machine is found by its ``handle`` (baked into the kernel arguments planners keep);
    setting :attr:`charged` before a compiled call makes this link the one its handle reaches.
    Copies of a link (a pipeline deep-copied for its warm-up, or unpickled in a worker) keep the
    handle, and each reaches its own machine once it sets ``charged``.
    """

    def __init__(self, machine, handle: int | None = None, logical: bool | None = None):
        self.machine = machine
        # a logical solver (solve_stack / solve_many, reached by solve_submit) or an annealer (anneal_batch)
        self.logical = isinstance(machine, LogicalIsingSolver) if logical is None else bool(logical)
        if self.logical:  # the compiled tabu kernel, or the solver's own call (another method, faults, any solver)
            self.direct = (type(machine) is LogicalIsingSolver and machine.method == "tabu"
                           and machine.health is None)
        else:
            self.direct = kernel_capable(machine)
        self.handle = -1 if self.direct else (next(_IDS) if handle is None else int(handle))
        if self.logical:
            self.kernel_args = None
        elif self.direct:
            self.kernel_args = (-1, *self.machine.kernel_args())
        else:
            self.kernel_args = (self.handle, 1, True, -1.0, -1.0, _NO_MISMATCH, 0.0)
        self.charged = None

    @property
    def charged(self) -> CallLedger | None:
        """The ledger the running compiled call charges (a callback machine charges it per submission)."""
        return self._charged

    @charged.setter
    def charged(self, ledger: CallLedger | None) -> None:
        self._charged = ledger
        if not self.direct:
            _LINKS[self.handle] = self

    def logical_args(self, n: int) -> tuple:
        """:func:`solve_submit`'s arguments after the seed for programs of ``n`` spins on a logical solver."""
        return (-1, *self.machine.kernel_args(n)) if self.direct else (self.handle, 1, 1, 1)

    def __getstate__(self) -> dict:
        return {"machine": self.machine, "handle": self.handle, "logical": self.logical}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["machine"], None if state.get("handle", -1) < 0 else state["handle"], state.get("logical"))

    def settle(self, calls, seconds, charged: CallLedger) -> None:
        """Charge what a compiled call submitted: the emulator's kernel calls (``calls[i]`` calls,
        ``seconds[i]`` emulation seconds each) to the chip and ``charged``; nothing for a callback
        machine (each of its calls charged itself, and ``charged``, as it ran)."""
        if self.direct:
            self.machine.charge_into(calls, seconds, charged)


def _callback(handle, h, J, num_reads, seed, spins, energies) -> float:
    """One submission of a compiled loop on the linked machine (object mode): the answer copied into
    ``spins`` / ``energies``, the call's charge added to ``link.charged`` (also when it fails).
    int8 spins are checked for +-1 in compiled code after the copy (:func:`_all_spins`)."""
    link = _LINKS[handle]
    machine = link.machine
    has_last = hasattr(machine, "last_call")  # else the charge is read off the ledger, as MeteredSolver does
    before = machine.last_call if has_last else machine.ledger.snapshot()
    e = None
    try:
        if link.logical:  # energies are not used by the compiled loops of a logical solver
            if hasattr(machine, "solve_stack"):
                s = machine.solve_stack(h, J, num_reads=int(num_reads), seed=int(seed))
            else:  # any solver with solve_many(models, num_reads, seed)
                models = [IsingModel.trusted(h[b], J[b]) for b in range(h.shape[0])]
                s = np.stack([np.asarray(r.spins).reshape(int(num_reads), -1)
                              for r in machine.solve_many(models, num_reads=int(num_reads), seed=int(seed))])
        else:
            s, e = machine.anneal_batch(h, J, num_reads=int(num_reads), seed=int(seed))
    finally:  # a call that failed is charged what it spent
        if link.charged is not None:
            if not has_last:
                link.charged._add_in_place(machine.ledger.since(before))
            elif machine.last_call is not before:
                link.charged._add_in_place(machine.last_call)
    s = np.asarray(s)
    if s.shape != spins.shape or (s.dtype != np.int8 and not ((s == 1) | (s == -1)).all()):
        raise SolverOutputError(f"got shape {s.shape}, expected {spins.shape} spins in {{-1, +1}}")
    spins[...] = s
    if e is not None:
        energies[...] = e
    return 0.0


@numba.njit(cache=True)
def _all_spins(spins) -> bool:
    flat = spins.reshape(-1)
    bad = 0
    for i in range(flat.size):
        bad += (flat[i] != 1) & (flat[i] != -1)
    return bad == 0


@numba.njit(cache=True)
def anneal_submit(h, J, num_reads, seed, handle, sweeps, geometric, beta_hot, beta_cold, mismatch, flip_prob,
                  spins, energies):
    """Anneal ``h (B, n)``, ``J (B, n, n)`` into ``spins`` / ``energies`` on the linked machine
    (``handle, sweeps, ... flip_prob`` = :attr:`MachineLink.kernel_args`); returns the emulation
    seconds to charge (the emulator's kernel), 0 for a machine that charged itself."""
    if handle < 0:
        return anneal_kernel_timed(h, J, num_reads, seed, sweeps, geometric, beta_hot, beta_cold, mismatch,
                                   flip_prob, spins, energies)
    with numba.objmode(t="float64"):
        t = _callback(handle, h, J, num_reads, seed, spins, energies)
    if not _all_spins(spins):
        raise SolverOutputError("the machine returned spins other than -1 and +1")
    return t


@numba.njit(cache=True)
def solve_submit(h, J, num_reads, seed, handle, restarts, iterations, tenure, spins, energies):
    """A logical solver's ``solve_stack`` of ``h (B, n)``, ``J (B, n, n)`` into ``spins`` (``handle, restarts,
    iterations, tenure`` = :meth:`MachineLink.logical_args`): its tabu kernel in the loop, or the callback;
    returns the emulation seconds to charge (0 for a solver that charged itself)."""
    if handle < 0:
        t0 = clock_ns()
        tabu_kernel(h, J, num_reads, mix_seed(seed, h.shape[1]), restarts, iterations, tenure, spins, energies)
        return (clock_ns() - t0) * 1e-9
    with numba.objmode(t="float64"):
        t = _callback(handle, h, J, num_reads, seed, spins, energies)
    if not _all_spins(spins):
        raise SolverOutputError("the machine returned spins other than -1 and +1")
    return t
