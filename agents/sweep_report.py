"""What a chip sweep says: per-spec statistics, Pareto fronts, the figure and ``summary.md``.

Per (controller, spec): success rate; mean route cost and, when a chip-free reference
controller ran (``strong`` by default), the mean paired gap to it (%) over the worlds both
solved; medians of chip calls, accelerator energy, host energy, system energy, chip latency
(parallel dispatch) and system latency (host + chip).  A spec is on the Pareto front of
(cost, x) when it solved every world and no other such spec is at least as good in both with
one strictly better.  The figure sets the paper's convention (accelerator energy) beside the
system totals (host included), with the classical reference drawn on the same axes.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

__all__ = ["spec_stats", "pareto_front", "plot_pareto", "write_summary", "write_report"]

#: (statistic, axis label) of the figure's panels.
PANELS = (
    ("accelerator_energy_j", "accelerator energy per plan (J, paper convention)"),
    ("chip_time_parallel_s", "chip latency per plan (s, parallel cores; paper convention)"),
    ("total_energy_j", "system energy per plan (J, host + accelerator)"),
    ("latency_parallel_s", "system latency per plan (s, host + chip over the cores)"),
)


def _median(vals) -> float:
    vals = [float(v) for v in vals if v is not None and not (isinstance(v, float) and math.isnan(v))]
    return float(np.median(vals)) if vals else math.nan


def spec_stats(result, reference: str | None = "strong") -> list[dict]:
    """One dict per (chip controller, spec) and per chip-free controller (``spec_id`` -1)."""
    rows = result.rows
    ref = {(r["world_seed"], r["seed"]): r["route_cost"] for r in rows
           if r["controller"] == reference and r.get("is_success")}
    groups: dict = {}
    for r in rows:
        groups.setdefault((r["controller"], r["spec_id"]), []).append(r)
    out = []
    for (controller, spec_id), rs in groups.items():
        ok = [r for r in rs if r.get("is_success")]
        gaps = [100.0 * (r["route_cost"] - ref[k]) / ref[k] for r in ok
                if (k := (r["world_seed"], r["seed"])) in ref and ref[k] > 0]
        first = rs[0]
        out.append({
            "controller": controller,
            "spec_id": spec_id,
            "spec": first.get("spec", ""),
            "n_spins": first.get("n_spins"),
            "j_range": first.get("j_range"),
            "n_cores": first.get("n_cores"),
            "episodes": len(rs),
            "success_rate": len(ok) / len(rs),
            "mean_cost": float(np.mean([r["route_cost"] for r in ok])) if ok else math.nan,
            "mean_gap_pct": float(np.mean(gaps)) if gaps else math.nan,
            "chip_calls": _median(r.get("chip_calls") for r in rs),
            "accelerator_energy_j": _median(r.get("accelerator_energy_j") for r in rs),
            "host_energy_j": _median(r.get("host_energy_j") for r in rs),
            "total_energy_j": _median(r.get("total_energy_j") for r in rs),
            "chip_time_parallel_s": _median(r.get("chip_time_parallel_s") for r in rs),
            "latency_parallel_s": _median(r.get("latency_parallel_s") for r in rs),
            "host_cpu_s": _median(r.get("host_cpu_s") for r in rs),
            "retries": _median(r.get("retries") for r in rs),
            "fallbacks_per_plan": float(np.mean([r.get("fallbacks") or 0 for r in rs])),
            "error": next((r["error"] for r in rs if r.get("error")), ""),
        })
    return out


def _cost_key(stats: list[dict]) -> str:
    return "mean_gap_pct" if any(math.isfinite(s["mean_gap_pct"]) for s in stats if s["spec_id"] >= 0) else "mean_cost"


def pareto_front(stats: list[dict], x: str, cost: str | None = None) -> list[dict]:
    """The chip specs that solved every world and are not dominated in (``cost``, ``x``), by ``x``."""
    cost = cost or _cost_key(stats)
    cand = [s for s in stats if s["spec_id"] >= 0 and s["success_rate"] == 1.0
            and math.isfinite(s[cost]) and math.isfinite(s[x])]
    front = []
    for s in cand:
        dominated = any(o is not s and o[cost] <= s[cost] and o[x] <= s[x] and (o[cost] < s[cost] or o[x] < s[x])
                        for o in cand)
        if not dominated:
            front.append(s)
    return sorted(front, key=lambda s: (s[x], s[cost]))


def plot_pareto(stats: list[dict], path, title: str = "") -> Path:
    """Cost against accelerator energy and chip latency (the paper's convention) and against system
    energy and latency (host included), one point per spec; the chip-free reference as a star (PNG)."""
    import matplotlib.pyplot as plt

    fig = pareto_figure(stats, title)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def _x_axis(ax, values, unit: str) -> None:
    """Log scale only when the points span a decade or more (a narrower log axis labels its minor
    ticks in full and they overlap); values with SI prefixes either way (``52.5 uJ``)."""
    from matplotlib.ticker import EngFormatter, MaxNLocator, NullFormatter

    pos = [v for v in values if v > 0 and math.isfinite(v)]
    if pos and max(pos) >= 10 * min(pos):
        ax.set_xscale("log")
        ax.xaxis.set_minor_formatter(NullFormatter())
    else:
        ax.xaxis.set_major_locator(MaxNLocator(4))
    ax.xaxis.set_major_formatter(EngFormatter(unit=unit))
    ax.tick_params(axis="x", labelsize=7)


def pareto_figure(stats: list[dict], title: str = ""):
    """The figure of :func:`plot_pareto` (a matplotlib ``Figure``, Agg backend)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cost = _cost_key(stats)
    chips = [s for s in stats if s["spec_id"] >= 0 and s["success_rate"] > 0]
    refs = [s for s in stats if s["spec_id"] < 0 and s["success_rate"] > 0]
    spins = sorted({s["n_spins"] for s in chips})
    cmap = plt.get_cmap("viridis", max(len(spins), 2))
    fig, grid = plt.subplots(2, 2, figsize=(11, 8.5))
    axes = grid.ravel()
    for ax, (x, label) in zip(axes, PANELS):
        for k, n in enumerate(spins):
            pts = [s for s in chips if s["n_spins"] == n and math.isfinite(s[x])]
            full = [s for s in pts if s["success_rate"] == 1.0]
            part = [s for s in pts if s["success_rate"] < 1.0]
            ax.scatter([s[x] for s in full], [s[cost] for s in full], color=cmap(k), s=22, label=f"{n} spins")
            ax.scatter([s[x] for s in part], [s[cost] for s in part], facecolors="none", edgecolors=cmap(k), s=22)
        front = pareto_front(stats, x, cost)
        if front:
            ax.plot([s[x] for s in front], [s[cost] for s in front], "k--", lw=1, label="Pareto front")
            for s in front[:3]:
                ax.annotate(_short_label(s), (s[x], s[cost]), fontsize=6, xytext=(4, -10 - 7 * front.index(s)),
                            textcoords="offset points")
        for s in refs:
            if s[x] > 0 and math.isfinite(s[x]):
                y = s[cost] if cost == "mean_cost" else 0.0
                ax.scatter([s[x]], [y], marker="*", s=110, color="tab:red", label=f"{s['controller']} (no chip)")
        _x_axis(ax, [s[x] for s in chips + refs], "J" if x.endswith("_j") else "s")
        if cost == "mean_gap_pct":
            ax.set_yscale("symlog", linthresh=1.0)
        ax.set_xlabel(label, fontsize=8)
        ax.set_ylabel("mean gap to the reference (%)" if cost == "mean_gap_pct" else "mean route cost (moves)",
                      fontsize=8)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, loc="best")
    axes[2].legend(fontsize=7, loc="best")
    fig.suptitle(title or "chip sweep: filled = every world solved, hollow = some failed", fontsize=9)
    fig.tight_layout()
    return fig


def _short_label(s: dict) -> str:
    """``45 sp, +-7, 8 c`` for a spec row (or its axis labels when the usual fields are absent)."""
    if s.get("n_spins") is not None and s.get("j_range") is not None and s.get("n_cores") is not None:
        return f"{s['n_spins']} sp, \u00b1{s['j_range']}, {s['n_cores']} c"
    return s["spec"]


def _f(v, pattern="{:.3g}") -> str:
    return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else pattern.format(v)


def write_summary(result, stats: list[dict], path) -> Path:
    """``summary.md``: the configuration, the recommended specs, and every spec's statistics."""
    cfg = result.config
    cost = _cost_key(stats)
    axes = ", ".join(f"{k} = {{{', '.join(v)}}}" for k, v in cfg["axes"].items())
    lines = [
        "# Chip sweep",
        "",
        f"Worlds: {cfg['n_worlds']} of `{cfg['env_id']}` {cfg['env_kwargs'] or '(defaults)'} from seed "
        f"{cfg['world_seed']}; controller seeds {cfg['seeds']}; step limit {cfg['max_steps']}.",
        f"Axes: {axes} ({len(result.specs)} specs); other fields as the base chip.",
        "",
        "Cost: " + ("mean gap (%) to the chip-free reference on the worlds both solved." if cost == "mean_gap_pct"
                    else "mean route cost (moves) over the solved worlds."),
        "Energy and latency: medians per plan; accelerator = chip calls x energy per call (the paper's "
        "convention); system = accelerator + host CPU x 15 W; latency = host + chip time over the cores.",
        "",
        "## Pareto-optimal specs (every world solved)",
        "",
    ]
    for x, label in PANELS:
        front = pareto_front(stats, x, cost)
        names = "; ".join(f"{s['spec']} ({_f(s[cost], '{:.2f}')}, {_f(s[x])})" for s in front) or "none"
        lines.append(f"- cost vs {label}: {names}")
    lines += ["", "## Every spec", "",
              "| controller | spec | success | cost | gap % | chip calls | accel E (J) | system E (J) | "
              "chip latency (s) | latency (s) | note |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    order = sorted(stats, key=lambda s: (s["spec_id"] >= 0, -s["success_rate"],
                                         s[cost] if math.isfinite(s[cost]) else math.inf))
    for s in order:
        lines.append(
            f"| {s['controller']} | {s['spec'] or '(no chip)'} | {100 * s['success_rate']:.0f}% | "
            f"{_f(s['mean_cost'], '{:.2f}')} | {_f(s['mean_gap_pct'], '{:.2f}')} | {_f(s['chip_calls'], '{:.0f}')} | "
            f"{_f(s['accelerator_energy_j'])} | {_f(s['total_energy_j'])} | {_f(s['chip_time_parallel_s'])} | "
            f"{_f(s['latency_parallel_s'])} | {s['error'][:80]} |")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n")
    return path


def write_report(result, out, reference: str | None = "strong") -> list[Path]:
    """``sweep.csv``, ``sweep.json``, ``specs.csv`` (per-spec statistics), ``pareto.png`` and
    ``summary.md`` in ``out``."""
    from agents.evaluation import write_csv

    out = Path(out)
    stats = spec_stats(result, reference)
    files = [result.to_csv(out / "sweep.csv"), result.to_json(out / "sweep.json"), write_csv(stats, out / "specs.csv")]
    files.append(plot_pareto(stats, out / "pareto.png"))
    files.append(write_summary(result, stats, out / "summary.md"))
    return files
