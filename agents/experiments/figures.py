"""The experiments' figures: boxplots of cost, time and energy per method, like the paper's,
with the paper's convention (accelerator only) and the system totals side by side.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from agents.experiments.paper import METHOD_LABELS
from agents.experiments.records import ExperimentResult

_FIG_COST = {
    "path": "path length (moves)",
    "tour": "optimality gap (%)",
    "sharing": "total route length (moves)",
    "endtoend": "total route length (moves)",
}
_FIG_TITLE = {
    "path": "Pathfinding",
    "tour": "Tour construction",
    "sharing": "Target sharing",
    "endtoend": "End-to-end pipeline",
}


def plot_experiment(result: ExperimentResult, path) -> Path:
    """One figure like the paper's: boxplots of cost, time and energy per method (PNG, Agg).

    The time and energy panels show two boxes per method: the paper's convention (6.1:
    a classical method's CPU, an Ising method's accelerator only) and the system total
    (latency = host CPU + chip time; energy = host CPU x 15 W + accelerator), so an Ising
    method's host work is never hidden.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    labels = [METHOD_LABELS.get(m, m) for m in result.methods]
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.0))
    panels = (
        (("cost",), _FIG_COST[result.name], False),
        (("time_s", "latency_s"), "time (s)", True),
        (("energy_j", "total_energy_j"), "energy (J)", True),
    )
    series = {  # (legend, face colour, hatch)
        "time_s": ("paper: CPU wall / chip only", "#9ecae1", ""),
        "latency_s": ("system: host CPU + chip", "#fdae6b", "//"),
        "energy_j": ("paper: CPU 15 W / chip only", "#9ecae1", ""),
        "total_energy_j": ("system: host CPU 15 W + chip", "#fdae6b", "//"),
    }
    x = np.arange(1, len(labels) + 1, dtype=float)
    for ax, (keys, ylabel, log) in zip(axes, panels):
        width = 0.8 / len(keys)
        handles = []
        for j, key in enumerate(keys):
            data = []
            for m in result.methods:
                v = result.values(m, key)
                v = v[np.isfinite(v)]
                if log:
                    v = v[v > 0]
                data.append(v if len(v) else np.array([np.nan]))
            pos = x + (j - (len(keys) - 1) / 2) * width
            bp = ax.boxplot(data, positions=pos, widths=width * 0.9, showfliers=True, patch_artist=True)
            if key in series:
                name, colour, hatch = series[key]
                for box in bp["boxes"]:
                    box.set(facecolor=colour, hatch=hatch)
                handles.append((bp["boxes"][0], name))
        ax.set_xticks(x, labels, rotation=30, ha="right")
        ax.set_xlim(0.4, len(labels) + 0.6)
        ax.set_ylabel(ylabel)
        if log:
            ax.set_yscale("log")
        if handles:
            ax.legend([h for h, _ in handles], [n for _, n in handles], fontsize=7, loc="best")
        ax.grid(axis="y", alpha=0.3)
    n = len(result.method_rows(result.methods[0]))
    fig.suptitle(f"{_FIG_TITLE[result.name]} ({n} instances)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
