"""Host-rule ablation (issue 33): each decision class answered by the host rule instead of the chip, same worlds.

For each preset and decision class, every world is planned twice in the same run -- the chip deciding,
and ``HostRule(class)`` putting the generic host rule (greedy construction + steepest descent) in its
place -- and the table gives the mean route cost, the plans that failed, and the chip calls left.
Paper worlds (10x10, 3 robots, 10 targets) for ``ising`` and ``ising-paper``; fleet worlds (20x20,
5 robots, 40 targets: ``ising`` runs its fleet search) for ``ising``.

    flock /tmp/mrmt-bench.lock python benchmarks/host_rule.py --write
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from _common import cpu_name, finish  # noqa: E402

from ising_backend.audit.host_rule import GENERIC_CLASSES, HostRule  # noqa: E402
from mrmt_env.generation import generate_world  # noqa: E402
from planners.pipeline import make_pipeline  # noqa: E402

SECTION = "## Host-rule ablation: each chip decision against the host rule in its place (issue 33)"


def _plans(preset, worlds, classes=None):
    rows = []
    for i, w in enumerate(worlds):
        ctx = HostRule(classes) if classes else None
        if ctx:
            with ctx:
                p = make_pipeline(preset).plan(w, seed=i)
        else:
            p = make_pipeline(preset).plan(w, seed=i)
        rows.append((p.success, p.route_cost if p.success else np.nan, p.compute.chip_calls + p.compute.logical_calls))
    return np.array(rows, dtype=float)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--worlds", type=int, default=30, help="paper worlds per preset")
    ap.add_argument("--fleet", type=int, default=5, help="fleet worlds (20x20, 5 robots, 40 targets)")
    ap.add_argument("--write", action="store_true")
    args = ap.parse_args(argv)
    suites = [("ising", "paper", [generate_world(i, n_robots=3, n_targets=10) for i in range(args.worlds)]),
              ("ising-paper", "paper", [generate_world(i, n_robots=3, n_targets=10) for i in range(args.worlds)]),
              ("ising", "fleet", [generate_world(i, height=20, width=20, n_robots=5, n_targets=40)
                                  for i in range(args.fleet)])]
    lines = [SECTION, "", f"`python benchmarks/host_rule.py --worlds {args.worlds} --fleet {args.fleet} --write` on "
             f"{cpu_name()}. Same worlds and seeds for every row; cost: mean route cost over the worlds both plans "
             "solved; change: the host rule's cost against the chip's.", "",
             "| preset | worlds | host rule in | plans failed (chip / host rule) | cost, chip | cost, host rule | change "
             "| chip calls left |", "|---|---|---|---|---|---|---|---|"]
    for preset, kind, worlds in suites:
        chip = _plans(preset, worlds)
        for cls in (*GENERIC_CLASSES, "all"):
            host = _plans(preset, worlds, cls)
            both = (chip[:, 0] == 1) & (host[:, 0] == 1)
            if not both.any():
                continue
            c, h = chip[both, 1].mean(), host[both, 1].mean()
            calls = int(host[:, 2].sum())
            if cls != "all" and calls == int(chip[:, 2].sum()) and np.array_equal(chip, host, equal_nan=True):
                continue  # the class does not occur in this preset's plans
            line = (f"| {preset} | {kind} ({len(worlds)}) | {cls} | {int((chip[:, 0] == 0).sum())} / "
                    f"{int((host[:, 0] == 0).sum())} | {c:.2f} | {h:.2f} | {100 * (h / c - 1):+.1f} % | "
                    f"{calls} of {int(chip[:, 2].sum())} |")
            lines.append(line)
            print(line, flush=True)
    finish(SECTION, lines, args.write)


if __name__ == "__main__":
    main()
