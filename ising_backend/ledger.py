"""Call ledger: physical chip calls, logical (projected) calls, time and energy (paper section 6.1).

Contract: :class:`CallLedger` counts an ``anneal_batch`` of ``B`` programs x ``r`` reads as ``B * r``
physical calls in ``ceil(B * r / n_cores)`` batches, each charged the spec's solve time and energy; a
logical call is projected as one chip call (``logical_calls``); a faulty chip's retries and probe calls
are counted, and ``emulation_s`` (host time spent emulating the accelerator) is reported apart.
Accounting: ARCHITECTURE.md ("Chip call accounting"); design notes: docs/design/emulated_chip.md.
"""

from __future__ import annotations

import math
import weakref
from functools import reduce
from operator import add
from dataclasses import asdict, dataclass, fields

from ising_backend.spec import ChipSpec

__all__ = ["CallLedger"]


@dataclass
class CallLedger:
    """Running totals of accelerator use.  Ledgers add with ``+``.

    ``snapshot()`` freezes the current totals; ``since(snapshot)`` returns the
    ledger of what happened after it (handy to charge one planning layer).
    ``since`` is exact: while a snapshot is alive the ledger also sums every
    charge made after it from zero, so the same calls give bit-identical
    times and energies however much the ledger had charged before (a
    difference of running float totals would not).
    """

    physical_calls: int = 0
    batches: int = 0
    logical_calls: int = 0
    logical_batches: int = 0
    chip_time_s: float = 0.0
    chip_time_parallel_s: float = 0.0
    energy_j: float = 0.0
    emulation_s: float = 0.0
    retries: int = 0
    probe_calls: int = 0

    #: live snapshots, each carrying the exact sum of the charges made after it (made on first use)
    _taps = None

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state.pop("_taps", None)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)

    def record_physical(self, calls: int, spec: ChipSpec, seconds: float = 0.0, *, cores: int | None = None,
                        retries: int = 0, probe_calls: int = 0) -> "CallLedger":
        """Charge ``calls`` physical calls dispatched together (``seconds`` of host
        emulation time) over ``cores`` parallel cores (default ``spec.n_cores``), of which
        ``retries`` re-dispatch failed calls and ``probe_calls`` are health probes; returns
        this call's ledger."""
        return self._record(calls, spec, seconds, logical=False, cores=cores, retries=retries, probe_calls=probe_calls)

    def record_logical(self, calls: int, spec: ChipSpec, seconds: float = 0.0, *, cores: int | None = None,
                       retries: int = 0) -> "CallLedger":
        """Charge ``calls`` logical calls issued together, each projected as one chip call."""
        return self._record(calls, spec, seconds, logical=True, cores=cores, retries=retries)

    def record_each(self, calls, seconds, spec: ChipSpec, logical: bool = False) -> list["CallLedger"]:
        """Charge submissions one after another (``calls[i]`` calls, ``seconds[i]`` emulation
        seconds each), exactly as that many ``record_physical`` / ``record_logical`` calls."""
        return [self._record(c, spec, float(t), logical) for c, t in zip(calls, seconds)]

    def record_into(self, calls, seconds, spec: ChipSpec, into: "CallLedger", logical: bool = False) -> "CallLedger | None":
        """:meth:`record_each` for a caller that adds every submission's ledger to ``into``: each
        submission is charged in order to this ledger, its live snapshots and ``into`` (the same
        float additions, so the same bits), without a ledger object per submission.  Returns the
        last submission's ledger (``None`` for no submission)."""
        kind = getattr(getattr(calls, "dtype", None), "kind", None)
        calls = calls.tolist() if kind in ("i", "u") else [int(c) for c in calls]
        kind = getattr(getattr(seconds, "dtype", None), "kind", None)
        seconds = seconds.tolist() if kind == "f" else [float(t) for t in seconds]
        if len(calls) != len(seconds):
            raise ValueError(f"record_into: {len(calls)} call counts for {len(seconds)} emulation times")
        if not calls:
            return None
        if min(calls) < 0:
            raise ValueError(f"calls = {min(calls)} must be >= 0")
        ck, bk = ("logical_calls", "logical_batches") if logical else ("physical_calls", "batches")
        totals = [self.__dict__, into.__dict__]
        if self._taps:
            totals += [snap._charged_since.__dict__ for snap in list(self._taps.values())]
        n_cores, solve_s, energy = spec.n_cores, spec.solve_time_s, spec.energy_per_call_j
        batches = [math.ceil(c / n_cores) for c in calls]
        ct = [c * solve_s for c in calls]
        pt = [b * solve_s for b in batches]
        en = [c * energy for c in calls]
        if len({id(d) for d in totals}) == len(totals):  # each total on its own: the same additions in order
            n_calls, n_batches = sum(calls), sum(batches)
            for d in totals:
                d[ck] += n_calls
                d[bk] += n_batches
                d["chip_time_s"] = reduce(add, ct, d["chip_time_s"])  # ((total + a0) + a1) + ...: no compensation
                d["chip_time_parallel_s"] = reduce(add, pt, d["chip_time_parallel_s"])
                d["energy_j"] = reduce(add, en, d["energy_j"])
                d["emulation_s"] = reduce(add, seconds, d["emulation_s"])
        else:  # a ledger charged twice: submission by submission
            for i in range(len(calls)):
                for d in totals:
                    d[ck] += calls[i]
                    d[bk] += batches[i]
                    d["chip_time_s"] += ct[i]
                    d["chip_time_parallel_s"] += pt[i]
                    d["energy_j"] += en[i]
                    d["emulation_s"] += seconds[i]
        return CallLedger(**{ck: calls[-1], bk: batches[-1]}, chip_time_s=ct[-1], chip_time_parallel_s=pt[-1],
                          energy_j=en[-1], emulation_s=seconds[-1])

    def _record(self, calls: int, spec: ChipSpec, seconds: float, logical: bool, cores: int | None = None,
                retries: int = 0, probe_calls: int = 0) -> "CallLedger":
        """Charge ``calls`` chip calls (physical, or logical when ``logical``); returns the delta."""
        calls = int(calls)
        if calls < 0:
            raise ValueError(f"calls = {calls} must be >= 0")
        batches = math.ceil(calls / (spec.n_cores if cores is None else max(int(cores), 1)))
        counts = (
            {"logical_calls": calls, "logical_batches": batches}
            if logical
            else {"physical_calls": calls, "batches": batches}
        )
        delta = CallLedger(
            **counts,
            chip_time_s=calls * spec.solve_time_s,
            chip_time_parallel_s=batches * spec.solve_time_s,
            energy_j=calls * spec.energy_per_call_j,
            emulation_s=float(seconds),
            retries=int(retries),
            probe_calls=int(probe_calls),
        )
        self._add_in_place(delta)
        if self._taps:
            for snap in list(self._taps.values()):
                snap._charged_since._add_in_place(delta)
        return delta

    def _add_in_place(self, other: "CallLedger") -> None:
        d, o = self.__dict__, other.__dict__
        for name in _FIELDS:
            d[name] += o[name]

    def __add__(self, other: "CallLedger") -> "CallLedger":
        if not isinstance(other, CallLedger):
            return NotImplemented
        return CallLedger(**{f.name: getattr(self, f.name) + getattr(other, f.name) for f in fields(self)})

    def __sub__(self, other: "CallLedger") -> "CallLedger":
        if not isinstance(other, CallLedger):
            return NotImplemented
        return CallLedger(**{f.name: getattr(self, f.name) - getattr(other, f.name) for f in fields(self)})

    def snapshot(self) -> "CallLedger":
        """A copy of the current totals (also the mark for :meth:`since`)."""
        snap = CallLedger(**asdict(self))
        snap._charged_since = CallLedger()
        if self._taps is None:
            self._taps = weakref.WeakValueDictionary()
        self._taps[id(snap)] = snap
        return snap

    def since(self, snapshot: "CallLedger") -> "CallLedger":
        """What was charged after ``snapshot`` was taken (exact for this ledger's snapshots)."""
        if self._taps is not None and self._taps.get(id(snapshot)) is snapshot:
            return CallLedger(**asdict(snapshot._charged_since))
        return self - snapshot

    @property
    def total_calls(self) -> int:
        """Physical plus projected logical calls."""
        return self.physical_calls + self.logical_calls

    def to_dict(self) -> dict:
        return asdict(self)


_FIELDS = tuple(f.name for f in fields(CallLedger))
