"""Any Ising machine behind the planners: dimod adapters, driver adapters, recipes.

Contract: :class:`SamplerChip` wraps any ``dimod.Sampler`` as an :class:`~ising_backend.machines.base.IsingMachine`
(re-exported here with :class:`~ising_backend.machines.base.MachineBase`); :func:`as_machine` gives a bare sampler
the paper's spec and puts a minimal driver (``spec``, ``ledger``, ``anneal_batch``) behind a
:class:`DriverMachine`; :class:`MachineSpec` is a picklable recipe (spec + sampler name) for workers.
Design notes: docs/design/machine_link.md.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from importlib import import_module
from typing import Any

import dimod
import numpy as np

from ising_backend.machines.base import IsingMachine, MachineBase
from ising_backend.machines.chip import EmulatedChip
from ising_backend.ledger import CallLedger
from ising_backend.machines.link import MachineSession
from ising_backend.machines.logical import LogicalIsingSolver
from ising_backend.models import IsingModel
from ising_backend.faults.health import SolverOutputError
from ising_backend.machines.sampler_options import RESERVED, check_value, parameter_types, parse_value
from ising_backend.spec import ChipSpec

__all__ = ["IsingMachine", "MachineBase", "SamplerChip", "DriverMachine", "LogicalDriver", "as_logical_solver", "MachineSpec", "SAMPLERS", "as_machine",
           "build_machine", "parse_sampler_options", "sampler_names"]


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
    (:mod:`ising_backend.machines.sampler_options`); ``ValueError`` in one line naming an unknown or
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
    keywords (:mod:`ising_backend.machines.sampler_options`).  The emulator's knobs (``sweeps``, ``schedule``,
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


def build_machine(chip, seed: int | None = None) -> IsingMachine:
    """A fresh machine from a :class:`ChipSpec` (the emulator) or a :class:`MachineSpec`, seeded with ``seed``."""
    if isinstance(chip, MachineSpec):
        return chip.build(seed)
    if isinstance(chip, ChipSpec):
        return EmulatedChip(chip, seed=seed)
    raise TypeError(f"chip = {chip!r} must be a ChipSpec or a MachineSpec")


class DriverMachine(MachineBase):
    """A minimal driver (``spec``, ``ledger``, ``anneal_batch``) as a full machine: every call is the
    driver's own (its checks, its seeds, its charges to its own ``ledger``, which this shares);
    ``last_call`` is the driver's when it keeps one, else what its ledger gained."""

    def __init__(self, driver):
        self.driver = driver
        self.spec = driver.spec
        self.ledger = driver.ledger
        self.last_call = CallLedger()

    def __repr__(self) -> str:
        return f"DriverMachine({self.driver!r})"

    def anneal_batch(self, h, J, num_reads: int = 1, seed: int | None = None):
        before = self.ledger.snapshot()
        own = getattr(self.driver, "last_call", None)
        try:
            return self.driver.anneal_batch(h, J, num_reads=num_reads, seed=seed)
        finally:  # a call that failed is charged what it spent
            last = getattr(self.driver, "last_call", None)
            self.last_call = last if last is not None and last is not own else self.ledger.since(before)


class LogicalDriver:
    """A minimal logical solver (``solve_many(models, num_reads, seed)`` and ``ledger``) as the package
    uses one: ``solve_stack``, ``last_call`` (the solver's when it keeps one, else what its ledger
    gained) and a callback :meth:`session`; every call is the solver's own."""

    health = None

    def __init__(self, solver):
        self.solver = solver
        self.ledger = solver.ledger
        self.spec = getattr(solver, "spec", None) or ChipSpec()
        self.budget = int(getattr(solver, "budget", None) or self.spec.n_spins)
        self.last_call = CallLedger()

    def __repr__(self) -> str:
        return f"LogicalDriver({self.solver!r})"

    def solve_many(self, models, num_reads: int = 1, seed: int | None = None):
        before = self.ledger.snapshot()
        own = getattr(self.solver, "last_call", None)
        try:
            return self.solver.solve_many(models, num_reads=num_reads, seed=seed)
        finally:
            last = getattr(self.solver, "last_call", None)
            self.last_call = last if last is not None and last is not own else self.ledger.since(before)

    def solve_stack(self, h, J, num_reads: int = 1, seed: int | None = None) -> np.ndarray:
        models = [IsingModel.trusted(h[b], J[b]) for b in range(np.shape(h)[0])]
        return np.stack([np.asarray(r.spins).reshape(int(num_reads), -1)
                         for r in self.solve_many(models, num_reads=num_reads, seed=seed)])

    def session(self, ledger: CallLedger, decision: str = "unlabelled") -> MachineSession:
        return MachineSession(self, ledger, None, logical=True, decision=decision)


def as_logical_solver(solver):
    """``solver`` itself when it is a :class:`~ising_backend.machines.logical.LogicalIsingSolver`, else behind a
    :class:`LogicalDriver` (it needs ``solve_many`` and ``ledger``; anything else is refused)."""
    if isinstance(solver, LogicalIsingSolver):
        return solver
    missing = [a for a in ("solve_many", "ledger") if not hasattr(solver, a)]
    if missing:
        raise TypeError(f"solver = {solver!r} is not a logical Ising solver (missing {', '.join(missing)})")
    return LogicalDriver(solver)


def as_machine(chip=None, seed: int | None = None) -> IsingMachine:
    """``chip`` itself when it is an Ising machine; the paper's emulated chip (seeded with ``seed``) for ``None``; a bare
    ``dimod.Sampler`` behind a :class:`SamplerChip` of the paper's spec; a minimal driver behind a
    :class:`DriverMachine`; anything else is refused naming what is missing."""
    if chip is None:
        return EmulatedChip(ChipSpec(), seed=seed)
    if isinstance(chip, IsingMachine):
        return chip
    if isinstance(chip, dimod.Sampler):
        return SamplerChip(chip)
    missing = [a for a in ("spec", "ledger", "anneal_batch") if not hasattr(chip, a)]
    if not missing:
        return DriverMachine(chip)
    raise TypeError(f"chip = {chip!r} is not an Ising machine (missing {', '.join(missing)}; see "
                    "ising_backend.IsingMachine) nor a dimod.Sampler")
