"""Table 5 (mapping statistics), the per-experiment statistics beside the paper's, ``summary.md``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from agents.experiments.paper import PAPER
from agents.experiments.records import ExperimentResult
from ising_backend import MAPPING_FIELDS

def _merge_counts(acc: dict, mapping: dict | None, layer: str) -> None:
    """Add one row's ``stats["mapping"][layer]`` (:func:`ising_backend.mapping_record`) into ``acc``."""
    for choice, counts in ((mapping or {}).get(layer) or {}).items():
        slot = acc.setdefault(choice, dict.fromkeys(MAPPING_FIELDS, 0))
        for k in MAPPING_FIELDS:
            slot[k] += counts[k]


def mapping_table(path: ExperimentResult | None, sharing: ExperimentResult | None) -> list[dict]:
    """Paper Table 5 from the Ising rows' mapping statistics (one record per layer and choice, summed over
    every instance): per choice its decoded reads (``candidates``), valid reads and wins; valid rate =
    valid / reads (the pathfinding column), candidate share = reads / all reads (the sharing column), win
    share = wins / all wins."""
    rows = []
    for layer, result in (("path", path), ("sharing", sharing)):
        if result is None:
            continue
        acc: dict = {}
        for r in result.method_rows("ising"):
            _merge_counts(acc, r.get("mapping"), layer)
        total_w = sum(v["wins"] for v in acc.values())
        total_c = sum(v["reads"] for v in acc.values())
        for choice, v in acc.items():
            c, ok, w = v["reads"], v["valid"], v["wins"]
            paper = PAPER["mapping"].get((layer, choice), (None, None))
            rows.append(
                {
                    "layer": layer,
                    "choice": choice,
                    "candidates": int(c),
                    "valid": int(ok),
                    "wins": int(w),
                    "valid_rate_pct": 100.0 * ok / c if c else math.nan,
                    "candidate_share_pct": 100.0 * c / total_c if total_c else math.nan,
                    "win_share_pct": 100.0 * w / total_w if total_w else math.nan,
                    "paper_share_pct": paper[0],
                    "paper_win_share_pct": paper[1],
                }
            )
    return rows


# -------------------------------------------------------------- statistics
def _med(a) -> float:
    a = np.asarray(a, dtype=float)
    a = a[np.isfinite(a)]
    return float(np.median(a)) if len(a) else math.nan


def _mean(a) -> float:
    a = np.asarray(a, dtype=float)
    a = a[np.isfinite(a)]
    return float(np.mean(a)) if len(a) else math.nan


def _ratio(a: float, b: float) -> float:
    return a / b if b and np.isfinite(a) and np.isfinite(b) and b > 0 else math.nan


def summarize(result: ExperimentResult) -> dict:
    """The paper's statistics for one experiment, keyed like :data:`PAPER`'s entries (plus extras)."""
    r, name = result, result.name
    s: dict = {}
    ms = r.methods
    if name == "path":
        n = len(r.method_rows(ms[0]))
        for m in ms:
            ok = int(sum(x["success"] for x in r.method_rows(m)))
            s[f"{m} success"] = f"{ok}/{n}"
            s[f"{m} median path length"] = _med(r.values(m, "cost"))
        if "ising" in ms:
            classical = [m for m in ms if m != "ising"]
            s["classical success"] = f"{min(sum(x['success'] for x in r.method_rows(m)) for m in classical)}/{n}" if classical else "-"
            s["ising median chip calls"] = _med(r.values("ising", "chip_calls"))
            s["ising median chip time (ms)"] = 1e3 * _med(r.values("ising", "chip_time_s"))
            s["ising median energy (uJ)"] = 1e6 * _med(r.values("ising", "accelerator_energy_j"))
            s["ising median host cpu (ms)"] = 1e3 * _med(r.values("ising", "host_cpu_s"))
            s["ising median emulation (ms)"] = 1e3 * _med(r.values("ising", "emulation_s"))
            gap = r.values("ising", "cost") - r.values("ising", "bfs_length")
            s["ising median excess over BFS"] = _med(gap)
        if "astar" in ms:
            s["astar median time (us)"] = 1e6 * _med(r.values("astar", "cpu_s"))
            s["astar median energy (uJ)"] = 1e6 * _med(r.values("astar", "energy_j"))
            if "ising" in ms:
                s["energy ratio astar / ising"] = _ratio(s["astar median energy (uJ)"], s["ising median energy (uJ)"])
    elif name == "tour":
        for m in ms:
            s[f"{m} median gap (%)"] = _med(r.values(m, "cost"))
            s[f"{m} mean gap (%)"] = _mean(r.values(m, "cost"))
            s[f"{m} median time (ms)"] = 1e3 * _med(r.values(m, "time_s"))
        if "ising" in ms:
            s["ising median logical calls"] = _med(r.values("ising", "logical_calls"))
            s["ising median chip time (ms)"] = 1e3 * _med(r.values("ising", "chip_time_s"))
            s["ising median energy (uJ)"] = 1e6 * _med(r.values("ising", "accelerator_energy_j"))
            s["ising median host cpu (ms)"] = 1e3 * _med(r.values("ising", "host_cpu_s"))
            s["ising median emulation (ms)"] = 1e3 * _med(r.values("ising", "emulation_s"))
            if "3opt" in ms:
                e3 = 1e6 * _med(r.values("3opt", "energy_j"))
                s["3opt median energy (uJ)"] = e3
                s["energy ratio 3opt / ising"] = _ratio(e3, s["ising median energy (uJ)"])
    elif name == "sharing":
        for m in ms:
            s[f"{m} median total"] = _med(r.values(m, "cost"))
            s[f"{m} median gap to best (%)"] = _med(r.values(m, "gap_to_best"))
            s[f"{m} median gap to exact (%)"] = _med(r.values(m, "gap_to_exact"))
            s[f"{m} median makespan"] = _med(r.values(m, "makespan"))
            s[f"{m} median imbalance"] = _med(r.values(m, "imbalance"))
            s[f"{m} median energy (mJ)"] = 1e3 * _med(r.values(m, "energy_j"))
        if "ising" in ms:
            n = len(r.method_rows("ising"))
            s["ising success"] = f"{int(sum(x['success'] for x in r.method_rows('ising')))}/{n}"
            s["ising median chip calls"] = _med(r.values("ising", "chip_calls", successful=False))
            s["ising median chip batches"] = _med(r.values("ising", "chip_batches", successful=False))
            s["ising median chip time (ms)"] = 1e3 * _med(r.values("ising", "chip_time_s", successful=False))
            s["ising median energy (uJ)"] = 1e6 * _med(r.values("ising", "accelerator_energy_j", successful=False))
            s["ising median host cpu (ms)"] = 1e3 * _med(r.values("ising", "host_cpu_s", successful=False))
            s["ising median emulation (ms)"] = 1e3 * _med(r.values("ising", "emulation_s", successful=False))
            if "ssa" in ms:
                s["energy ratio ssa / ising"] = _ratio(
                    s["ssa median energy (mJ)"] * 1e3, s["ising median energy (uJ)"]
                )
    elif name == "endtoend":
        for m in ms:
            n = len(r.method_rows(m))
            s[f"{m} success"] = f"{int(sum(x['success'] for x in r.method_rows(m)))}/{n}"
            s[f"{m} median total"] = _med(r.values(m, "cost"))
            s[f"{m} median energy (mJ)"] = 1e3 * _med(r.values(m, "energy_j"))
            s[f"{m} median latency (ms)"] = 1e3 * _med(r.values(m, "time_s"))
            s[f"{m} median system energy (mJ)"] = 1e3 * _med(r.values(m, "total_energy_j"))
            s[f"{m} median host cpu (ms)"] = 1e3 * _med(r.values(m, "host_cpu_s"))
        if "ising" in ms:
            s["ising median gap to strong (%)"] = _med(r.values("ising", "gap_to_strong"))
            s["ising median emulation (ms)"] = 1e3 * _med(r.values("ising", "emulation_s"))
            s["ising median chip time, 8-core parallel (ms)"] = 1e3 * _med(r.values("ising", "chip_time_parallel_s"))
            for layer, key in (("path", "chip_calls"), ("sharing", "chip_calls"), ("tour", "logical_calls")):
                label = "chip calls" if key == "chip_calls" else "logical calls"
                s[f"ising median {layer} {label}"] = _med(r.values("ising", f"{layer}_{key}"))
            for other in ("strong", "fast"):
                if other in ms:
                    s[f"energy ratio {other} / ising"] = _ratio(
                        s[f"{other} median energy (mJ)"], s["ising median energy (mJ)"]
                    )
    return s


def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, str):
        return v
    if isinstance(v, float) and not math.isfinite(v):
        return "n/a"
    if isinstance(v, (int, np.integer)) or float(v).is_integer():
        return f"{int(v)}"
    av = abs(float(v))
    if av >= 100:
        return f"{v:.0f}"
    if av >= 1:
        return f"{v:.2f}"
    return f"{v:.3g}"


def _paper_rows(paper: dict, measured: dict) -> list[str]:
    """Rows ``| statistic | paper | measured |``: every paper statistic (``-`` where
    not measured), then the measured statistics the paper does not report."""
    rows = [f"| {key} | {_fmt(pv)} | {_fmt(measured.get(key))} |" for key, pv in paper.items()]
    rows += [f"| {key} | - | {_fmt(mv)} |" for key, mv in measured.items() if key not in paper]
    return rows


def write_summary(results: dict, mapping: list[dict], path, quick: bool, wall: dict) -> Path:
    """``summary.md``: every measured statistic beside the paper's number."""
    path = Path(path)
    lines = [
        "# Reproduction of paper section 6" + (" (quick run: small sizes, not the paper's)" if quick else ""),
        "",
        "Generated by `mrmt reproduce" + (" --quick" if quick else "") + "`.  Time and energy follow the paper's",
        "convention: classical = measured CPU wall time and 15 W x time; Ising = chip time (calls x 50 us,",
        "sequential) and accelerator energy (calls x 0.45 uJ; logical tour calls projected as chip calls).",
        "The Ising methods' host CPU time (classical glue) is listed separately as `host cpu`;",
        "the host time spent emulating the chip and the logical solver is `emulation` (not host work",
        "on a real system, whose chip time and energy are the calls x 50 us / 0.45 uJ above).",
        "",
    ]
    titles = {"path": "6.2.1 Pathfinding", "tour": "6.2.2 Tour construction", "sharing": "6.2.3 Target sharing",
              "endtoend": "6.2.4 End-to-end pipeline"}
    for name, res in results.items():
        stats = summarize(res)
        paper = PAPER[name]
        n = len(res.method_rows(res.methods[0]))
        lines += [f"## {titles[name]} ({n} instances; figure `fig_{name}.png`; rows `{name}.csv`)", "",
                  f"Settings: {json.dumps(res.config)}; wall time {wall.get(name, res.wall_s):.1f} s.", "",
                  "| statistic | paper | measured |", "|---|---|---|"]
        lines += _paper_rows(paper, stats)
        lines.append("")
    if mapping:
        lines += ["## Table 5: mapping outcomes (`mapping.csv`)", "",
                  "| layer | mapping choice | paper valid/candidate share | measured | paper win share | measured |",
                  "|---|---|---|---|---|---|"]
        for m in mapping:
            share = m["valid_rate_pct"] if m["layer"] == "path" else m["candidate_share_pct"]
            kind = "valid" if m["layer"] == "path" else "candidates"
            lines.append(
                f"| {m['layer']} | {m['choice']} | {_fmt(m['paper_share_pct'])}% {kind} | {_fmt(share)}% "
                f"| {_fmt(m['paper_win_share_pct'])}% | {_fmt(m['win_share_pct'])}% |"
            )
        lines.append("")
    path.write_text("\n".join(lines))
    return path
