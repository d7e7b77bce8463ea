"""The whole League round under its clock: one entry on every instance, scored as the competition scores.

Runs ``mrmt lorr round`` on the 2024 main round (``shared/lorr/2024-main``) with ``--entry`` (default: the
package's) under the rules' 1 s clock, ``--steps`` a prefix of each instance (default: full simulation times),
``--resume`` keeping what an earlier run finished; then reads its ``summary.json`` beside the 2024 teams' scores
(the LoRR Code-Archive table, :data:`TEAMS`) and the per-lever reading of that table on WAREHOUSE and SORTATION.
Instances run one at a time, each in its own process (peak memory its own); run nothing else beside it.

    flock /tmp/mrmt-bench.lock python benchmarks/lorr_round.py --out runs/round --write
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import cpu_name, finish  # noqa: E402

SECTION = "## League of Robot Runners 2024: the whole round under the clock (issue 56)"
ROOT = Path(__file__).resolve().parents[2] / "shared" / "lorr" / "2024-main"
#: The 2024 main round's scores (sum of shares) of the entries the issue names (LoRR Code-Archive table).
TEAMS = {"No Man's Sky (1st)": 9.842, "Kitty Knight (2nd)": 9.039, "SYSU-LCIS (3rd)": 8.527, "RAPID": 7.946,
         "start kit default entry": 5.062}
#: Tasks on WAREHOUSE / SORTATION of the start kit's default entry and of the winner's scheduler or planner alone.
LEVERS = {"start kit default entry": (63924, 85039),
          "No Man's Sky, scheduler track (default planner, following its own planner's next cells written into the "
          "tasks: docs/lorr.md)": (146398, 146375),
          "No Man's Sky, planner alone (default scheduler)": (134418, 135988), "No Man's Sky, combined": (154795, 152714)}
BEST = {"WAREHOUSE": 154834, "SORTATION": 152714}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--entry", default="default")
    parser.add_argument("--out", default="runs/lorr-round")
    parser.add_argument("--steps", type=int, default=None, help="a prefix of each instance (default: in full)")
    parser.add_argument("--resume", action="store_true")
    parser.add_argument("--write", action="store_true")
    args = parser.parse_args(argv)
    cmd = [sys.executable, "-m", "agents.cli", "lorr", "round", str(ROOT), "--entry", args.entry, "--out", args.out,
           "--no-progress"] + (["--steps", str(args.steps)] if args.steps else []) + (["--resume"] if args.resume else [])
    subprocess.run(cmd, check=True)
    summary = json.loads((Path(args.out) / "summary.json").read_text())
    shown = f"mrmt lorr round shared/lorr/2024-main --entry {args.entry} --out DIR" + \
        (f" --steps {args.steps}" if args.steps else "")
    lines = [SECTION, "", f"`{shown}` ({cpu_name()}, instances one at a time, {summary['clock']}). "
             + ("Each instance ran its first " + str(args.steps) + " steps: shares against the best-known pro rata, "
                "which reads low (the first steps finish fewer tasks than the average step)." if args.steps else
                "Full simulation times."), "",
             (Path(args.out) / "summary.md").read_text().strip(), "",
             "The 2024 main round's scores (sum of tasks / best-known over the ten instances): "
             + ", ".join(f"{k} {v}" for k, v in TEAMS.items()) + ".", "",
             "Where the levers are (2024 table, tasks / best-known on WAREHOUSE, SORTATION):", ""]
    for name, (w, s) in LEVERS.items():
        lines.append(f"- {name}: {w / BEST['WAREHOUSE']:.0%}, {s / BEST['SORTATION']:.0%}")
    finish(SECTION, lines, args.write)


if __name__ == "__main__":
    main()
