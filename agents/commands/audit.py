"""``mrmt audit DIR``: what the chip is worth per decision class, from an audit recorded with ``--audit DIR``.

    mrmt plan worlds.jsonl --pipeline ising --audit runs/audit     # record every chip decision
    mrmt audit runs/audit                                          # one row per decision class
    mrmt audit runs/audit --json                                   # the rows as JSON objects
    mrmt audit runs/audit --export qubo-set                        # the problems as a QUBO benchmark set

The columns: docs/design/cli.md#mrmt-audit; docs/audit.md.
"""

from __future__ import annotations

import json
import sys

NAME = "audit"
HELP = "judge a recorded decision audit: chip vs host rule vs optimum per decision class"

KEYS = ("class", "decisions", "chip_better", "chip_worse", "chip_gap", "host_gap", "chip_s", "host_s")


def add_arguments(parser) -> None:
    parser.add_argument("directory", metavar="DIR", help="an audit directory (written by --audit DIR)")
    parser.add_argument("--json", action="store_true", help="one JSON object per class instead of the table")
    parser.add_argument("--export", default=None, metavar="OUT",
                        help="write each class's problems as a benchmark set OUT/CLASS.jsonl (dimod BQMs)")
    parser.add_argument("--exact-max", type=int, default=None,
                        help="largest program (active spins) solved exactly (default 20, at most 26)")


def _error(message: str) -> int:
    print(f"mrmt audit: error: {message}", file=sys.stderr)
    return 2


def run(args) -> int:
    from ising_backend.audit.record import read_records, read_specs
    from ising_backend.audit.judge import EXACT_MAX, export, judge, table

    exact_max = EXACT_MAX if args.exact_max is None else args.exact_max
    if not 0 <= exact_max <= 26:
        return _error(f"--exact-max {exact_max} must be in 0..26 (2^26 states per program at most)")
    try:
        records = read_records(args.directory)
    except ValueError as exc:
        return _error(str(exc))
    judged = judge(records, exact_max)
    rows = table(judged)
    if args.export:
        try:
            counts = export(records, judged, args.export, read_specs(args.directory))
        except OSError as exc:
            return _error(f"{args.export}: cannot write ({exc.strerror or exc})")
        print(f"mrmt audit: exported {', '.join(f'{c}: {n}' for c, n in counts.items())} problems to {args.export}",
              file=sys.stderr)
    if args.json:
        for r in rows:
            print(json.dumps({k: r[k] for k in (*KEYS, "host_rule", "exact")}))
        return 0
    print(f"{'class':<16} {'decisions':>9} {'chip better':>11} {'chip worse':>10} {'chip gap':>9} {'host gap':>9} "
          f"{'chip us':>8} {'host us':>8}  host rule (exact optimum share)")
    for r in rows:
        print(f"{r['class']:<16} {r['decisions']:>9} {100 * r['chip_better']:>10.1f}% {100 * r['chip_worse']:>9.1f}% "
              f"{100 * r['chip_gap']:>8.2f}% {100 * r['host_gap']:>8.2f}% {1e6 * r['chip_s']:>8.1f} "
              f"{1e6 * r['host_s']:>8.1f}  {r['host_rule']} ({100 * r['exact']:.0f}%)")
    return 0
