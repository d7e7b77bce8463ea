"""The emulated CMOS Ising chip (paper sections 2.2, 3 and 6.1).

:class:`EmulatedChip` is a :class:`dimod.Sampler` (``sample``, ``sample_ising``,
``sample_qubo``; ``parameters``; ``properties`` with ``h_range`` / ``j_range`` like
D-Wave samplers) and offers a vectorised entry point,
:meth:`EmulatedChip.anneal_batch`, for planners that issue tens of thousands of
small programs.

It **refuses** any program that does not fit its :class:`~ising_backend.spec.ChipSpec`
(too many spins, a non-integer, out-of-range, NaN or infinite coefficient) with a
:class:`ChipProgramError` naming the spin or coupling, its value and the limit.
It never clips or rescales: that is a mapping rule's job
(:mod:`ising_backend.quantize`, :mod:`ising_backend.merge`).

Every call is charged to :attr:`EmulatedChip.ledger` (a
:class:`~ising_backend.ledger.CallLedger`); a ``SampleSet``'s ``info["ledger"]``
holds the charge of that call.

With a fault model in the spec (:attr:`ChipSpec.faulty`: dead cores, stuck spins,
program write errors) the chip probes its cores at bring-up and every call goes
through the fault-tolerant dispatch of :mod:`ising_backend.health` (quarantine,
placement around stuck spins, re-dispatch within ``spec.max_retries``, else
:class:`~ising_backend.health.ChipUnavailableError`); :attr:`EmulatedChip.health`
holds what it found.  Without faults nothing of this runs.
"""

from __future__ import annotations

import time
from typing import Sequence

import dimod
import numba
import numpy as np

from .anneal import anneal_kernel, anneal_kernel_cores
from .faults import FaultMap
from .health import HealthMonitor, dispatch
from .ledger import CallLedger
from .models import IsingModel
from .spec import ChipSpec

__all__ = ["EmulatedChip", "ChipProgramError", "check_program", "stack_programs", "kernel_capable", "programs_fit"]


class ChipProgramError(ValueError):
    """A program does not fit the chip (names the spin/coupling, value and limit)."""


def _first(mask: np.ndarray) -> tuple[int, ...]:
    return tuple(int(v) for v in np.argwhere(mask)[0])


def _where(prog: tuple, batched: bool) -> str:
    return f" in program {prog[0]}" if batched else ""


@numba.njit(cache=True, nogil=True)
def _all_fit(h, J, hlo, hhi, jlo, jhi) -> bool:
    """One compiled pass: every coefficient finite, integer, in range; J strictly upper.

    Counting loops without early exits (they vectorise); NaN fails every comparison.
    The ranges hold 0 (:class:`ChipSpec` checks it), so the lower triangle only
    needs its own zero test.
    """
    B, n = h.shape
    bad = 0
    hv = h.reshape(-1)
    for q in range(hv.size):
        v = hv[q]
        bad += np.int64(v >= hlo) * np.int64(v <= hhi) * np.int64(v == np.floor(v)) ^ 1
    Jv = J.reshape(-1)
    for q in range(Jv.size):
        w = Jv[q]
        bad += np.int64(w >= jlo) * np.int64(w <= jhi) * np.int64(w == np.floor(w)) ^ 1
    for b in range(B):
        for i in range(n):
            for j in range(i + 1):
                bad += np.int64(J[b, i, j] != 0)
    return bad == 0


#: The compiled test of :func:`check_program` (``(h (B, n), J (B, n, n), h_lo, h_hi, j_lo, j_hi)
#: -> bool``), for compiled planner loops that program the chip's kernel themselves: a stack that
#: fails it goes through ``anneal_batch``, which names the violation.
programs_fit = _all_fit


def _native(h: np.ndarray, J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """C-contiguous int64 arrays for integer (or bool) input, float64 otherwise (no copy when already so)."""
    def fits_int64(dt):  # uint64 could wrap
        return dt.kind in "bi" or (dt.kind == "u" and dt.itemsize < 8)

    if fits_int64(h.dtype) and fits_int64(J.dtype):
        return np.ascontiguousarray(h, dtype=np.int64), np.ascontiguousarray(J, dtype=np.int64)
    return np.ascontiguousarray(h, dtype=np.float64), np.ascontiguousarray(J, dtype=np.float64)


def kernel_capable(chip) -> bool:
    """Whether ``chip`` is an :class:`EmulatedChip` whose annealing is its own, so a compiled planner
    loop may call its kernel (:meth:`EmulatedChip.kernel_args`) and charge it
    (:meth:`EmulatedChip.charge`); subclasses that override ``anneal_batch`` (e.g. to inject faults),
    chips with a fault model (their calls need the fault-tolerant dispatch) and other solvers go
    through ``anneal_batch``."""
    return isinstance(chip, EmulatedChip) and type(chip).anneal_batch is EmulatedChip.anneal_batch \
        and getattr(chip, "health", None) is None


def check_program(h, J, spec: ChipSpec = ChipSpec(), native: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Validate one program (``h (n,)``, ``J (n, n)``) or a stack (``(B, n)``, ``(B, n, n)``).

    Returns float64 C-contiguous copies shaped ``(B, n)`` and ``(B, n, n)`` (with
    ``native=True``: int64 instead when both inputs have an integer dtype, which the
    annealing kernel takes as is, saving the conversion).
    Raises :class:`ChipProgramError` on the first violation (and counts the rest).
    """
    h = np.asarray(h)
    J = np.asarray(J)
    batched = h.ndim == 2
    if h.ndim not in (1, 2):
        raise ChipProgramError(f"h must be (n,) or (B, n), got shape {h.shape}")
    if not batched:
        h = h[None]
        J = J[None] if J.ndim == 2 else J
    B, n = h.shape
    if J.shape == (B, 0) or (J.size == 0 and n <= 1):
        J = np.zeros((B, n, n))
    if J.shape != (B, n, n):
        raise ChipProgramError(f"J must have shape {(B, n, n) if batched else (n, n)} to match h, got {J.shape if batched else J.shape[1:]}")
    for arr, name in ((h, "h"), (J, "J")):
        if arr.dtype.kind not in "biuf":  # real numbers or booleans (not complex, not objects)
            raise ChipProgramError(f"{name} has dtype {arr.dtype}; the chip takes real integer coefficients")
    if n > spec.n_spins:
        raise ChipProgramError(
            f"program{' 0' if batched else ''} has {n} spins; the chip has {spec.n_spins} (spec.n_spins). "
            "Use spin-budget branching or a larger chip spec"
        )
    hf, Jf = _native(h, J)
    if _all_fit(hf, Jf, *map(float, spec.h_range), *map(float, spec.j_range)):
        if hf.dtype != np.float64 and not native:
            hf, Jf = hf.astype(np.float64), Jf.astype(np.float64)
        return hf, Jf
    hf = np.ascontiguousarray(h, dtype=np.float64)
    Jf = np.ascontiguousarray(J, dtype=np.float64)
    # slow path: find and name the first violation of each kind, in a fixed order
    for arr, name, (lo, hi), kind in ((hf, "h", spec.h_range, "field"), (Jf, "J", spec.j_range, "coupling")):
        bad = ~np.isfinite(arr)
        if bad.any():
            idx = _first(bad)
            raise ChipProgramError(
                f"{kind} {name}{list(idx[1:])} = {float(arr[idx]):g}{_where(idx, batched)} is not finite "
                f"({int(bad.sum())} non-finite coefficient(s)); the chip takes integers in [{lo}, {hi}]"
            )
        bad = arr != np.round(arr)
        if bad.any():
            idx = _first(bad)
            raise ChipProgramError(
                f"{kind} {name}{list(idx[1:])} = {float(arr[idx]):g}{_where(idx, batched)} is not an integer "
                f"({int(bad.sum())} non-integer coefficient(s)); the chip takes integers in [{lo}, {hi}]: "
                "quantize or merge the model first"
            )
        bad = (arr < lo) | (arr > hi)
        if bad.any():
            idx = _first(bad)
            raise ChipProgramError(
                f"{kind} {name}{list(idx[1:])} = {arr[idx]:g}{_where(idx, batched)} is outside "
                f"{name.lower()}_range [{lo}, {hi}] ({int(bad.sum())} out-of-range coefficient(s)); "
                "the chip never clips: quantize, merge or saturate the model first"
            )
    if n >= 1:
        low = np.tril(np.ones((n, n), dtype=bool))
        bad = (Jf != 0) & low[None]
        if bad.any():
            idx = _first(bad)
            raise ChipProgramError(
                f"J{list(idx[1:])} = {Jf[idx]:g}{_where(idx, batched)} is on or below the diagonal; "
                "programs take strictly upper triangular J (J[i, j] for i < j)"
            )
    raise AssertionError("program check disagreement")  # pragma: no cover


def stack_programs(models: Sequence[IsingModel], n: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Stack models into ``h (B, n)``, ``J (B, n, n)``, zero-padding smaller ones.

    Padding spins have no field and no coupling, so they change no energy; their
    returned values are meaningless and should be dropped (``spins[..., :m]``).
    """
    size = max((m.n for m in models), default=0) if n is None else int(n)
    B = len(models)
    h = np.zeros((B, size))
    J = np.zeros((B, size, size))
    for b, m in enumerate(models):
        if m.n > size:
            raise ValueError(f"model {b} has {m.n} spins > stack size {size}")
        h[b, : m.n] = m.h
        J[b, : m.n, : m.n] = m.J
    return h, J


def sample_bqm(solver, bqm: dimod.BinaryQuadraticModel, num_reads: int, seed: int | None,
               **info) -> dimod.SampleSet:
    """``solver.sample(bqm)`` through ``solver.anneal_batch`` on one program (exact
    conversion to SPIN and back); the SampleSet's info holds the call's ledger
    (``solver.last_call``) then ``info``."""
    variables = list(bqm.variables)
    model = IsingModel.from_bqm(bqm.spin if bqm.vartype is dimod.BINARY else bqm, variables)
    spins, _ = solver.anneal_batch(model.h[None], model.J[None], num_reads=num_reads, seed=seed)
    samples = spins[0]
    if bqm.vartype is dimod.BINARY:
        samples = ((samples + 1) // 2).astype(np.int8)
    return dimod.SampleSet.from_samples_bqm((samples, variables), bqm,
                                            info={"ledger": solver.last_call.to_dict(), **info})


def check_call_seed(seed) -> int:
    """A per-call sampling seed: an integer in ``[0, 2**64)`` (a float, bool or NaN is refused)."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= int(seed) < 2**64:
        raise ValueError(f"seed = {seed!r} must be None or an integer in [0, 2**64)")
    return int(seed)


#: Most reads per program in one call (each read is one physical chip call).
MAX_READS = 2**20


def check_num_reads(num_reads) -> int:
    """Reads per program: an integer in ``[1, MAX_READS]`` (a bool, NaN, inf or non-number is refused)."""
    try:
        ok = (not isinstance(num_reads, (bool, np.bool_)) and np.ndim(num_reads) == 0
              and int(num_reads) == num_reads and 1 <= num_reads <= MAX_READS)
    except (TypeError, ValueError, OverflowError):
        ok = False
    if not ok:
        shown = " ".join(repr(num_reads).split())[:60]
        raise ValueError(f"num_reads = {shown} must be an integer in [1, {MAX_READS}] (MAX_READS)")
    return int(num_reads)


def seeded_rng(seed, where: str) -> np.random.Generator:
    """``np.random.default_rng(seed)``, with an error naming ``where`` and the bad seed."""
    try:
        return np.random.default_rng(seed)
    except (TypeError, ValueError) as exc:
        raise ValueError(
            f"{where}: seed = {seed!r} is not a numpy seed (None, an integer >= 0 or a sequence of them): {exc}"
        ) from exc


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


class EmulatedChip(dimod.Sampler):
    """An emulated multi-core CMOS Ising chip.

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

    def __init__(self, spec: ChipSpec | None = None, seed: int | None = None, probe: bool = True):
        self.spec = ChipSpec() if spec is None else spec
        self._rng = seeded_rng(seed, "EmulatedChip")
        self.ledger = CallLedger()
        self._mismatch = _mismatch_matrices(self.spec)
        #: the fault-tolerant driver's view of the cores (``None`` without a fault model)
        self.health: HealthMonitor | None = None
        if self.spec.faulty:
            self.faults = FaultMap.from_spec(self.spec)
            self._clamp = self.faults.clamp if self.faults.clamp.any() else np.zeros((0, 0), dtype=np.int8)
            self.health = HealthMonitor(self.spec, self.faults, self._mismatch)
            if probe:
                self.health.probe(self._run_cores, self._charge_probe)
        self._parameters = {"num_reads": [], "seed": []}
        self._properties = {
            "h_range": list(self.spec.h_range),
            "j_range": list(self.spec.j_range),
            "num_spins": self.spec.n_spins,
            "num_cores": self.spec.n_cores,
            "solve_time_s": self.spec.solve_time_s,
            "energy_per_call_j": self.spec.energy_per_call_j,
            "spec": self.spec.to_dict(),
        }

    @property
    def parameters(self) -> dict:
        return self._parameters

    @property
    def properties(self) -> dict:
        return self._properties

    def check_program(self, h, J) -> tuple[np.ndarray, np.ndarray]:
        """Validate a program or stack against this chip's spec (see :func:`check_program`)."""
        return check_program(h, J, self.spec)

    def _draw_seed(self, seed) -> int:
        if seed is None:
            return int(self._rng.integers(0, 2**63 - 1))
        return check_call_seed(seed)

    def anneal_batch(self, h, J, num_reads: int = 1, seed: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Anneal a stack of programs.

        Args:
            h: ``(B, n)`` integer fields (a single ``(n,)`` program is accepted too).
            J: ``(B, n, n)`` integer couplings, strictly upper triangular.
            num_reads: reads per program (each read is one physical chip call).
            seed: sampling seed; ``None`` draws one from the chip's generator.

        Returns:
            ``spins`` int8 ``(B, num_reads, n)`` and ``energies`` float64
            ``(B, num_reads)`` (programmed coefficients; single program: leading
            axis dropped).  Charges ``B * num_reads`` calls to :attr:`ledger`.
        """
        t0 = time.perf_counter()
        single = np.ndim(h) == 1
        num_reads = check_num_reads(num_reads)
        hf, Jf = check_program(h, J, self.spec, native=True)
        seed = self._draw_seed(seed)
        B, n = hf.shape
        spins = np.empty((B, num_reads, n), dtype=np.int8)
        energies = np.empty((B, num_reads), dtype=np.float64)
        if self.spec.beta_range is None:
            hot, cold = -1.0, -1.0
        else:
            hot, cold = self.spec.beta_range
        if self.health is not None and B and n:
            return self._dispatch(hf, Jf, num_reads, seed, single, t0)
        if B:
            anneal_kernel(hf, Jf, num_reads, np.uint64(seed), self.spec.sweeps, self.spec.schedule == "geometric",
                          hot, cold, self._mismatch, float(self.spec.readout_flip_prob), spins, energies)
        # a program without spins is not run on the chip: nothing is charged
        self.last_call = self.ledger.record_physical(B * num_reads if n else 0, self.spec, time.perf_counter() - t0)
        if single:
            return spins[0], energies[0]
        return spins, energies

    @property
    def usable_spins(self) -> int:
        """Spins a program may use without touching a stuck spin the health probe found
        (``spec.n_spins`` without faults)."""
        return self.spec.n_spins if self.health is None else self.health.usable_spins

    def _dispatch(self, hf, Jf, num_reads, seed, single, t0):
        """:meth:`anneal_batch` on a faulty chip: :func:`ising_backend.health.dispatch`, each round charged
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
            spins, energies = dispatch(self.health, hf, Jf, num_reads, seed, self._run_cores, charge)
        finally:
            charge(0, 0.0, 0, 0)  # the driver's seconds after the last round: no call, the machine's time
            self.last_call = total
        if single:
            return spins[0], energies[0]
        return spins, energies

    def _run_cores(self, h, J, reads, seed, cores, raw):
        """The annealing kernel with each read's core given (``raw``: physical placement, for the probe)."""
        M, n = h.shape
        spins = np.empty((M, reads, n), dtype=np.int8)
        energies = np.empty((M, reads), dtype=np.float64)
        hot, cold = (-1.0, -1.0) if self.spec.beta_range is None else self.spec.beta_range
        clamp = self._clamp if raw or not self._clamp.size else self.health.clamp
        mismatch = self._mismatch if raw else self.health.mismatch
        anneal_kernel_cores(np.ascontiguousarray(h), np.ascontiguousarray(J), reads, np.uint64(seed), self.spec.sweeps,
                            self.spec.schedule == "geometric", hot, cold, mismatch,
                            float(self.spec.readout_flip_prob), np.asarray(cores, dtype=np.int64), clamp, spins,
                            energies)
        return spins, energies

    def _charge_probe(self, calls, seconds, retries, probe):
        self.ledger.record_physical(calls, self.spec, seconds, cores=self.spec.n_cores, retries=retries,
                                    probe_calls=probe)

    def kernel_args(self) -> tuple:
        """``(sweeps, geometric, beta_hot, beta_cold, mismatch, flip_prob)``: this chip's arguments of
        :func:`~ising_backend.anneal.anneal_kernel` after the seed.

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

    def anneal_models(self, models: Sequence[IsingModel], num_reads: int = 1, seed: int | None = None):
        """Anneal chip-legal :class:`IsingModel` s in one batch.

        Returns a list of ``(spins (reads, n_b) int8, energies (reads,))`` with each
        model's offset added to its energies.
        """
        h, J = stack_programs(models)
        spins, energies = self.anneal_batch(h, J, num_reads=num_reads, seed=seed)
        return [(spins[b, :, : m.n], energies[b] + m.offset) for b, m in enumerate(models)]

    def sample(self, bqm: dimod.BinaryQuadraticModel, num_reads: int = 1, seed: int | None = None,
               **kwargs) -> dimod.SampleSet:
        """Sample a BQM that fits the chip (after exact conversion to SPIN).

        Raises:
            ChipProgramError: the program does not fit the spec (nothing is clipped).
        """
        self.remove_unknown_kwargs(**kwargs)
        return sample_bqm(self, bqm, num_reads, seed, spec=self.spec.to_dict())
