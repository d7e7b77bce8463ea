"""The emulated chip's hardware faults (a :class:`~ising_backend.spec.ChipSpec` fault model).

Contract: every fault is a pure function of the spec (``seed`` and the fault fields), the core index and
the call's seed.  :class:`FaultMap` holds one chip's dead cores and stuck spins (drawn from a stream of
their own, so the mismatch pattern is unchanged); :func:`write_failures` says which reads' program writes
failed; :func:`garbage_spins` is what a dead core in ``"garbage"`` mode answers.
Design notes: docs/design/faults.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ising_backend._rng import chain_key, splitmix_array
from ising_backend.spec import ChipSpec

__all__ = ["FaultMap", "write_failures", "garbage_spins", "mix"]

_FAULT_STREAM = 0x5EED_FA17
_TAG_WRITE = 1
_TAG_GARBAGE = 2


_MASK = (1 << 64) - 1


def mix(*parts) -> np.ndarray:
    """A uint64 hash of integers / integer arrays (broadcast), one splitmix64 round per part."""
    if all(isinstance(p, (int, np.integer)) for p in parts):  # scalars (every dispatch)
        return np.uint64(chain_key(np.array([int(p) & _MASK for p in parts], dtype=np.uint64)))
    key = np.zeros(np.broadcast(*[np.asarray(p) for p in parts]).shape, dtype=np.uint64)
    for p in parts:
        arr = np.asarray(p)
        if arr.dtype != np.uint64:
            arr = (arr.astype(object) % (1 << 64)).astype(np.uint64) if arr.dtype == object else \
                arr.astype(np.int64).astype(np.uint64)
        key = splitmix_array(key ^ arr)
    return key


def _uniform(key: np.ndarray) -> np.ndarray:
    return (key >> np.uint64(11)).astype(np.float64) * (1.0 / 9007199254740992.0)


@dataclass(frozen=True)
class FaultMap:
    """Static faults of one chip (see the module docstring).

    Attributes:
        dead: ``(n_cores,)`` bool, the dead cores.
        clamp: ``(n_cores, n_spins)`` int8, ``+-1`` where a physical spin is stuck, else 0.
        mode: ``"garbage"`` or ``"timeout"`` (what a dead core does).
    """

    dead: np.ndarray
    clamp: np.ndarray
    mode: str

    @classmethod
    def from_spec(cls, spec: ChipSpec) -> "FaultMap":
        rng = np.random.default_rng([int(spec.seed), _FAULT_STREAM])
        C, N = spec.n_cores, spec.n_spins
        dead = np.zeros(C, dtype=bool)
        dead[rng.choice(C, size=spec.dead_cores, replace=False)] = True
        clamp = np.zeros((C, N), dtype=np.int8)
        for c in range(C):
            pos = rng.choice(N, size=spec.stuck_spins, replace=False)
            clamp[c, pos] = rng.choice(np.array([-1, 1], dtype=np.int8), size=spec.stuck_spins)
        dead.setflags(write=False)
        clamp.setflags(write=False)
        return cls(dead=dead, clamp=clamp, mode=spec.dead_core_mode)

    @property
    def dead_cores(self) -> list[int]:
        return [int(c) for c in np.flatnonzero(self.dead)]

    def stuck(self, core: int) -> dict[int, int]:
        """Physical spin -> stuck value on ``core``."""
        return {int(i): int(self.clamp[core, i]) for i in np.flatnonzero(self.clamp[core])}


def write_failures(spec: ChipSpec, cores: np.ndarray, seed: int, attempt: int) -> np.ndarray:
    """``(T,)`` bool: whether writing the program of read ``k`` (on core ``cores[k]``) failed."""
    if spec.program_error_prob <= 0:
        return np.zeros(len(cores), dtype=bool)
    reads = np.arange(len(cores))
    key = mix(_TAG_WRITE, int(spec.seed), np.asarray(cores), np.uint64(seed), reads, attempt)
    return _uniform(key) < spec.program_error_prob


def garbage_spins(spec: ChipSpec, cores: np.ndarray, reads: np.ndarray, seed: int, n: int) -> np.ndarray:
    """``(len(reads), n)`` int8 random spins: what dead cores ``cores`` answer for reads ``reads``."""
    key = mix(_TAG_GARBAGE, int(spec.seed), np.asarray(cores)[:, None], np.uint64(seed),
              np.asarray(reads)[:, None], np.arange(n)[None, :])
    return np.where((key >> np.uint64(63)) == 1, 1, -1).astype(np.int8)
