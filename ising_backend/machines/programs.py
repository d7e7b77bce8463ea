"""Chip programs: the checks every machine applies (never a clip), stacking, seeds and reads.

:func:`check_program` refuses a program that does not fit a :class:`~ising_backend.spec.ChipSpec`
(too many spins, a non-integer, out-of-range, NaN or infinite coefficient) with a
:class:`ChipProgramError` naming the spin or coupling, its value and the limit.
"""

from __future__ import annotations

from typing import Sequence

import dimod
import numba
import numpy as np

from ising_backend.models import IsingModel
from ising_backend.spec import ChipSpec

__all__ = ["ChipProgramError", "check_program", "stack_programs", "programs_fit", "sample_bqm", "check_call_seed",
           "check_num_reads", "seeded_rng", "MAX_READS"]


class ChipProgramError(ValueError):
    """A program does not fit the chip (names the spin/coupling, value and limit)."""


def _first(mask: np.ndarray) -> tuple[int, ...]:
    return tuple(int(v) for v in np.argwhere(mask)[0])


def _where(at: tuple, batched: bool) -> str:
    return f" in program {at[0]}" if batched else ""


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
