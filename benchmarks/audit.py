"""The decision audit on the paper's worlds, fleet worlds and a LoRR instance: what the chip is worth per decision.

Records every chip program (``ising_backend.audit.record.Audit``) of: the ``ising-paper`` and ``ising`` presets on
``--worlds`` paper worlds (10x10, 3 robots, 10 targets), the ``ising`` preset on ``--fleet`` fleet worlds
(20x20, 5 robots, 40 targets: the fleet search), and the ``ising`` LoRR scheduler on RANDOM-01 for ``--steps``
steps, and the ``pibt-ising`` and ``epibt-ising`` executors on RANDOM-03; judges each class (``mrmt audit``: chip vs the host rule vs the optimum) and exports the problems as a
benchmark set (``--export DIR``).  Writes the RESULTS.md section (``--write``).

    flock /tmp/mrmt-bench.lock python benchmarks/audit.py --export /tmp/qubo-set --write
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from _common import cpu_name, finish  # noqa: E402

SECTION = "## Decision audit: what the chip is worth per decision (issue 33)"
LORR = Path(__file__).resolve().parents[2] / "shared" / "lorr" / "2024-main"


def _record(directory: Path, args) -> dict:
    from agents.lorr.run import run_lorr
    from ising_backend.audit.record import Audit
    from mrmt_env.generation import generate_world
    from planners.pipeline import make_pipeline

    sources = {}
    jobs = [(f"paper worlds, {p}", p, dict(), args.worlds) for p in ("ising-paper", "ising")]
    jobs.append(("fleet worlds, ising", "ising", dict(height=20, width=20, n_robots=5, n_targets=40), args.fleet))
    for label, preset, kw, n in jobs:
        pipe = make_pipeline(preset)
        pipe.warmup(generate_world(0, **kw))
        with Audit(directory) as audit:
            before = dict(audit.counts)
            for s in range(n):
                pipe.plan(generate_world(s, **kw), seed=s)
        sources[label] = {c: audit.counts[c] - before.get(c, 0) for c in audit.counts}
    if args.steps:
        path = next(LORR.glob("*/RANDOM-01.json"))
        run_lorr(path, "ising", "pibt", steps=3)  # compiled before the audit
        with Audit(directory) as audit:
            run_lorr(path, "ising", "pibt", steps=args.steps)
        sources[f"LoRR RANDOM-01, ising scheduler, {args.steps} steps"] = dict(audit.counts)
    if args.joint_steps:  # the joint next moves of congested groups (executor pibt-ising), host rule PIBT
        path = next(LORR.glob("*/RANDOM-03.json"))
        run_lorr(path, "lorr-greedy", "pibt-ising", steps=3)
        with Audit(directory) as audit:
            run_lorr(path, "lorr-greedy", "pibt-ising", steps=args.joint_steps)
        sources[f"LoRR RANDOM-03, lorr-greedy + pibt-ising, {args.joint_steps} steps"] = dict(audit.counts)
    if args.lns_steps:  # EPIBT's neighbourhood groups (executor epibt-ising), host rule the search's greedy
        path = next(LORR.glob("*/RANDOM-03.json"))
        run_lorr(path, "lorr-greedy", "epibt-ising", steps=3)
        with Audit(directory) as audit:
            run_lorr(path, "lorr-greedy", "epibt-ising", steps=args.lns_steps)
        sources[f"LoRR RANDOM-03, lorr-greedy + epibt-ising, {args.lns_steps} steps"] = dict(audit.counts)
    return sources


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", type=int, default=30)
    parser.add_argument("--fleet", type=int, default=3)
    parser.add_argument("--steps", type=int, default=300, help="LoRR steps (0 = none)")
    parser.add_argument("--joint-steps", type=int, default=100, help="LoRR steps with the pibt-ising executor (0 = none)")
    parser.add_argument("--lns-steps", type=int, default=40,
                        help="LoRR steps with the epibt-ising executor (0 = none)")
    parser.add_argument("--audit", default=None, help="audit directory (default: a temporary one)")
    parser.add_argument("--export", default=None, help="also export the benchmark set here")
    parser.add_argument("--write", action="store_true")
    args = parser.parse_args(argv)
    from ising_backend.audit.record import read_records, read_specs
    from ising_backend.audit.judge import export, judge, table

    directory = Path(args.audit or tempfile.mkdtemp(prefix="mrmt-audit-"))
    t0 = time.perf_counter()
    sources = _record(directory, args)
    records = read_records(directory)
    t1 = time.perf_counter()
    judged = judge(records)
    rows = table(judged)
    t2 = time.perf_counter()
    counts = export(records, judged, args.export, read_specs(directory)) if args.export else {}
    lines = [SECTION, "", f"`python benchmarks/audit.py --worlds {args.worlds} --fleet {args.fleet} --steps {args.steps} "
             f"--joint-steps {args.joint_steps} --lns-steps {args.lns_steps}"
             f"{' --export DIR' if args.export else ''} --write` on {cpu_name()}: {len(records)} chip programs recorded in "
             f"{t1 - t0:.0f} s, judged in {t2 - t1:.0f} s.  A decision = one program as the machine took it (quantized; a "
             "packed program holds several problems).  Chip = the best of its reads; host rule = greedy construction "
             "then steepest single-flip descent on the same program (the rule a host would run in the chip's place), "
             "except joint_moves, whose host rule is PIBT's own answer, and lns_groups, whose host rule is the "
             "search's greedy, each encoded in the same program; "
             "optimum exact up to 20 active spins, else the best of a long tabu run (share exact in the last column). "
             "Gaps are fractions of max(|optimum|, 1); chip us at 50 us a call (paper rule), host us measured.", "",
             "| source | programs per class |", "|---|---|"]
    lines += [f"| {k} | {', '.join(f'{c} {n}' for c, n in v.items() if n)} |" for k, v in sources.items()]
    lines += ["", "| class | decisions | chip better | chip worse | chip gap | host gap | chip us | host us | host rule | exact |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['class']} | {r['decisions']} | {100 * r['chip_better']:.1f} % | {100 * r['chip_worse']:.1f} % | "
                     f"{100 * r['chip_gap']:.2f} % | {100 * r['host_gap']:.2f} % | {1e6 * r['chip_s']:.0f} | "
                     f"{1e6 * r['host_s']:.1f} | {r['host_rule']} | {100 * r['exact']:.0f} % |")
    if counts:
        lines += ["", "Exported (`mrmt audit DIR --export OUT`, one dimod BQM per line with its optimum, host-rule and chip "
                  "energies and the chip spec): " + ", ".join(f"{c} {n}" for c, n in counts.items()) + "."]
    finish(SECTION, lines, args.write)


if __name__ == "__main__":
    main()
