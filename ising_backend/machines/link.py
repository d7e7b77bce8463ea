"""How the planners' compiled search loops reach an Ising machine: one session per compiled call.

Contract: ``with machine.session(ledger) as link:`` opens a :class:`MachineSession`; compiled code anneals
through :func:`anneal_submit` (or :func:`solve_submit`, a logical solver) with ``link.args``, an opaque
record.  The healthy emulator and the logical solver's tabu method run their kernel in the loop and
:meth:`MachineSession.settle` charges what they returned; any other machine is called back and charges as
it always does.  A machine's exception propagates unchanged.  Design notes: docs/design/machine_link.md.
"""

from __future__ import annotations

import itertools
from typing import NamedTuple

import numba
import numpy as np

from ising_backend._clock import clock_ns
from ising_backend.machines.anneal import NO_CLAMP, NO_CORES, anneal_kernel
from ising_backend.audit.record import active_audit
from ising_backend.audit.host_rule import host_answer, host_rule_classes
from ising_backend.ledger import CallLedger
from ising_backend.machines.tabu import mix_seed, tabu_kernel
from ising_backend.faults.health import SolverOutputError

__all__ = ["MachineSession", "AnnealArgs", "SolverArgs", "anneal_submit", "solve_submit", "via_callback"]


class AnnealArgs(NamedTuple):
    """An annealer session's record for compiled loops (:attr:`MachineSession.args`): the emulator's kernel
    arguments after the seed (``EmulatedChip.kernel_args``), or a callback handle."""

    handle: int  # -1: the loop runs the emulator's kernel; else the session's callback handle
    sweeps: int
    geometric: bool  # the schedule
    beta_hot: float  # -1: the kernel's default range
    beta_cold: float
    mismatch: np.ndarray  # the coupling mismatch
    flip_prob: float  # readout flips


class SolverArgs(NamedTuple):
    """A logical solver's session record for programs of one size (:meth:`MachineSession.args_for`)."""

    handle: int  # -1: the loop runs the tabu kernel; else the session's callback handle
    restarts: int
    iterations: int
    tenure: int

_SESSIONS: dict[int, "MachineSession"] = {}
_IDS = itertools.count()
_NO_MISMATCH = np.zeros((0, 0, 0))


class MachineSession:
    """One compiled call's way to one machine (module docstring); made by ``machine.session(ledger)``.

    ``kernel``: the machine's kernel arguments after the seed when the loop may run its kernel
    itself (``machine.kernel_args()``; for a logical solver a function of the program size), or
    ``None`` for a machine reached by the callback.  ``ledger`` is charged what ran.  ``decision``
    names the decision class of what the session submits; while an :class:`~ising_backend.audit.record.Audit`
    is open every session goes through the callback and each submission is recorded under it.
    """

    __slots__ = ("machine", "ledger", "logical", "direct", "handle", "_kernel", "args", "decision", "audit", "host")

    def __init__(self, machine, ledger: CallLedger, kernel=None, logical: bool = False, decision: str = "unlabelled"):
        if not isinstance(ledger, CallLedger):
            raise TypeError(f"ledger = {ledger!r} must be an ising_backend.CallLedger")
        self.audit = active_audit()
        self.decision = decision
        self.host = decision in host_rule_classes()  # an ablation: the host rule answers (host_rule.py)
        if self.audit is not None or self.host:  # the machine's own call (same kernel and seeds), or the host rule
            kernel = None
        self.machine = machine
        self.ledger = ledger
        self.logical = bool(logical)
        self.direct = kernel is not None
        self.handle = -1 if self.direct else next(_IDS)
        self._kernel = kernel
        if self.logical:
            self.args = None
        elif self.direct:
            self.args = AnnealArgs(-1, *kernel)
        else:
            self.args = AnnealArgs(self.handle, 1, True, -1.0, -1.0, _NO_MISMATCH, 0.0)

    def args_for(self, n: int) -> SolverArgs:
        """A logical solver's record for programs of ``n`` spins (:func:`solve_submit`)."""
        if not self.logical:
            raise TypeError("args_for(n) is a logical solver's record; an annealer's is .args")
        return SolverArgs(-1, *self._kernel(n)) if self.direct else SolverArgs(self.handle, 1, 1, 1)

    def __enter__(self) -> "MachineSession":
        if not self.direct:
            _SESSIONS[self.handle] = self
        return self

    def __exit__(self, *exc) -> None:
        _SESSIONS.pop(self.handle, None)

    def anneal(self, h, J, num_reads: int, seed: int, host: tuple | None = None):
        """One submission from Python (the MAPF planners' group programs): ``(spins, energies)`` of the machine's
        ``anneal_batch``, or under the host-rule ablation of this session's decision class the host rule's answer
        (no call, nothing charged); charged to the session's ledger (also when it fails) and recorded in an open
        audit, beside ``host`` (the class's own host rule: ``(energies, seconds per program, name)``) when given."""
        return self._submit(h, J, num_reads, seed, host)

    def _submit(self, h, J, num_reads, seed, host=None):
        if self.host:  # the host rule's answer: no machine call, nothing charged, nothing audited as the chip's
            return host_answer(h, J, int(num_reads))
        machine = self.machine
        before = machine.last_call
        e = None
        try:
            if self.logical:  # energies are not used by the compiled loops of a logical solver
                s = machine.solve_stack(h, J, num_reads=int(num_reads), seed=int(seed))
            else:
                s, e = machine.anneal_batch(h, J, num_reads=int(num_reads), seed=int(seed))
        finally:  # a call that failed is charged what it spent
            if machine.last_call is not before:
                self.ledger._add_in_place(machine.last_call)
        s = np.asarray(s)
        if self.audit is not None:
            self.audit.record(self.decision, h, J, s, e, machine.last_call, logical=self.logical, host=host,
                              spec=machine.spec)
        return s, e

    def settle(self, calls, seconds, into: CallLedger | None = None) -> None:
        """Charge what the compiled call submitted through the machine's kernel (``calls[i]`` calls,
        ``seconds[i]`` emulation seconds each, in order) to the machine and to ``into`` (default the
        session's ledger); nothing for a callback machine (each call charged itself as it ran)."""
        if self.direct:
            self.machine.charge_into(calls, seconds, self.ledger if into is None else into)


@numba.njit(cache=True)
def via_callback(machine) -> bool:
    """Whether an anneal record reaches its machine by the callback (its checks and packing rule are
    the machine's own) rather than the emulator's kernel."""
    return machine.handle >= 0


def _callback(handle, h, J, num_reads, seed, spins, energies) -> float:
    """One submission of a compiled loop on the linked machine (object mode): the answer copied into
    ``spins`` / ``energies``, the call's charge added to the session's ledger (also when it fails).
    int8 spins are checked for +-1 in compiled code after the copy (:func:`_all_spins`)."""
    link = _SESSIONS.get(handle)
    if link is None:
        raise RuntimeError("a machine session's record was used outside its `with machine.session(ledger) as link:` "
                           "block")
    s, e = link._submit(h, J, num_reads, seed)
    if link.host:  # the host rule's answer (no machine call)
        spins[...] = s
        if energies.shape == e.shape:
            energies[...] = e
        return 0.0
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
def _answered(handle, h, J, num_reads, seed, spins, energies):
    """A machine behind the callback answers (object mode); its spins checked for +-1 in compiled code."""
    with numba.objmode(t="float64"):
        t = _callback(handle, h, J, num_reads, seed, spins, energies)
    if not _all_spins(spins):
        raise SolverOutputError("the machine returned spins other than -1 and +1")
    return t


@numba.njit(cache=True)
def anneal_submit(h, J, num_reads, seed, machine, spins, energies):
    """Anneal ``h (B, n)``, ``J (B, n, n)`` into ``spins`` / ``energies`` on the session's machine
    (``machine`` = :attr:`MachineSession.args`); returns the emulation seconds to charge (the
    emulator's kernel), 0 for a machine that charged itself."""
    if machine.handle < 0:
        t0 = clock_ns()  # the emulator's own kernel: its wall seconds are what the caller charges
        anneal_kernel(h, J, num_reads, seed, machine.sweeps, machine.geometric, machine.beta_hot, machine.beta_cold,
                      machine.mismatch, machine.flip_prob, (NO_CORES, NO_CLAMP), (spins, energies))
        return (clock_ns() - t0) * 1e-9
    return _answered(machine.handle, h, J, num_reads, seed, spins, energies)


@numba.njit(cache=True)
def solve_submit(h, J, num_reads, seed, solver, spins, energies):
    """A logical solver's ``solve_stack`` of ``h (B, n)``, ``J (B, n, n)`` into ``spins`` (``solver`` =
    :meth:`MachineSession.args_for`): its tabu kernel in the loop, or the callback; returns the
    emulation seconds to charge (0 for a solver that charged itself)."""
    if solver.handle < 0:
        t0 = clock_ns()
        tabu_kernel(h, J, num_reads, mix_seed(seed, h.shape[1]), solver.restarts, solver.iterations, solver.tenure,
                    spins, energies)
        return (clock_ns() - t0) * 1e-9
    return _answered(solver.handle, h, J, num_reads, seed, spins, energies)
