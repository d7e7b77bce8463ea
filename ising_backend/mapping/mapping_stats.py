"""One record of mapping statistics for every Ising layer (paper Table 5).

Contract: each layer keeps, per mapping choice (a quantization rule, a merge style, ``"logical"``), the
counts :data:`MAPPING_FIELDS` (``programs``, ``reads``, ``valid``, ``wins``, ``map_errors``) in
``stats["mapping"][layer][choice]``, plain ints in plain dicts, so the pipeline's ``merge_stats`` sums
them over calls and plans and they serialize as they are.
Design notes (the fields): docs/design/mapping_kernels.md.
"""

from __future__ import annotations

import numpy as np

__all__ = ["MAPPING_FIELDS", "mapping_record", "record_of_reads", "add_counts"]

MAPPING_FIELDS = ("programs", "reads", "valid", "wins", "map_errors")


def mapping_record(choices, rows=None) -> dict[str, dict[str, int]]:
    """``{choice: {field: count}}`` over ``choices`` in order: zeros, or ``rows`` (one per choice, its
    counts in :data:`MAPPING_FIELDS` order)."""
    choices = list(choices)
    if rows is None:
        return {c: dict.fromkeys(MAPPING_FIELDS, 0) for c in choices}
    rows = [list(r) for r in rows]
    if len(rows) != len(choices) or any(len(r) != len(MAPPING_FIELDS) for r in rows):
        raise ValueError(f"mapping rows must be {len(choices)} x {len(MAPPING_FIELDS)} ({MAPPING_FIELDS}), "
                         f"got {[len(r) for r in rows]}")
    return {c: {f: int(v) for f, v in zip(MAPPING_FIELDS, r)} for c, r in zip(choices, rows)}


def record_of_reads(choices, rows, num_reads: int) -> dict[str, dict[str, int]]:
    """:func:`mapping_record` from a kernel's per-choice rows ``(reads, valid, wins, map_errors)``: every
    program that was sent is read ``num_reads`` times."""
    return mapping_record(choices, [(r // num_reads, r, v, w, e) for r, v, w, e in np.asarray(rows).tolist()])


def add_counts(into: dict, **counts) -> None:
    """Add ``counts`` to the counters of ``into`` (a choice's record, a layer's statistics) that exist
    already: a misspelt name is a KeyError, not a new counter."""
    for name, value in counts.items():
        into[name] += int(value)
