"""Any Ising machine behind the planners: the interface, a base class for drivers, dimod adapters.

Contract (docs/ising_machines.md): an Ising machine has a :class:`~ising_backend.spec.ChipSpec`
(``spec``: spins, h/J ranges, cores, time and energy per call), a
:class:`~ising_backend.ledger.CallLedger` (``ledger``) with the charge of its latest call in
``last_call``, and one submission primitive, ``anneal_batch(h (B, n), J (B, n, n), num_reads,
seed) -> (spins int8 (B, reads, n), energies (B, reads))``, that refuses programs that do not
fit the spec (never clips), anneals, times and charges ``B * num_reads`` physical calls.
:class:`~ising_backend.chip.EmulatedChip` (healthy or faulty) and every class here satisfy it.

:class:`MachineBase` does everything but the anneal: a driver implements ``_sample``.
:class:`SamplerChip` wraps any ``dimod.Sampler`` (dwave-samplers, neal, OpenJij, a QPU
sampler) as such a machine; :func:`as_machine` turns a bare sampler into one with the paper's
spec, so ``make_pipeline("ising", chip=neal.SimulatedAnnealingSampler())`` works.
:class:`MachineSpec` is a picklable recipe (spec + sampler name) for worker processes.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field
from importlib import import_module
from typing import Any, Protocol, runtime_checkable

import dimod
import numpy as np

from .chip import EmulatedChip, check_call_seed, check_num_reads, check_program, sample_bqm, seeded_rng, stack_programs
from .health import program_energy
from .ledger import CallLedger
from .meter import SolverOutputError
from .sampler_options import RESERVED, check_value, parameter_types, parse_value
from .spec import ChipSpec

__all__ = ["IsingMachine", "MachineBase", "SamplerChip", "MachineSpec", "SAMPLERS", "as_machine",
           "build_machine", "parse_sampler_options", "sampler_names"]


@runtime_checkable
class IsingMachine(Protocol):
    """What a planner needs of an Ising machine (module docstring)."""

    spec: ChipSpec
    ledger: CallLedger

    def anneal_batch(self, h, J, num_reads: int = 1, seed: int | None = None) -> tuple[np.ndarray, np.ndarray]:
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

    def __init__(self, spec: ChipSpec | None = None, seed: int | None = None):
        self.spec = ChipSpec() if spec is None else spec
        if not isinstance(self.spec, ChipSpec):
            raise TypeError(f"spec = {self.spec!r} must be an ising_backend.ChipSpec")
        if self.spec.faulty:
            raise ValueError("the fault model (dead_cores, stuck_spins, program_error_prob) is emulated by "
                             "EmulatedChip only; a device reports its own failures")
        self.ledger = CallLedger()
        self.last_call = CallLedger()
        self._rng = seeded_rng(seed, type(self).__name__)

    def _sample(self, h: np.ndarray, J: np.ndarray, num_reads: int, seed: int) -> np.ndarray:
        """Anneal a checked stack (``h (B, n)``, ``J (B, n, n)`` upper triangular, integers in range,
        ``n >= 1``) and return spins ``(B, num_reads, n)`` of +-1."""
        raise NotImplementedError

    @property
    def usable_spins(self) -> int:
        return self.spec.n_spins

    @property
    def parameters(self) -> dict:
        return {"num_reads": [], "seed": []}

    @property
    def properties(self) -> dict:
        return {"h_range": list(self.spec.h_range), "j_range": list(self.spec.j_range),
                "num_spins": self.spec.n_spins, "num_cores": self.spec.n_cores,
                "solve_time_s": self.spec.solve_time_s, "energy_per_call_j": self.spec.energy_per_call_j}

    def check_program(self, h, J) -> tuple[np.ndarray, np.ndarray]:
        return check_program(h, J, self.spec)

    def anneal_batch(self, h, J, num_reads: int = 1, seed: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Anneal a stack of programs (same contract and shapes as :meth:`EmulatedChip.anneal_batch`)."""
        single = np.ndim(h) == 1
        num_reads = check_num_reads(num_reads)
        t0 = time.perf_counter()
        hf, Jf = check_program(h, J, self.spec)
        seed = int(self._rng.integers(0, 2**63 - 1)) if seed is None else check_call_seed(seed)
        B, n = hf.shape
        if B and n:
            spins = np.asarray(self._sample(hf, Jf, num_reads, seed))
            if spins.shape != (B, num_reads, n) or not ((spins == 1) | (spins == -1)).all():
                raise SolverOutputError(f"{type(self).__name__}._sample returned shape {spins.shape}; expected "
                                        f"{(B, num_reads, n)} spins in {{-1, +1}}")
            spins = spins.astype(np.int8, copy=False)
        else:
            spins = np.ones((B, num_reads, n), dtype=np.int8)
        energies = program_energy(hf, Jf, spins)
        self.last_call = self.ledger.record_physical(B * num_reads if n else 0, self.spec, time.perf_counter() - t0)
        if single:
            return spins[0], energies[0]
        return spins, energies

    def anneal_models(self, models, num_reads: int = 1, seed: int | None = None):
        """Chip-legal :class:`IsingModel` s in one batch: ``[(spins (reads, n_b), energies + offset)]``."""
        h, J = stack_programs(models)
        spins, energies = self.anneal_batch(h, J, num_reads=num_reads, seed=seed)
        return [(spins[b, :, : m.n], energies[b] + m.offset) for b, m in enumerate(models)]

    def sample(self, bqm: dimod.BinaryQuadraticModel, num_reads: int = 1, seed: int | None = None,
               **kwargs) -> dimod.SampleSet:
        """Sample a BQM that fits the spec (exact conversion to SPIN; nothing is clipped)."""
        self.remove_unknown_kwargs(**kwargs)
        return sample_bqm(self, bqm, num_reads, seed, spec=self.spec.to_dict())


#: ``--sampler`` names: (module, class, extra that installs it)
SAMPLERS = {
    "dwave-sa": ("dwave.samplers", "SimulatedAnnealingSampler", None),
    "dwave-tabu": ("dwave.samplers", "TabuSampler", None),
    "dwave-greedy": ("dwave.samplers", "SteepestDescentSolver", None),
    "neal": ("neal", "SimulatedAnnealingSampler", None),
    "openjij-sa": ("openjij", "SASampler", "samplers"),
    "openjij-sqa": ("openjij", "SQASampler", "samplers"),
}


def sampler_names() -> tuple[str, ...]:
    return tuple(SAMPLERS)


def _load_sampler(name: str) -> dimod.Sampler:
    if name not in SAMPLERS:
        raise ValueError(f"unknown sampler {name!r}; known: {', '.join(SAMPLERS)}")
    module, cls, extra = SAMPLERS[name]
    try:
        mod = import_module(module)
    except ImportError:
        hint = f"pip install 'mrmt-ising[{extra}]'" if extra else f"pip install {module.split('.')[0]}"
        raise ValueError(f"sampler {name!r} needs the package {module!r}: {hint}") from None
    return getattr(mod, cls)()


def parse_sampler_options(name: str, items) -> tuple[tuple[str, Any], ...]:
    """``(key, text)`` pairs (command-line ``KEY=VALUE`` s) for the sampler ``name`` as typed
    ``(key, value)`` pairs, each text read by its parameter's type
    (:mod:`ising_backend.sampler_options`); ``ValueError`` in one line naming an unknown or
    reserved key (with the sampler's known parameters) or a value of the wrong type."""
    sampler = _load_sampler(name)
    types = parameter_types(sampler)
    settable = sorted(set(types) - set(RESERVED))
    out = []
    for key, text in items:
        if key in RESERVED:
            raise ValueError(f"{key}={text!r}: {key!r} is set per call by the planner, not fixed")
        if key not in types:
            raise ValueError(f"{key}={text!r}: {key!r} is not one of the parameters of {name} "
                             f"({type(sampler).__name__}): {', '.join(settable) or '(none)'}")
        out.append((key, parse_value(types[key], key, text)))
    return tuple(out)


class SamplerChip(MachineBase):
    """A ``dimod.Sampler`` as an Ising machine of spec ``spec`` (default: the paper's chip).

    Each program of a stack is one ``sampler.sample(bqm, num_reads=..., seed=..., **params)``
    call on a SPIN BQM over variables ``0..n-1`` (a per-program seed in ``[0, 2**31)`` drawn
    from the call's seed, when the sampler takes ``seed``; without it the sampler's own
    randomness decides and plans are not reproducible).  The spec decides what fits (programs
    outside it are refused exactly as by :class:`EmulatedChip`) and what each call costs; the
    sampler's wall time is recorded as ``emulation_s``.  ``params`` are checked against
    ``sampler.parameters`` and the keywords of ``sampler.sample``, their values against the types of those
    keywords (:mod:`ising_backend.sampler_options`).  The emulator's knobs (``sweeps``, ``schedule``,
    noise) do not apply.
    """

    def __init__(self, sampler: dimod.Sampler, spec: ChipSpec | None = None, seed: int | None = None, **params):
        if not isinstance(sampler, dimod.Sampler):
            raise TypeError(f"sampler = {sampler!r} is not a dimod.Sampler")
        super().__init__(spec, seed)
        types = parameter_types(sampler)
        known = set(types)
        for key in RESERVED:
            if key in params:
                raise ValueError(f"sampler parameter {key!r} is set per call by the planner, not fixed")
        unknown = sorted(set(params) - known)
        if unknown:
            raise ValueError(f"sampler parameter {unknown[0]!r} is not one of {type(sampler).__name__}'s: "
                             f"{', '.join(sorted(known - set(RESERVED))) or '(none)'}")
        for key, value in params.items():
            try:
                check_value(types[key], key, value)
            except ValueError as exc:
                raise ValueError(f"sampler parameter {exc}") from None
        self.sampler = sampler
        self.params = dict(params)
        self._seeded = "seed" in known

    @property
    def parameters(self) -> dict:
        return {"num_reads": [], "seed": []}

    def probe(self) -> None:
        """One 1-spin program through the sampler with ``params``, uncharged, so values the sampler
        refuses (``num_sweeps=-1``, a 3-element ``beta_range``) fail now, in one ``ValueError``
        naming them, rather than at the first plan."""
        try:
            self._sample(np.zeros((1, 1), dtype=np.int64), np.zeros((1, 1, 1), dtype=np.int64), 1, 0)
        except Exception as exc:  # whatever the package raises, reported in one line
            given = ", ".join(f"{k}={v!r}" for k, v in self.params.items()) or "its defaults"
            raise ValueError(f"{type(self.sampler).__name__} refuses {given}: {type(exc).__name__}: "
                             f"{' '.join(str(exc).split())}") from None

    def __repr__(self) -> str:
        return f"SamplerChip({type(self.sampler).__name__}, n_spins={self.spec.n_spins})"

    def _sample(self, h, J, num_reads, seed):
        B, n = h.shape
        out = np.empty((B, num_reads, n), dtype=np.int8)
        seeds = np.random.default_rng(seed).integers(0, 2**31, size=B)  # neal and dwave-samplers take [0, 2**31)
        iu, ju = np.triu_indices(n, 1)
        for b in range(B):
            upper = J[b, iu, ju]
            mask = upper != 0
            bqm = dimod.BinaryQuadraticModel.from_numpy_vectors(h[b], (iu[mask], ju[mask], upper[mask]), 0.0, dimod.SPIN)
            kw = dict(self.params, num_reads=num_reads)
            if self._seeded:
                kw["seed"] = int(seeds[b])
            with warnings.catch_warnings():
                if not (h[b].any() or J[b].any()):  # every state is a ground state; SA samplers warn of it
                    warnings.simplefilter("ignore", UserWarning)
                ss = self.sampler.sample(bqm, **kw)
            rec = ss.record
            samples = np.repeat(rec.sample, rec.num_occurrences, axis=0)
            if samples.shape[0] != num_reads:
                raise SolverOutputError(f"{type(self.sampler).__name__} returned {samples.shape[0]} reads for "
                                        f"num_reads = {num_reads}")
            order = [ss.variables.index(v) for v in range(n)]
            out[b] = samples[:, order]
        return out


@dataclass(frozen=True)
class MachineSpec:
    """A picklable recipe of an Ising machine: the emulator of ``spec`` (``sampler=None``) or the
    named sampler (:data:`SAMPLERS`) behind a :class:`SamplerChip` of that spec."""

    spec: ChipSpec = field(default_factory=ChipSpec)
    sampler: str | None = None
    options: tuple[tuple[str, Any], ...] = ()

    def __post_init__(self):
        if self.sampler is not None and self.sampler not in SAMPLERS:
            raise ValueError(f"unknown sampler {self.sampler!r}; known: {', '.join(SAMPLERS)}")
        if self.options and self.sampler is None:
            raise ValueError("sampler options given without a sampler")
        for key in RESERVED:
            if key in dict(self.options):
                raise ValueError(f"sampler parameter {key!r} is set per call by the planner, not fixed")
        def frozen(v):  # list values (a JSON option such as beta_range=[0.1, 5]) kept hashable
            return tuple(frozen(x) for x in v) if isinstance(v, (list, tuple)) else v

        object.__setattr__(self, "options", tuple(sorted((k, frozen(v)) for k, v in dict(self.options).items())))

    def build(self, seed: int | None = None):
        if self.sampler is None:
            return EmulatedChip(self.spec, seed=seed)
        return SamplerChip(_load_sampler(self.sampler), self.spec, seed=seed, **dict(self.options))

    def replace_spec(self, spec: ChipSpec) -> "MachineSpec":
        return MachineSpec(spec, self.sampler, self.options)

    def to_dict(self) -> dict:
        out = self.spec.to_dict()
        if self.sampler is not None:
            out["sampler"] = self.sampler
            out.update({f"sampler.{k}": v for k, v in self.options})
        return out


def build_machine(chip) -> IsingMachine:
    """A fresh machine from a :class:`ChipSpec` (the emulator) or a :class:`MachineSpec`."""
    if isinstance(chip, MachineSpec):
        return chip.build()
    if isinstance(chip, ChipSpec):
        return EmulatedChip(chip)
    raise TypeError(f"chip = {chip!r} must be a ChipSpec or a MachineSpec")


def as_machine(chip) -> IsingMachine:
    """``chip`` itself when it is an Ising machine; a bare ``dimod.Sampler`` behind a
    :class:`SamplerChip` of the paper's spec; anything else is refused naming what is missing."""
    if isinstance(chip, IsingMachine):
        return chip
    if isinstance(chip, dimod.Sampler):
        return SamplerChip(chip)
    missing = [a for a in ("spec", "ledger", "anneal_batch") if not hasattr(chip, a)]
    raise TypeError(f"chip = {chip!r} is not an Ising machine (missing {', '.join(missing)}; see "
                    "ising_backend.IsingMachine) nor a dimod.Sampler")

