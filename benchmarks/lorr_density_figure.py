"""Issue 57's figure, drawn from the measured tables of ``benchmarks/RESULTS.md`` (no run of its own).

Three panels:

* the share of the best-known on RANDOM-01..05: the default entry in full under the clock (three seeds' mean, the
  seeds' range as whiskers; section :data:`SEEDS`), beside the 2024 start kit's default entry and the 2024 winner's
  Combined entry (``benchmarks/data/lorr2024_main_round.json``);
* the chip annealer (``epibt-chain-ising``) and its host-rule twin against the host annealer (``epibt-chain``),
  tasks summed over three seeds on RANDOM-01..05 (the third table of section :data:`SEEDS`);
* energy per finished task on RANDOM-04 / -05 (first 300 steps, three seeds' mean) of the host annealer, the chip
  annealer, its twin and host chains + chip, the host's (CPU seconds x 15 W) and the machine's (0.45 uJ a call)
  apart, on a log scale (section :data:`ANNEALERS`).

    python benchmarks/lorr_density_figure.py --out docs/lorr_density.png
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from agents.lorr.round import best_known_table  # noqa: E402

SEEDS = "## RANDOM-01..05 in full, three seeds, under the push cap (issue 57)"
ANNEALERS = "## The chip annealer inside the chain plan, three seeds under the entry's scheduler (issue 57)"
LEADERBOARD = Path(__file__).resolve().parent / "data" / "lorr2024_main_round.json"
INSTANCES = [f"RANDOM-0{i}" for i in range(1, 6)]
TEAMS = {"Default_Entry": "2024 start kit's default entry", "No_Man's_Sky": "2024 winner (Combined entry)"}


def section_table(name: str, text: str, which: int = 0) -> list[dict]:
    """The rows of Markdown table number ``which`` (0: the first) under heading ``name`` in ``text``, as
    ``{column: cell}``."""
    start = text.find(name + "\n")
    if start < 0:
        raise ValueError(f"RESULTS.md has no section {name!r}")
    tables, table = [], []
    for line in text[start:].splitlines()[1:] + [""]:
        if line.startswith("## "):
            break
        if line.startswith("|"):
            table.append([c.strip() for c in line.strip().strip("|").split("|")])
        elif table:
            tables.append(table)
            table = []
    if len(tables) <= which or len(tables[which]) < 3:
        raise ValueError(f"section {name!r} has no table {which + 1}")
    head = tables[which][0]
    return [dict(zip(head, row)) for row in tables[which][2:]]


def number(cell: str) -> float:
    """The first number of a cell (``2,324 (89.9 %)`` -> 2324.0, ``**2,676**`` -> 2676.0)."""
    found = re.search(r"-?[\d,]*\.?\d+(?:e[-+]?\d+)?", cell.replace("*", ""))
    if not found:
        raise ValueError(f"no number in table cell {cell!r}")
    return float(found.group(0).replace(",", ""))


def numbers(cell: str) -> list[float]:
    """Every number of a cell written ``a / b / c`` (or ``a - b``: its ends)."""
    return [number(part) for part in re.split(r" / | - ", cell)]


def figure(text: str, leaderboard: dict, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    best = best_known_table()
    seeds = {row["instance"]: [number(row[f"seed {s}"]) for s in range(3)] for row in section_table(SEEDS, text)}
    chips = section_table(ANNEALERS, text)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6))
    ax = axes[0]
    x = range(len(INSTANCES))
    width = 0.27
    for k, (team, label) in enumerate(TEAMS.items()):
        shares = [100 * leaderboard["teams"][team][leaderboard["columns"].index(name)] / best[name].tasks
                  for name in INSTANCES]
        ax.bar([i + (k - 1) * width for i in x], shares, width, label=label, color=("#bbbbbb", "#d62728")[k])
    runs = [[100 * t / best[name].tasks for t in seeds[name]] for name in INSTANCES]
    mean = [sum(r) / 3 for r in runs]
    err = [[m - min(r) for m, r in zip(mean, runs)], [max(r) - m for m, r in zip(mean, runs)]]
    ax.bar([i + width for i in x], mean, width, yerr=err, capsize=3, label="the entry (3 seeds, 2 cores)",
           color="#1f77b4")
    short = [name.replace("RANDOM", "R") for name in INSTANCES]
    ax.set_xticks(list(x), short)
    ax.set_ylabel("% of the best-known")
    ax.set_ylim(0, 115)
    ax.set_title(f"In full under the 1 s clock: RANDOM mean {sum(mean) / 5:.1f} %")
    ax.axhline(90, color="k", lw=0.6, ls="--")
    ax.legend(fontsize=7, loc="upper center", ncol=2)
    ratios = {row["instance"]: row for row in section_table(SEEDS, text, which=2)}
    chip = [number(ratios[name]["chip / host annealer"]) for name in INSTANCES]
    twin = [c / number(ratios[name]["chip / twin"]) for c, name in zip(chip, INSTANCES)]
    axes[1].bar([i - 0.2 for i in x], chip, 0.4, color="#2ca02c", label="chip annealer (epibt-chain-ising)")
    axes[1].bar([i + 0.2 for i in x], twin, 0.4, color="#9467bd", label="its host-rule twin (the search's greedy)")
    axes[1].axhline(1.0, color="#1f77b4", lw=1.5, label="host annealer (epibt-chain)")
    axes[1].axhline(1.05, color="k", lw=0.6, ls="--", label="issue 57's target, 1.05x")
    axes[1].set_xticks(list(x), short)
    axes[1].set_ylim(0, 1.3)
    axes[1].set_ylabel("tasks against the host annealer (3 seeds summed)")
    axes[1].set_title("The chip as EPIBT's annealer (100 / 300 steps)")
    axes[1].legend(fontsize=7, loc="upper center", ncol=2)
    names = ["host annealer", "chip annealer", "host-rule twin", "host chains + chip"]
    colors = ["#1f77b4", "#2ca02c", "#9467bd", "#ff7f0e"]
    for j, inst in enumerate(("RANDOM-04", "RANDOM-05")):
        for k, row in enumerate(r for r in chips if r["instance"] == inst):
            host = sum(numbers(row["host J / task (0 / 1 / 2)"])) / 3
            machine = numbers(row["machine J / task"])
            m = sum(machine) / len(machine)
            axes[2].bar(j * 2 + k * 0.4 - 0.6, host, 0.2, color=colors[k], label=names[k] if j == 0 else None)
            if m > 0:
                axes[2].bar(j * 2 + k * 0.4 - 0.4, m, 0.2, color=colors[k], hatch="//", alpha=0.5,
                            label="the machine's (hatched)" if (j, k) == (0, 1) else None)
    axes[2].set_xticks([0, 2], ["RANDOM-04", "RANDOM-05"])
    axes[2].set_yscale("log")
    axes[2].set_ylim(2e-3, 1e3)
    axes[2].set_ylabel("J per finished task (host; machine hatched)")
    axes[2].set_title("Energy per task (host CPU s x 15 W; 0.45 uJ a call)")
    axes[2].legend(fontsize=7, loc="upper center", ncol=2)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    print(f"wrote {out}")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/lorr_density.png")
    args = parser.parse_args(argv)
    figure(RESULTS.read_text(), json.loads(LEADERBOARD.read_text()), Path(args.out))


if __name__ == "__main__":
    main()
