"""Graceful degradation of a faulty chip: health probe, quarantine, spin remapping, retries.

Contract: with a fault model on, every chip call goes through :func:`dispatch`: reads round-robin over
the cores not quarantined, failed reads (write error, timeout) charged and re-dispatched within
``spec.max_retries`` rounds, else :class:`ChipUnavailableError` (after charging).
:meth:`HealthMonitor.probe` finds dead cores and stuck spins at bring-up; programs of up to
:attr:`HealthMonitor.usable_spins` spins never meet a known stuck spin.  Design notes: docs/design/faults.md.
"""

from __future__ import annotations

import time

import numpy as np

from ising_backend.faults.model import FaultMap, garbage_spins, mix, write_failures
from ising_backend.spec import ChipSpec

__all__ = ["ChipUnavailableError", "SolverOutputError", "HealthMonitor", "dispatch", "emulate", "program_energy",
           "PROBE_READS"]

#: Reads of each probe program (one per polarity) on every core.
PROBE_READS = 4
#: A core whose probe reads get more than this share of spins wrong is dead.
DEAD_ERROR_RATE = 0.25


class ChipUnavailableError(RuntimeError):
    """The chip could not answer a call: every core is quarantined, or reads kept failing
    (write errors, timeouts) after ``spec.max_retries`` re-dispatch rounds."""


class SolverOutputError(RuntimeError):
    """A solver's answer is not a (programs, reads, spins) array of +-1."""


def emulate(spec: ChipSpec, faults: FaultMap, cores: np.ndarray, seed: int, attempt: int,
            spins: np.ndarray, energies: np.ndarray, h: np.ndarray, J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The hardware faults of one round, in place: reads ``k`` (flat over ``spins (M, R, n)``) ran on
    ``cores[k]``.  Dead cores in garbage mode overwrite their reads with random spins (energies
    recomputed on ``h``, ``J``).  Returns the detectable flags ``(write_failed, timed_out)``, ``(M*R,)``."""
    M, R, n = spins.shape
    failed = write_failures(spec, cores, seed, attempt)
    on_dead = faults.dead[cores]
    timed_out = on_dead & ~failed if faults.mode == "timeout" else np.zeros(len(cores), dtype=bool)
    if faults.mode == "garbage" and on_dead.any() and n:
        k = np.flatnonzero(on_dead)
        flat = spins.reshape(M * R, n)
        flat[k] = garbage_spins(spec, cores[k], k, seed, n)
        energies.reshape(-1)[k] = program_energy(h[k // R], J[k // R], flat[k])
    return failed, timed_out


def program_energy(h: np.ndarray, J: np.ndarray, spins: np.ndarray) -> np.ndarray:
    """``E_k = h_k . s_k + sum_{i != j} J_kij s_ki s_kj`` (diagonal ignored) of rows ``k``, without offset;
    ``spins`` ``(k, n)`` gives ``(k,)``, ``(k, reads, n)`` gives ``(k, reads)``."""
    s = spins.astype(np.float64)
    if s.ndim == 3:
        return (np.einsum("kri,ki->kr", s, h) + np.einsum("kri,kij,krj->kr", s, J, s)
                - np.einsum("kii->k", J)[:, None])
    return (np.einsum("ki,ki->k", h, s) + np.einsum("ki,kij,kj->k", s, J, s)
            - np.einsum("kii->k", J))


class HealthMonitor:
    """What the driver knows about the cores: quarantine, stuck spins, counters (module docstring)."""

    def __init__(self, spec: ChipSpec, faults: FaultMap, mismatch: np.ndarray):
        self.spec = spec
        self.faults = faults
        C, N = spec.n_cores, spec.n_spins
        self.quarantined = np.zeros(C, dtype=bool)
        self.reasons: dict[int, str] = {}
        self.known_stuck = np.zeros((C, N), dtype=np.int8)
        self.counts = {"probe_calls": 0, "write_errors": 0, "timeouts": 0, "retries": 0, "unavailable": 0}
        #: ``(programs, reads)``: the core that answered each read of the last dispatched call
        self.last_cores = np.zeros((0, 0), dtype=np.int64)
        self._raw_mismatch = mismatch
        self._arrays()

    # ------------------------------------------------------------------ state
    @property
    def healthy(self) -> np.ndarray:
        """Indices of the cores work may go to."""
        return self._healthy

    @property
    def usable_spins(self) -> int:
        """Spins a program may use on every healthy core without touching a known stuck spin."""
        return self._usable

    def quarantine(self, core: int, reason: str) -> None:
        if not self.quarantined[core]:
            self.quarantined.setflags(write=True)
            self.quarantined[core] = True
            self.reasons[int(core)] = reason
            self._state()

    def _state(self) -> None:
        """The healthy cores and usable spins, recomputed where quarantine or known stuck spins change
        (both arrays are read-only in between, so nothing else can change them)."""
        self.quarantined.setflags(write=False)
        self.known_stuck.setflags(write=False)
        self._healthy = h = np.flatnonzero(~self.quarantined)
        self._healthy.setflags(write=False)
        self._usable = int(self.spec.n_spins) if not len(h) else \
            int(self.spec.n_spins - (self.known_stuck[h] != 0).sum(axis=1).max())

    def placement(self, core: int) -> np.ndarray:
        """Physical spin of each logical spin on ``core``: good spins first, known stuck ones last."""
        stuck = self.known_stuck[core] != 0
        return np.concatenate([np.flatnonzero(~stuck), np.flatnonzero(stuck)])

    def _arrays(self) -> None:
        """Per core, the stuck values and mismatch factors as the logical spins see them."""
        self._state()
        C = self.spec.n_cores
        perms = [self.placement(c) for c in range(C)]
        self.clamp = np.ascontiguousarray(np.stack([self.faults.clamp[c, perms[c]] for c in range(C)]))
        mm = self._raw_mismatch
        self.mismatch = mm if not mm.size else np.ascontiguousarray(
            np.stack([mm[c][np.ix_(perms[c], perms[c])] for c in range(C)]))

    def summary(self) -> dict:
        """Quarantined cores (with reasons), known stuck spins per core, counters."""
        stuck = {int(c): {int(i): int(self.known_stuck[c, i]) for i in np.flatnonzero(self.known_stuck[c])}
                 for c in range(self.spec.n_cores) if self.known_stuck[c].any()}
        return {"quarantined": dict(sorted(self.reasons.items())), "healthy": self.healthy.tolist(),
                "usable_spins": self.usable_spins, "stuck": stuck, **self.counts}

    # ------------------------------------------------------------------ probe
    def probe(self, run, charge) -> None:
        """Known-answer test of every core (raw placement): fields ``-m * p`` with ``m`` the largest
        field, no couplings, ground state ``p`` (all +1, then all -1), :data:`PROBE_READS` reads of each
        on every core.  ``run(h, J, reads, seed, cores, raw=True)`` anneals; ``charge(calls, seconds,
        retries, probe)`` records.  Quarantines dead cores and learns stuck spins."""
        spec = self.spec
        C, N, P = spec.n_cores, spec.n_spins, PROBE_READS
        m = min(-spec.h_range[0], spec.h_range[1])
        h = np.stack([-m * np.ones(N), m * np.ones(N)]).astype(np.int64)
        J = np.zeros((2, N, N), dtype=np.int64)
        expect = np.array([1, -1])
        R = C * P
        cores = np.tile(np.repeat(np.arange(C), P), 2)
        seed = int(mix(int(spec.seed), 0x9B0BE))
        seen = np.zeros(2 * R, dtype=bool)
        wrong = np.zeros((2 * R, N), dtype=bool)
        todo = np.arange(2 * R)
        for attempt in range(spec.max_retries + 1):
            t0 = time.perf_counter()
            sub = seed if attempt == 0 else int(mix(seed, attempt))
            prog = todo // R
            spins, energies = run(h[prog], J[prog], 1, sub, cores[todo], True)
            failed, timed_out = emulate(spec, self.faults, cores[todo], sub, attempt, spins, energies, h[prog], J[prog])
            charge(len(todo), time.perf_counter() - t0, 0 if attempt == 0 else len(todo), len(todo))
            self.counts["probe_calls"] += len(todo)
            self.counts["write_errors"] += int(failed.sum())
            self.counts["timeouts"] += int(timed_out.sum())
            for c in np.unique(cores[todo][timed_out]):
                self.quarantine(int(c), "timed out in the health probe")
            ok = ~failed & ~timed_out
            seen[todo[ok]] = True
            wrong[todo[ok]] = spins[ok, 0, :] != expect[prog[ok], None]
            todo = todo[failed]
            if not len(todo):
                break
        for c in range(C):
            if self.quarantined[c]:
                continue
            rows = np.flatnonzero((cores == c) & seen)
            if not len(rows):
                continue
            rate = float(wrong[rows].mean())
            if rate > DEAD_ERROR_RATE:
                self.quarantine(c, f"health probe: {rate:.0%} of spins wrong on a known-answer program")
                continue
            for b, p in enumerate(expect):
                r = rows[rows // R == b]
                if len(r):
                    stuck = wrong[r].mean(axis=0) > 0.5  # reads -p where the field forces p
                    self.known_stuck.setflags(write=True)
                    self.known_stuck[c, stuck] = -p
        self._arrays()


def dispatch(monitor: HealthMonitor, h: np.ndarray, J: np.ndarray, num_reads: int, seed: int, run, charge,
             what: str = "chip") -> tuple[np.ndarray, np.ndarray]:
    """Run ``B`` programs x ``num_reads`` reads on the healthy cores with re-dispatch (module docstring).

    ``run(h, J, reads, seed, cores, raw=False)`` -> ``(spins (M, reads, n), energies (M, reads))``;
    ``charge(calls, seconds, retries, probe)`` records one round.  Returns ``spins``, ``energies``.
    """
    spec = monitor.spec
    B, n = h.shape[0], h.shape[1]
    R = num_reads
    healthy = monitor.healthy
    if not len(healthy):
        monitor.counts["unavailable"] += 1
        raise ChipUnavailableError(f"{what}: every core is quarantined ({_reasons(monitor)})")
    t0 = time.perf_counter()
    cores = _assign(healthy, B * R, seed)
    spins, energies = run(h, J, R, seed, cores, False)
    failed, timed_out = emulate(spec, monitor.faults, cores, seed, 0, spins, energies, h, J)
    charge(B * R, time.perf_counter() - t0, 0, 0)
    flat_s = spins.reshape(B * R, n)
    flat_e = energies.reshape(-1)
    todo = np.arange(B * R)
    monitor.last_cores = where = cores.reshape(B, R).copy()
    for attempt in range(1, spec.max_retries + 2):
        bad = failed | timed_out
        if not bad.any():
            return spins, energies
        monitor.counts["write_errors"] += int(failed.sum())
        monitor.counts["timeouts"] += int(timed_out.sum())
        for c in np.unique(cores[timed_out]):
            monitor.quarantine(int(c), "timed out")
        todo = todo[bad]
        healthy = monitor.healthy
        if attempt > spec.max_retries or not len(healthy):
            monitor.counts["unavailable"] += 1
            why = (f"every core is quarantined ({_reasons(monitor)})" if not len(healthy) else
                   f"{len(todo)} call(s) still failing (write errors / timeouts) after max_retries = "
                   f"{spec.max_retries} re-dispatch rounds")
            raise ChipUnavailableError(f"{what}: {why}")
        t0 = time.perf_counter()
        sub = int(mix(seed, attempt))
        cores = _assign(healthy, len(todo), sub)
        prog = todo // R
        s, e = run(h[prog], J[prog], 1, sub, cores, False)
        failed, timed_out = emulate(spec, monitor.faults, cores, sub, attempt, s, e, h[prog], J[prog])
        charge(len(todo), time.perf_counter() - t0, len(todo), 0)
        monitor.counts["retries"] += len(todo)
        flat_s[todo] = s[:, 0]
        flat_e[todo] = e[:, 0]
        where.reshape(-1)[todo] = cores
    raise AssertionError("unreachable")  # pragma: no cover


def _assign(healthy: np.ndarray, reads: int, seed: int) -> np.ndarray:
    """Core of each read: round-robin over ``healthy`` from an offset drawn from the call seed (all
    cores healthy and offset 0 would be ``k % n_cores``, the fault-free assignment)."""
    offset = int(mix(seed, 0xC0E) % np.uint64(len(healthy)))
    return healthy[(offset + np.arange(reads)) % len(healthy)]


def _reasons(monitor: HealthMonitor) -> str:
    return "; ".join(f"core {c}: {r}" for c, r in sorted(monitor.reasons.items())) or "none"
