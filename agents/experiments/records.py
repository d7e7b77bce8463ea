"""Rows of the experiments: compute columns in the paper's convention and the system's,
plan validity, per-layer columns, the result container and the CSV/JSON writers.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from planners.compute import ComputeReport

def _compute_columns(report: ComputeReport, cpu_s: float, accelerated: bool) -> dict:
    """:meth:`ComputeReport.to_record` with the measured ``cpu_s``; ``time_s`` / ``energy_j``
    are the paper's convention (Ising = accelerator only, classical = CPU) used by the figures."""
    row = report.replace(cpu_s=cpu_s).to_record(accelerated)
    row["time_s"] = row["paper_time_s"]
    row["energy_j"] = row["paper_energy_j"]
    return row


def _is_accelerated(report: ComputeReport) -> bool:
    return report.chip_calls > 0 or report.logical_calls > 0


def _mapping_of(stats: dict) -> dict | None:
    m = stats.get("mapping") if isinstance(stats, dict) else None
    return _jsonable(m) if m else None


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    return x



def _plan_valid(world, plan) -> bool:
    """``plan.success`` and the plan passes :func:`planners.plan.validate_plan`; an
    invalid plan (a planner bug) is recorded in ``plan.stats["invalid"]``, not hidden."""
    from planners.plan import PlanError, validate_plan

    if not plan.success:
        return False
    try:
        validate_plan(world, plan)
    except PlanError as exc:
        plan.stats.setdefault("invalid", str(exc))
        return False
    return True


def _layer_columns(plan) -> dict:
    """``{layer}_cpu_s``, ``{layer}_chip_calls``, ``{layer}_logical_calls`` of the
    pipeline layers a plan reports in ``plan.stats["layers"]``."""
    layers = plan.stats.get("layers", {}) if isinstance(plan.stats, dict) else {}
    cols = {}
    for layer in ("sharing", "tour", "path"):
        rep = layers.get(layer)
        if rep is not None:
            cols[f"{layer}_cpu_s"] = rep.cpu_s
            cols[f"{layer}_chip_calls"] = rep.chip_calls
            cols[f"{layer}_logical_calls"] = rep.logical_calls
    return cols


# ---------------------------------------------------------------------- running
@dataclass
class ExperimentResult:
    """Rows of one experiment (one dict per instance and method) and its settings."""

    name: str
    rows: list[dict]
    methods: tuple[str, ...]
    config: dict = field(default_factory=dict)
    wall_s: float = 0.0

    def method_rows(self, method: str) -> list[dict]:
        return [r for r in self.rows if r["method"] == method]

    def values(self, method: str, key: str, successful: bool = True) -> np.ndarray:
        vals = [r.get(key) for r in self.method_rows(method) if (r["success"] or not successful)]
        return np.array([np.nan if v is None else float(v) for v in vals], dtype=float)


def _clean(v):
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return _jsonable(v)


def write_rows(rows: list[dict], stem: Path) -> tuple[Path, Path]:
    """``stem.csv`` (``mapping`` column as JSON text) and ``stem.json``."""
    import csv

    stem.parent.mkdir(parents=True, exist_ok=True)
    cols: list[str] = []
    for r in rows:
        for k in r:
            if k not in cols:
                cols.append(k)
    csv_path, json_path = stem.with_suffix(".csv"), stem.with_suffix(".json")
    with open(csv_path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=cols)
        w.writeheader()
        for r in rows:
            w.writerow({k: (json.dumps(r[k]) if isinstance(r.get(k), (dict, list)) else r.get(k)) for k in cols})
    with open(json_path, "w") as f:
        json.dump([{k: _clean(v) for k, v in r.items()} for r in rows], f, indent=1)
    return csv_path, json_path
