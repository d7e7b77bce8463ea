"""Compute accounting for one planning call (paper section 6.1, plus the honest total).

:class:`ComputeReport`: host CPU seconds x 15 W per core (:data:`CPU_WATTS_PER_CORE`), chip calls x 50 us and
x 0.45 uJ, the emulator's own seconds apart (``emulation_s``; ``host_cpu_s = cpu_s - emulation_s``), the one-off
warm-up apart (``warmup_s``) and the fault counts (``retries``, ``fallbacks``);
``total_energy_j = accelerator_energy_j + host_energy_j``. Design notes: docs/design/pipeline.md#compute-accounting.
"""

from __future__ import annotations

import dataclasses
import time
from contextlib import contextmanager
from dataclasses import dataclass, field

__all__ = ["ComputeReport", "CPU_WATTS_PER_CORE", "RECORD_KEYS", "stopwatch"]

#: Paper 6.1: "a 15 W per-core power estimate obtained by normalizing the CPU TDP".
CPU_WATTS_PER_CORE = 15.0


@dataclass(frozen=True)
class ComputeReport:
    """What one planning call cost.  Reports add with ``+``.

    Attributes:
        cpu_s: measured host wall seconds of the planning call (all layers,
            including the Ising pipeline's classical glue).
        chip_calls: physical chip calls (one program on one core each).
        chip_batches: chip submissions (a batch holds up to ``cores`` programs).
        logical_calls: logical Ising calls, each projected as one chip call.
        chip_time_s: accelerator time with calls run one after another
            (physical + projected logical calls x 50 us: the paper's figure).
        chip_time_parallel_s: accelerator time with parallel dispatch over
            the chip's cores (per batch of up to 8 programs).
        accelerator_energy_j: (physical + projected) calls x 0.45 uJ.
        emulation_s: of ``cpu_s``, the host seconds spent emulating the
            accelerator (chip kernel and program checks, logical solver).
        retries: chip calls re-dispatched after a detected failure (faulty chips).
        fallbacks: layer calls answered by the classical fallback instead of the chip.
        warmup_s: wall seconds of the one-off warm-up (kernel compile) run before this
            plan, reported apart: not in ``cpu_s`` nor in any energy.
    """

    cpu_s: float = 0.0
    chip_calls: int = 0
    chip_batches: int = 0
    logical_calls: int = 0
    chip_time_s: float = 0.0
    chip_time_parallel_s: float = 0.0
    accelerator_energy_j: float = 0.0
    #: measured wall time, so left out of ``==`` (layer reports of one seed compare equal)
    emulation_s: float = field(default=0.0, compare=False)
    retries: int = 0
    fallbacks: int = 0
    #: measured wall time of a warm-up, left out of ``==`` like ``emulation_s``
    warmup_s: float = field(default=0.0, compare=False)

    @classmethod
    def from_ledger(cls, ledger) -> "ComputeReport":
        """The accelerator part of a report from an :class:`ising_backend.CallLedger`
        (or any object with its fields), ``cpu_s`` left 0 for the caller to measure."""
        return cls(
            chip_calls=int(ledger.physical_calls),
            chip_batches=int(ledger.batches),
            logical_calls=int(ledger.logical_calls),
            chip_time_s=float(ledger.chip_time_s),
            chip_time_parallel_s=float(ledger.chip_time_parallel_s),
            accelerator_energy_j=float(ledger.energy_j),
            emulation_s=float(ledger.emulation_s),
            retries=int(getattr(ledger, "retries", 0)),
        )

    @property
    def host_cpu_s(self) -> float:
        """Host seconds of real host work: ``cpu_s`` minus the accelerator emulation."""
        return max(self.cpu_s - self.emulation_s, 0.0)

    @property
    def host_energy_j(self) -> float:
        """Host CPU energy proxy: ``host_cpu_s`` x 15 W (one core)."""
        return self.host_cpu_s * CPU_WATTS_PER_CORE

    @property
    def total_energy_j(self) -> float:
        """Accelerator energy plus host CPU energy (the system total)."""
        return self.accelerator_energy_j + self.host_energy_j

    def __add__(self, other: "ComputeReport") -> "ComputeReport":
        if not isinstance(other, ComputeReport):
            return NotImplemented
        return ComputeReport(
            self.cpu_s + other.cpu_s, self.chip_calls + other.chip_calls, self.chip_batches + other.chip_batches,
            self.logical_calls + other.logical_calls, self.chip_time_s + other.chip_time_s,
            self.chip_time_parallel_s + other.chip_time_parallel_s,
            self.accelerator_energy_j + other.accelerator_energy_j, self.emulation_s + other.emulation_s,
            self.retries + other.retries, self.fallbacks + other.fallbacks, self.warmup_s + other.warmup_s)

    def replace(self, **changes) -> "ComputeReport":
        return dataclasses.replace(self, **changes)

    @property
    def accelerated(self) -> bool:
        """Whether any (physical or projected logical) accelerator call was made."""
        return self.chip_calls > 0 or self.logical_calls > 0

    def to_record(self, accelerated: bool | None = None) -> dict:
        """The one flat record of a report: ``mrmt plan``'s ``compute`` object and the compute
        columns of ``compare``, ``reproduce`` and the benchmarks (:data:`RECORD_KEYS`).

        Measured and derived values side by side: host time and energy (the system
        total's host part), accelerator time and energy, latency = host + chip time
        (sequential / 8-core parallel), and the paper's convention (section 6.1):
        ``paper_time_s`` / ``paper_energy_j`` are the accelerator's figures for an
        accelerated method and the CPU's for a classical one (``accelerated``:
        default :attr:`accelerated`).
        """
        acc = self.accelerated if accelerated is None else bool(accelerated)
        return {
            "cpu_s": float(self.cpu_s),
            "emulation_s": float(self.emulation_s),
            "host_cpu_s": float(self.host_cpu_s),
            "chip_calls": int(self.chip_calls),
            "chip_batches": int(self.chip_batches),
            "logical_calls": int(self.logical_calls),
            "chip_time_s": float(self.chip_time_s),
            "chip_time_parallel_s": float(self.chip_time_parallel_s),
            "latency_s": float(self.host_cpu_s + self.chip_time_s),
            "latency_parallel_s": float(self.host_cpu_s + self.chip_time_parallel_s),
            "accelerator_energy_j": float(self.accelerator_energy_j),
            "host_energy_j": float(self.host_energy_j),
            "total_energy_j": float(self.total_energy_j),
            "paper_time_s": float(self.chip_time_s if acc else self.cpu_s),
            "paper_energy_j": float(self.accelerator_energy_j if acc else self.host_energy_j),
            "retries": int(self.retries),
            "fallbacks": int(self.fallbacks),
            "warmup_s": float(self.warmup_s),
        }

    to_dict = to_record


#: Keys of :meth:`ComputeReport.to_record`, in order.
RECORD_KEYS = tuple(ComputeReport().to_record())


@contextmanager
def stopwatch():
    """``with stopwatch() as t: ...; t()`` -> elapsed wall seconds (perf_counter)."""
    start = time.perf_counter()
    end: list[float] = []

    def elapsed() -> float:
        return (end[0] if end else time.perf_counter()) - start

    try:
        yield elapsed
    finally:
        end.append(time.perf_counter())
