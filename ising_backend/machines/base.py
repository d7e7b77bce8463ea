"""The Ising-machine interface: the protocol every planner relies on and the base class of drivers.

Contract (docs/ising_machines.md): :class:`IsingMachine` has ``spec``, ``ledger``, ``last_call``,
``health``, ``usable_spins``, ``anneal_batch(h, J, num_reads, seed)`` (refuses programs outside the spec,
never clips; anneals, times and charges ``B * num_reads`` physical calls), ``anneal_models`` and
``session(ledger)``; planners use these members and no others.  :class:`MachineBase` does everything but
the anneal (a driver implements ``_sample`` or ``_anneal``).  Design notes: docs/design/machine_link.md.
"""

from __future__ import annotations

import time
from typing import Protocol, runtime_checkable

import dimod
import numpy as np

from ising_backend.faults.health import SolverOutputError, program_energy
from ising_backend.ledger import CallLedger
from ising_backend.machines.link import MachineSession
from ising_backend.machines.programs import check_call_seed, check_num_reads, check_program, sample_bqm, seeded_rng, stack_programs
from ising_backend.spec import ChipSpec

__all__ = ["IsingMachine", "MachineBase"]


@runtime_checkable
class IsingMachine(Protocol):
    """What the package uses of an Ising machine (module docstring); :class:`MachineBase` has it all."""

    spec: ChipSpec
    ledger: CallLedger
    last_call: CallLedger
    health: object
    usable_spins: int

    def anneal_batch(self, h, J, num_reads: int = 1, seed: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        ...

    def anneal_models(self, models, num_reads: int = 1, seed: int | None = None) -> list:
        ...

    def session(self, ledger: CallLedger, decision: str = "unlabelled"):
        ...


class MachineBase(dimod.Sampler):
    """An Ising machine from one method: subclasses implement :meth:`_sample`.

    The base checks each stack against ``spec`` (a :class:`ChipProgramError` naming the
    coefficient and the limit; nothing is clipped), draws a seed when the caller gives none,
    checks the device's answer (:class:`SolverOutputError`), computes energies on the
    programmed coefficients and charges ``B * num_reads`` physical calls by the spec, the
    wall time of check and anneal as ``emulation_s`` (the device's time on the host's clock).
    It is a ``dimod.Sampler`` too (``sample``, ``sample_ising``, ``sample_qubo``).
    """

    health = None  # no fault-tolerant dispatch: a device reports its own failures by raising
    _native = False  # programs handed to _anneal as float64 (True: int64 when integral, as the emulator's kernel)
    _emulates_faults = False  # a spec with a fault model is refused (only the emulator emulates one)
    _logical = False  # calls charged as physical (True: projected logical calls, the logical solver's)

    def __init__(self, spec: ChipSpec | None = None, seed: int | None = None):
        self.spec = ChipSpec() if spec is None else spec
        if not isinstance(self.spec, ChipSpec):
            raise TypeError(f"spec = {self.spec!r} must be an ising_backend.ChipSpec")
        if self.spec.faulty and not self._emulates_faults:
            raise ValueError("the fault model (dead_cores, stuck_spins, program_error_prob) is emulated by "
                             "EmulatedChip only; a device reports its own failures")
        self.ledger = CallLedger()
        self.last_call = CallLedger()
        self._rng = seeded_rng(seed, type(self).__name__)

    def _sample(self, h: np.ndarray, J: np.ndarray, num_reads: int, seed: int) -> np.ndarray:
        """Anneal a checked stack (``h (B, n)``, ``J (B, n, n)`` upper triangular, integers in range,
        ``n >= 1``) and return spins ``(B, num_reads, n)`` of +-1."""
        raise NotImplementedError

    def _anneal(self, h: np.ndarray, J: np.ndarray, num_reads: int, seed: int, t0: float):
        """``(spins, energies, charged)`` of a checked stack: :meth:`_sample`'s spins checked, energies on
        the programmed coefficients, ``charged`` False (the base charges the call)."""
        B, n = h.shape
        if B and n:
            spins = np.asarray(self._sample(h, J, num_reads, seed))
            if spins.shape != (B, num_reads, n) or not ((spins == 1) | (spins == -1)).all():
                raise SolverOutputError(f"{type(self).__name__}._sample returned shape {spins.shape}; expected "
                                        f"{(B, num_reads, n)} spins in {{-1, +1}}")
            spins = spins.astype(np.int8, copy=False)
        else:
            spins = np.ones((B, num_reads, n), dtype=np.int8)
        return spins, program_energy(h, J, spins), False

    @property
    def usable_spins(self) -> int:
        """Spins a program may use (``spec.n_spins``; the emulator's stuck spins are not usable)."""
        return self.spec.n_spins

    @property
    def parameters(self) -> dict:
        return {"num_reads": [], "seed": []}

    @property
    def properties(self) -> dict:
        return {"h_range": list(self.spec.h_range), "j_range": list(self.spec.j_range),
                "num_spins": self.spec.n_spins, "num_cores": self.spec.n_cores,
                "solve_time_s": self.spec.solve_time_s, "energy_per_call_j": self.spec.energy_per_call_j,
                "spec": self.spec.to_dict()}

    def check_program(self, h, J) -> tuple[np.ndarray, np.ndarray]:
        """Validate a program or stack against this machine's spec (:func:`~ising_backend.check_program`)."""
        return check_program(h, J, self.spec)

    def _checked(self, h, J) -> tuple[np.ndarray, np.ndarray]:
        """The stack :meth:`_anneal` receives (``h (B, n)``, ``J (B, n, n)``), or a ChipProgramError."""
        return check_program(h, J, self.spec, native=self._native)

    def _draw_seed(self, seed) -> int:
        return int(self._rng.integers(0, 2**63 - 1)) if seed is None else check_call_seed(seed)

    def anneal_batch(self, h, J, num_reads: int = 1, seed: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Anneal a stack of programs.

        Args:
            h: ``(B, n)`` integer fields (a single ``(n,)`` program is accepted too).
            J: ``(B, n, n)`` integer couplings, strictly upper triangular.
            num_reads: reads per program (each read is one physical chip call).
            seed: sampling seed; ``None`` draws one from the machine's generator.

        Returns:
            ``spins`` int8 ``(B, num_reads, n)`` and ``energies`` float64 ``(B, num_reads)``
            (programmed coefficients; single program: leading axis dropped).  Charges
            ``B * num_reads`` calls to :attr:`ledger` (a program without spins is not run: nothing).
        """
        t0 = time.perf_counter()
        single = np.ndim(h) == 1
        num_reads = check_num_reads(num_reads)
        hf, Jf = self._checked(h, J)
        seed = self._draw_seed(seed)
        B, n = hf.shape
        spins, energies, charged = self._anneal(hf, Jf, num_reads, seed, t0)
        if not charged:
            record = self.ledger.record_logical if self._logical else self.ledger.record_physical
            self.last_call = record(B * num_reads if n else 0, self.spec, time.perf_counter() - t0)
        if single:
            return spins[0], energies[0]
        return spins, energies

    def anneal_models(self, models, num_reads: int = 1, seed: int | None = None):
        """Chip-legal :class:`IsingModel` s in one batch: ``[(spins (reads, n_b), energies + offset)]``."""
        h, J = stack_programs(models)
        spins, energies = self.anneal_batch(h, J, num_reads=num_reads, seed=seed)
        return [(spins[b, :, : m.n], energies[b] + m.offset) for b, m in enumerate(models)]

    def session(self, ledger: CallLedger, decision: str = "unlabelled"):
        """A :class:`~ising_backend.machines.link.MachineSession` charging ``ledger`` for submissions of the decision
        class ``decision``: compiled loops reach this machine by the callback (its own ``anneal_batch``)."""
        return MachineSession(self, ledger, decision=decision)

    def sample(self, bqm: dimod.BinaryQuadraticModel, num_reads: int = 1, seed: int | None = None,
               **kwargs) -> dimod.SampleSet:
        """Sample a BQM that fits the spec (exact conversion to SPIN; nothing is clipped)."""
        self.remove_unknown_kwargs(**kwargs)
        return sample_bqm(self, bqm, num_reads, seed, spec=self.spec.to_dict())
