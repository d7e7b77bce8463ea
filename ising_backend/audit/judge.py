"""Judging an audit: each recorded program's optimum, the host rule's answer, one row per decision class.

Contract: :func:`judge` gives each record its optimum (exact up to ``exact_max`` active spins, else a long
tabu run labelled ``"tabu"``; lowered to a lower chip or host energy, a best-known) and the host rule's
answer (:func:`greedy_descent`, unless the class recorded its own); :func:`table` gives one row per
class, gaps relative to ``max(|optimum|, 1)``.  :func:`export` writes the QUBO benchmark.
Usage: docs/audit.md; design: docs/design/machine_link.md.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numba
import numpy as np

from ising_backend.audit.record import program_arrays
from ising_backend.machines.tabu import tabu_kernel

__all__ = ["exact_ground", "greedy_descent", "judge", "table", "export", "load_benchmark", "EXACT_MAX"]

#: Most active spins solved exactly by default (2^20 states, ~10 ms each).
EXACT_MAX = 20
_EPS = 1e-9


@numba.njit(cache=True)
def exact_ground(h, J):
    """``(energy, spins)``: a ground state of ``h (n,)``, ``J (n, n)`` upper triangular by Gray-code
    enumeration (``n <= 30``; ``2^n`` states)."""
    n = h.shape[0]
    W = J + J.T
    s = -np.ones(n)
    field = h.copy()  # dE/ds_i / 1: local field h_i + sum_j W_ij s_j
    for i in range(n):
        for j in range(n):
            field[i] -= W[i, j]
    e = 0.0
    for i in range(n):
        e -= h[i]
        for j in range(i + 1, n):
            e += J[i, j]
    best = e
    best_s = s.copy()
    for k in range(1, 1 << n):
        i = 0
        while not (k >> i) & 1:
            i += 1
        e -= 2.0 * s[i] * field[i]
        s[i] = -s[i]
        for j in range(n):
            if j != i:
                field[j] += 2.0 * W[j, i] * s[i]
        if e < best - 1e-12:
            best = e
            best_s[:] = s
    return best, best_s


@numba.njit(cache=True)
def greedy_descent(h, J):
    """``(energy, spins)`` of the generic host rule (module docstring)."""
    n = h.shape[0]
    W = J + J.T
    weight = np.abs(h).copy()
    for i in range(n):
        for j in range(n):
            weight[i] += abs(W[i, j])
    order = np.argsort(-weight, kind="mergesort")
    s = np.zeros(n)
    for i in order:
        f = h[i]
        for j in range(n):
            f += W[i, j] * s[j]
        s[i] = -1.0 if f > 0 else 1.0
    field = h.copy()
    for i in range(n):
        for j in range(n):
            field[i] += W[i, j] * s[j]
    while True:
        gain, at = 0.0, -1
        for i in range(n):
            d = -2.0 * s[i] * field[i]
            if d < gain - 1e-12:
                gain, at = d, i
        if at < 0:
            break
        s[at] = -s[at]
        for j in range(n):
            if j != at:
                field[j] += 2.0 * W[j, at] * s[at]
    e = 0.0
    for i in range(n):
        e += h[i] * s[i]
        for j in range(i + 1, n):
            e += J[i, j] * s[i] * s[j]
    return e, s


def _active(h, J) -> np.ndarray:
    return np.flatnonzero((h != 0) | (J != 0).any(axis=0) | (J != 0).any(axis=1))


def _tabu_best(h, J) -> float:
    n = h.shape[0]
    reads = 8
    spins = np.empty((1, reads, n), dtype=np.int8)
    energies = np.empty((1, reads))
    tabu_kernel(h[None], J[None], reads, np.uint64(12345), 16, 200 * n, min(10, max(1, n // 4)), spins, energies)
    return float(energies.min())


def judge(records, exact_max: int = EXACT_MAX) -> list[dict]:
    """Per record: ``class``, ``optimum``, ``optimum_kind`` (``exact`` / ``tabu`` / ``best-known``), ``chip_energy``,
    ``host_energy``, ``host_rule``, ``host_s``, ``chip_s``."""
    out = []
    greedy_descent(np.zeros(1), np.zeros((1, 1)))  # compiled before any is timed
    for row in records:
        h, J = program_arrays(row)
        a = _active(h, J)
        ha, Ja = np.ascontiguousarray(h[a]), np.ascontiguousarray(J[np.ix_(a, a)])
        if "host_energy" in row:
            host_e, host_s, rule = row["host_energy"], row["host_s"], row["host_rule"]
        else:
            t0 = time.perf_counter()
            host_e = float(greedy_descent(ha, Ja)[0]) if a.size else 0.0
            host_s, rule = time.perf_counter() - t0, "greedy+descent"
        if a.size <= exact_max:
            opt, kind = (float(exact_ground(ha, Ja)[0]) if a.size else 0.0), "exact"
        else:
            opt, kind = _tabu_best(ha, Ja), "tabu"
        chip = float(row["chip_energy"])
        if min(chip, host_e) < opt - _EPS:
            if kind == "exact":
                raise AssertionError(f"an answer below the exact optimum ({min(chip, host_e)} < {opt})")
            opt, kind = min(chip, host_e), "best-known"
        out.append({"class": row["class"], "optimum": opt, "optimum_kind": kind, "chip_energy": chip,
                    "host_energy": float(host_e), "host_rule": rule, "host_s": float(host_s),
                    "chip_s": float(row.get("chip_s", 0.0)), "n": int(a.size)})
    return out


def table(judged) -> list[dict]:
    """One row per class (first-seen order): ``class``, ``decisions``, ``chip_better``, ``chip_worse`` (shares),
    ``chip_gap``, ``host_gap`` (means, fractions of ``max(|optimum|, 1)``), ``chip_s``, ``host_s`` (mean
    seconds per decision), ``host_rule``, ``exact`` (share of decisions with an exact optimum)."""
    by: dict = {}
    for r in judged:
        by.setdefault(r["class"], []).append(r)
    rows = []
    for cls, rs in by.items():
        scale = np.array([max(abs(r["optimum"]), 1.0) for r in rs])
        opt = np.array([r["optimum"] for r in rs])
        chip = np.array([r["chip_energy"] for r in rs])
        host = np.array([r["host_energy"] for r in rs])
        rows.append({"class": cls, "decisions": len(rs),
                     "chip_better": float(np.mean(chip < host - _EPS)), "chip_worse": float(np.mean(chip > host + _EPS)),
                     "chip_gap": float(np.mean((chip - opt) / scale)), "host_gap": float(np.mean((host - opt) / scale)),
                     "chip_s": float(np.mean([r["chip_s"] for r in rs])),
                     "host_s": float(np.mean([r["host_s"] for r in rs])),
                     "host_rule": ", ".join(sorted({r["host_rule"] for r in rs})),
                     "exact": float(np.mean([r["optimum_kind"] == "exact" for r in rs]))})
    return rows


def export(records, judged, out, specs: dict | None = None) -> dict:
    """Each class's problems as a benchmark set ``OUT/CLASS.jsonl``: per line a dimod BQM (SPIN,
    ``BinaryQuadraticModel.to_serializable()``), ``optimum`` and ``optimum_kind``, the host rule's energy
    and name, the chip's energy, and the chip spec the problems fit (``specs[class]``; a logical class
    fits the spin count, not the coefficient range).  Returns counts per class."""
    import dimod

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files, counts = {}, {}
    try:
        for row, j in zip(records, judged):
            cls = row["class"]
            if cls not in files:
                files[cls] = open(out / f"{cls}.jsonl", "w", encoding="utf-8")
            h, J = program_arrays(row)
            i, k = np.nonzero(J)
            bqm = dimod.BinaryQuadraticModel.from_numpy_vectors(h, (i, k, J[i, k]), 0.0, dimod.SPIN)
            line = {"bqm": bqm.to_serializable(), "optimum": j["optimum"], "optimum_kind": j["optimum_kind"],
                    "host_energy": j["host_energy"], "host_rule": j["host_rule"], "chip_energy": j["chip_energy"],
                    "logical": bool(row.get("logical", False)), "spec": (specs or {}).get(cls)}
            files[cls].write(json.dumps(line, separators=(",", ":")) + "\n")
            counts[cls] = counts.get(cls, 0) + 1
    finally:
        for f in files.values():
            f.close()
    return counts


def load_benchmark(path):
    """The problems of one exported class file: a list of ``(bqm, record)`` (``record`` without the BQM)."""
    import dimod

    out = []
    with open(path, encoding="utf-8") as f:
        for k, line in enumerate(f, 1):
            try:
                row = json.loads(line)
                bqm = dimod.BinaryQuadraticModel.from_serializable(row.pop("bqm"))
            except (ValueError, KeyError, TypeError) as exc:
                raise ValueError(f"{path}:{k}: not a benchmark problem ({exc})") from None
            out.append((bqm, row))
    return out
