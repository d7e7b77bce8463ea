"""Schedulers at scale: the winner's measure (``lorr-weighted``) and the chip's group decisions on it (``lorr-ising``,
its host-rule twin beside it) against the start kit's greedy, same planner.

On the 2024 main round's large instances (CITY-01 1,500 robots, CITY-02 3,000, SORTATION and WAREHOUSE 10,000),
the first ``--steps`` steps under the rules' 1 s clock, each run in its own process: ``lorr-greedy`` (the start
kit's default scheduler), ``lorr-weighted`` with the way weighed by 1 (the package's default) and by 5 (the 2024
winner's) and with the jam term, ``lorr-ising`` on the jam term and its host-rule twin (``--host-rule
task_groups``), every one with PIBT with turning (lanes off on SORTATION as in the default entry).  Tasks, the ratio
to greedy, timeouts, step p99, chip calls per step, energy per task (host and machine apart) and peak memory.  Run
nothing else beside it.

    flock /tmp/mrmt-bench.lock python benchmarks/lorr_schedulers.py --steps 1000 --write
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import cpu_name, finish  # noqa: E402

SECTION = ("## League of Robot Runners 2024: the chip at ten thousand robots, lorr-ising against its host-rule twin "
           "(issue 56)")
SECTION_ENTRY = "## League of Robot Runners 2024: lorr-ising with the entry's planner (issue 56)"
SECTION_FLOW = "## League of Robot Runners 2024: lorr-ising with the start kit's default planner (issue 56)"
#: ``pibt-flow``'s memory bound for its fields (2 GiB: SORTATION's 10,000 robots x 54,320 free cells need 1.1 GB)
FLOW_FIELD_BYTES = 2 << 30
#: planner choice -> (its section, what the table says it is)
PLANNERS = {"pibt": (SECTION, "PIBT with turning, lanes off on SORTATION as in the default entry"),
            "pibt-flow": (SECTION_FLOW, "the start kit's default, PIBT along traffic-flow guide paths (`pibt-flow`)"),
            "entry": (SECTION_ENTRY, "the default entry's for each instance")}
ROOT = Path(__file__).resolve().parents[2] / "shared" / "lorr" / "2024-main"
INSTANCES = {"CITY-01": "city.domain", "CITY-02": "city.domain", "SORTATION": "warehouse.domain",
             "WAREHOUSE": "warehouse.domain"}
#: (label, scheduler, scheduler options, other arguments)
SCHEDULERS = (("lorr-greedy", "lorr-greedy", [], []), ("lorr-weighted (weight 1)", "lorr-weighted", ["weight=1"], []),
              ("lorr-weighted (weight 5)", "lorr-weighted", ["weight=5"], []),
              ("lorr-weighted (jam 4)", "lorr-weighted", ["jam=4"], []),
              ("lorr-ising (jam 4)", "lorr-ising", ["jam=4"], []),
              ("lorr-ising (jam 4) host rule", "lorr-ising", ["jam=4"], ["--host-rule", "task_groups"]),
              ("lorr-weighted (jam 4 turns)", "lorr-weighted", ["jam=4", "turns=true"], []),
              ("lorr-ising (jam 4 turns)", "lorr-ising", ["jam=4", "turns=true"], []))


def _value(v) -> str:
    """An option value as the command line reads it (JSON: numbers, true / false, null; text as it is)."""
    return v if isinstance(v, str) else json.dumps(v)


def planner_args(name: str, planner: str) -> list[str]:
    """The planner's arguments: ``pibt`` (lanes off on SORTATION, as the default entry), ``pibt-flow`` (the start
    kit's default planner: PIBT along traffic-flow guide paths, no lanes) or ``entry`` (the default entry's planner for
    the instance, with its options and guidance)."""
    if planner == "pibt-flow":  # a field and a guide path per robot: SORTATION's need 1.1 GB, over the default bound
        return ["--planner", "pibt-flow", "--planner-option", f"field_bytes={FLOW_FIELD_BYTES}"]
    if planner == "pibt":
        return ["--planner", "pibt", *(["--guidance", "0"] if name == "SORTATION" else [])]
    from agents.lorr.entry import load_entry
    from mrmt_env.lorr.instance import read_instance

    choice = load_entry("default").choose(read_instance(ROOT / INSTANCES[name] / f"{name}.json"))
    # the entry's planner with the options it gives that differ from the planner's defaults (guidance among them)
    return ["--planner", choice.planner.name, *[a for k, v in choice.planner.given.items()
                                                 for a in ("--planner-option", f"{k}={_value(v)}")]]


def run(name: str, scheduler: str, options: list[str], extra: list[str], steps: int, planner: str = "pibt") -> dict:
    path = ROOT / INSTANCES[name] / f"{name}.json"
    cmd = [sys.executable, "-m", "agents.cli", "lorr", "run", str(path), "--scheduler", scheduler,
           *planner_args(name, planner), *[a for o in options for a in ("--scheduler-option", o)], "--steps", str(steps),
           "--step-limit", "rules", "--json", "--no-progress", *extra]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--instances", default=",".join(INSTANCES))
    parser.add_argument("--rows", default=",".join(label for label, *_ in SCHEDULERS),
                        help="which of the scheduler rows to run (labels, comma-separated)")
    parser.add_argument("--planner", choices=tuple(PLANNERS), default="pibt",
                        help="pibt (PIBT with turning), pibt-flow (the start kit's default planner) or entry (the "
                        "default entry's planner for each instance)")
    parser.add_argument("--write", action="store_true")
    args = parser.parse_args(argv)
    names = [n.strip() for n in args.instances.split(",") if n.strip()]
    unknown = [n for n in names if n not in INSTANCES]
    if unknown:
        parser.error(f"unknown instance {unknown[0]!r}; known: {', '.join(INSTANCES)}")
    wanted = [r.strip() for r in args.rows.split(",") if r.strip()]
    missing = [r for r in wanted if r not in [label for label, *_ in SCHEDULERS]]
    if missing:
        parser.error(f"unknown row {missing[0]!r}; known: {', '.join(label for label, *_ in SCHEDULERS)}")
    rows = []
    for name in names:
        base = None
        for label, scheduler, options, extra in [row for row in SCHEDULERS if row[0] in wanted]:
            r = run(name, scheduler, options, extra, args.steps, args.planner)
            base = r["tasks_finished"] if base is None else base
            rows.append((name, label, r, r["tasks_finished"] / max(base, 1)))
            print(f"{name} {label}: {r['tasks_finished']} tasks, {r['timeouts']} timeouts", file=sys.stderr)
    section, what = PLANNERS[args.planner]
    lines = [section, "",
             f"`python benchmarks/lorr_schedulers.py --steps {args.steps} --planner {args.planner} --rows "
             f"'{args.rows}'` ({cpu_name()}; each run its own process, the first {args.steps} steps under the rules' "
             f"1 s clock; planner: {what}).", "",
             "| instance | scheduler | tasks | x greedy | timeouts | step p50 s | step p99 s | chip calls / step "
             "| host J / task | machine mJ / task | peak MiB |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for name, label, r, ratio in rows:
        lines.append(f"| {name} | {label} | {r['tasks_finished']:,} | {ratio:.2f} | {r['timeouts']} | "
                     f"{r['step_p50_s']:.3f} | {r['step_p99_s']:.3f} | {r['chip_calls'] / r['decisions']:,.0f} | "
                     f"{r['host_energy_per_task_j']:.2f} | {1e3 * r['machine_energy_per_task_j']:.3f} | "
                     f"{r['peak_rss_mb']:,.0f} |")
    finish(section, lines, args.write)


if __name__ == "__main__":
    main()
