"""Decision audit: every program a labelled decision puts on a machine, for judging what the chip is worth.

Contract: while ``with Audit(directory):`` is open, each program of every submission made with a decision
class (``machine.session(ledger, decision=CLASS)``, ``MeteredSolver(..., decision=CLASS)``) is recorded
with its class, the program as the machine took it, the machine's best energy and the charge.  Plans are
the same with and without it; closed, it records and changes nothing.  Judged by
:mod:`ising_backend.audit.judge`.  Usage: docs/audit.md; design: docs/design/machine_link.md.
"""

from __future__ import annotations

import json
from collections import Counter
from contextlib import contextmanager
from pathlib import Path

import numpy as np

__all__ = ["Audit", "active_audit", "suspended", "read_records", "read_specs", "program_arrays", "RECORDS", "SPECS"]

#: The record file of an audit directory (JSON Lines, one program per line).
RECORDS = "decisions.jsonl"
#: The chip spec each class's programs went to (JSON object: class -> spec fields).
SPECS = "specs.json"
_ACTIVE: list = []


def active_audit() -> "Audit | None":
    """The open audit, or ``None`` (the common case: then nothing is recorded)."""
    return _ACTIVE[-1] if _ACTIVE else None


@contextmanager
def suspended():
    """No audit within (a pipeline's warm-up run on a scratch copy is not a decision of the plan)."""
    held = list(_ACTIVE)
    _ACTIVE.clear()
    try:
        yield
    finally:
        _ACTIVE[:] = held


class Audit:
    """An audit directory open for recording (module docstring); ``counts`` per class."""

    def __init__(self, directory):
        self.directory = Path(directory)
        if self.directory.exists() and not self.directory.is_dir():
            raise ValueError(f"audit directory {str(self.directory)!r} is a file")
        self.directory.mkdir(parents=True, exist_ok=True)
        self.counts: Counter = Counter()
        self.specs: dict = {}  # class -> the spec of the machine its programs went to (the first seen)
        self._file = None

    def __enter__(self) -> "Audit":
        if _ACTIVE:
            raise RuntimeError("an audit is open already; audits do not nest")
        self._file = open(self.directory / RECORDS, "a", encoding="utf-8")
        _ACTIVE.append(self)
        return self

    def __exit__(self, *exc) -> None:
        _ACTIVE.remove(self)
        self._file.close()
        self._file = None
        path = self.directory / SPECS
        known = json.loads(path.read_text()) if path.is_file() else {}
        path.write_text(json.dumps({**self.specs, **known}, indent=1))

    def record(self, decision: str, h, J, spins, energies=None, charge=None, logical: bool = False,
               host: tuple[np.ndarray, float, str] | None = None, spec=None) -> None:
        """Programs ``h (B, n)``, ``J (B, n, n)`` and the machine's ``spins (B, reads, n)`` (``energies``
        ``(B, reads)``, computed if not given) of one submission of class ``decision``; ``charge``
        the submission's :class:`~ising_backend.ledger.CallLedger`; ``host``: the class's own host
        rule as ``(energies (B,), seconds per program, rule name)``; ``spec`` the machine's
        :class:`~ising_backend.spec.ChipSpec` (the benchmark export names what the problems fit)."""
        if self._file is None:
            raise RuntimeError("the audit is not open")
        if spec is not None and decision not in self.specs:
            self.specs[decision] = {**spec.to_dict(), "logical": bool(logical)}
        h = np.asarray(h, dtype=np.float64)
        J = np.asarray(J, dtype=np.float64)
        spins = np.asarray(spins)
        if h.ndim == 1:
            h, J, spins = h[None], J[None], spins[None]
        B = h.shape[0]
        if not B:
            return
        if energies is None:
            from ising_backend.faults.health import program_energy

            energies = program_energy(h, J, spins)
        energies = np.asarray(energies, dtype=np.float64).reshape(B, -1)
        reads = spins.shape[1]
        calls = 0 if charge is None else (charge.logical_calls if logical else charge.physical_calls)
        chip_s = 0.0 if charge is None else charge.chip_time_s / B
        emu_s = 0.0 if charge is None else charge.emulation_s / B
        for b in range(B):
            i, j = np.nonzero(np.triu(J[b], 1))
            best = int(np.argmin(energies[b]))
            row = {"class": decision, "n": int(h.shape[1]), "h": h[b].tolist(),
                   "J": [[int(a), int(c), float(J[b, a, c])] for a, c in zip(i.tolist(), j.tolist())],
                   "chip_energy": float(energies[b, best]), "chip_spins": spins[b, best].astype(int).tolist(),
                   "reads": int(reads), "calls": int(calls) // B if B else 0, "chip_s": chip_s,
                   "emulation_s": emu_s, "logical": bool(logical)}
            if host is not None:
                row.update(host_energy=float(host[0][b]), host_s=float(host[1]), host_rule=host[2])
            self._file.write(json.dumps(row, separators=(",", ":")) + "\n")
        self.counts[decision] += B
        self._file.flush()


def read_records(directory):
    """The records of an audit directory, in order (dicts as :meth:`Audit.record` wrote them); a missing
    directory or file, or a line that is not a record, is a ``ValueError`` naming it."""
    path = Path(directory) / RECORDS
    if not path.is_file():
        raise ValueError(f"{str(directory)!r} holds no audit ({RECORDS} not found): record one with --audit DIR")
    out = []
    with open(path, encoding="utf-8") as f:
        for k, line in enumerate(f, 1):
            try:
                row = json.loads(line)
                if not isinstance(row, dict) or not {"class", "n", "h", "J", "chip_energy"} <= set(row):
                    raise ValueError("not an audit record")
            except ValueError as exc:
                raise ValueError(f"{path}:{k}: {exc}") from None
            out.append(row)
    return out


def read_specs(directory) -> dict:
    """Class -> the spec fields its programs fit (empty if none was recorded)."""
    path = Path(directory) / SPECS
    return json.loads(path.read_text()) if path.is_file() else {}


def program_arrays(row) -> tuple[np.ndarray, np.ndarray]:
    """``h (n,)``, ``J (n, n)`` (upper triangular) of one record."""
    n = int(row["n"])
    h = np.asarray(row["h"], dtype=np.float64)
    J = np.zeros((n, n))
    for i, j, v in row["J"]:
        J[int(i), int(j)] = v
    return h, J
