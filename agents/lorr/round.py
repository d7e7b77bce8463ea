"""A League round: every instance of a round folder run by one entry under the clock, scored as the competition scores.

:func:`round_instances`, :func:`best_known_table` and :func:`run_round` (each instance in a fresh process or a Ray
task, writing ``OUT/<NAME>/output.json`` and ``run.json``; a :class:`RoundSummary`, also ``OUT/summary.json`` and
``.md``). The score is the sum of tasks / best-known; ``resume`` keeps what the same entry made at the same commit.
Design notes: docs/design/lorr_runs.md#a-round.
"""

from __future__ import annotations

import json
import sys
from dataclasses import asdict, dataclass
from pathlib import Path

import mrmt_env

from agents.lorr.scores import BEST_KNOWN_FILE, BestKnown, best_known_table

__all__ = ["round_instances", "best_known_table", "run_round", "round_task", "RoundSummary", "BestKnown",
           "BEST_KNOWN_FILE"]

def round_instances(folder) -> list[Path]:
    """The instance files of a round folder (JSON files naming a ``mapFile``), sorted by name."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ValueError(f"{folder}: no such round folder")
    found = []
    for path in sorted([*folder.glob("*.json"), *folder.glob("*/*.json")], key=lambda p: p.stem):
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if isinstance(data, dict) and "mapFile" in data:
            found.append(path)
    if not found:
        raise ValueError(f"{folder}: no LoRR instance file (a JSON naming mapFile) in it or its sub-folders")
    return found


@dataclass(frozen=True)
class RoundSummary:
    """The round's rows (one per instance), its score (sum of shares) and how many instances were scored."""

    rows: list
    score: float
    scored: int
    instances: int
    entry: str
    clock: str
    code: str = "unknown"  # the package's commit every row was run at ("mixed" when they differ)
    machine: str = ""      # the CPU model and cores the rows were run on

    def to_json(self) -> dict:
        return asdict(self)


def code_version() -> str:
    """The package's commit (``git rev-parse HEAD`` of the checkout it runs from, ``+dirty`` when a tracked file of the
    library differs from it), or ``unknown`` outside a git checkout."""
    import subprocess

    root = Path(mrmt_env.__file__).resolve().parents[1]
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True,
                              timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no", "--",
                                "mrmt_env", "ising_backend", "planners", "agents"], capture_output=True, text=True,
                               timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return (head + ("+dirty" if dirty else "")) if head else "unknown"


def machine_name() -> str:
    """The CPU model and the cores this process may use."""
    import os
    import platform

    cpu = platform.processor() or platform.machine()
    try:
        cpu = next(line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                   if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return f"{cpu}, {cores} cores"


def _key(entry, steps, limit, seed) -> dict:
    """What makes two runs of an instance the same run: the entry (its name and rules, wherever its file is), the
    steps, the clock, the seed and the package's commit (:func:`code_version`)."""
    import hashlib

    rules = json.dumps(entry.to_json()["rules"], sort_keys=True)
    return {"entry": entry.name, "entry_rules": hashlib.sha1(rules.encode()).hexdigest()[:12], "steps": steps,
            "clock": "work-bounded" if limit is None else limit.label(), "seed": int(seed), "code": code_version()}


def round_task(instance: str, entry_spec: str, steps, seed: int, limit, out: str, best: dict) -> dict:
    """One instance of a round (module level, for the process pool and Ray): the entry's choice run, its files
    written, its row returned."""
    from agents.lorr.entry import load_entry
    from mrmt_env.lorr.output import write_output
    from agents.lorr.run import run_lorr
    from mrmt_env.lorr.instance import read_instance

    inst = read_instance(instance)
    entry = load_entry(entry_spec)
    choice = entry.choose(inst)
    known = best.get(inst.name)
    full = inst.steps or (known[1] if known else None)
    if steps is not None:
        n = int(steps)
    elif full is not None:
        n = int(full)
    else:
        raise ValueError(f"{instance}: no simulation time (no simulation_time.json, no best-known row): give --steps")
    record, sim, step_s = run_lorr(inst, choice.scheduler, choice.planner, steps=n, seed=seed,
                                   limit=limit)
    folder = Path(out) / inst.name
    write_output(sim, folder / "output.json", planner_times=step_s)
    prefix = full is None or n < full
    target = None if known is None or full is None else known[2] * min(n, full) / full
    row = {**record, **_key(entry, n, limit, seed), "rule": choice.rule, "full_steps": full, "prefix": prefix,
           "best_known": known[2] if known else None, "best_known_pro_rata": target,
           "share_of_best": (sim.finished / target) if target else None,
           "scored_share": 0.0 if record["preprocess_timeout"] else ((sim.finished / target) if target else None),
           "output": str(folder / "output.json"), "output_sha1": _sha1(folder / "output.json"),
           "machine": machine_name()}
    (folder / "run.json").write_text(json.dumps(row, indent=1))
    return row


def _sha1(path: Path) -> str:
    import hashlib

    return hashlib.sha1(path.read_bytes()).hexdigest()


def _kept(path: Path, key: dict) -> dict | None:
    """The row of ``path/run.json`` when it was made by the same run (``key``) and its output file is the one it
    wrote (its sha1) or not kept beside it (a committed round keeps its rows, not its large output files)."""
    try:
        row = json.loads((path / "run.json").read_text())
    except (OSError, ValueError):
        return None
    out = path / "output.json"
    if all(row.get(k) == v for k, v in key.items()) and (not out.is_file() or _sha1(out) == row.get("output_sha1")):
        return row
    return None


def _fresh_processes(tasks: list[tuple], jobs: int, progress: bool) -> list[dict]:
    """``round_task`` per task, each in a new process (spawned: its peak memory is its own), ``jobs`` at once."""
    import multiprocessing

    ctx = multiprocessing.get_context("spawn")
    rows = []
    with ctx.Pool(processes=jobs, maxtasksperchild=1) as pool:
        for row in pool.starmap(round_task, tasks, chunksize=1):
            rows.append(row)
            if progress:
                print(f"  {row['instance']}: {row['tasks_finished']} tasks, {row['timeouts']} timeouts",
                      file=sys.stderr)
    return rows


def run_round(folder, entry, out, steps=None, seed: int = 0, limit=None, best=None, resume: bool = False,
              jobs: int = 1, backend: str = "local", address: str | None = None,
              progress: bool = True) -> RoundSummary:
    """Run every instance of ``folder`` with ``entry`` (an :class:`~agents.lorr.entry.Entry`) under ``limit``; see
    the module docstring.  ``best``: a best-known table (:func:`best_known_table`); ``backend``: ``local`` (fresh
    processes, ``jobs`` at once) or ``ray`` (the task runner's Ray backend, ``address`` a cluster or a local one)."""
    paths = round_instances(folder)
    best = best_known_table() if best is None else best
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    kept, todo = {}, []
    for path in paths:
        key = _key(entry, steps, limit, seed)
        row = _kept(out / path.stem, {k: v for k, v in key.items() if v is not None}) if resume else None
        if row is not None and (steps is not None or not row["prefix"]):
            kept[path.stem] = row
        else:
            todo.append((str(path), entry.source, steps, seed, limit, str(out), {k: tuple(v) for k, v in best.items()}))
    if todo and backend == "ray":
        from agents.runner import RunConfig, run_tasks

        done = run_tasks(round_task, todo, RunConfig(backend="ray", jobs=jobs, address=address, chunk_size=1,
                                                     progress=progress))
    elif todo:
        done = _fresh_processes(todo, jobs, progress)
    else:
        done = []
    rows = {**kept, **{r["instance"]: r for r in done}}
    ordered = [rows[p.stem] for p in paths]
    scored = [r["scored_share"] for r in ordered if r["scored_share"] is not None]
    codes = {r.get("code", "unknown") for r in ordered}
    machines = sorted({r.get("machine", "") for r in ordered})
    summary = RoundSummary(rows=ordered, score=float(sum(scored)), scored=len(scored), instances=len(ordered),
                           entry=entry.name, clock="work-bounded" if limit is None else limit.label(),
                           code=codes.pop() if len(codes) == 1 else "mixed", machine="; ".join(machines))
    (out / "summary.json").write_text(json.dumps(summary.to_json(), indent=1))
    (out / "summary.md").write_text(summary_table(summary) + "\n")
    return summary


def summary_table(summary: RoundSummary) -> str:
    """The round as a Markdown table: per instance tasks, best-known, share, timeouts, step p50 / p99, peak memory,
    energy per task; then the score."""
    def f(x, spec):
        return "-" if x is None else format(x, spec)

    lines = [f"entry `{summary.entry}`, {summary.clock}, at commit {summary.code}, on {summary.machine}", "",
             "| instance | robots | steps | planner | tasks | best-known | share | timeouts | step p50 s | step p99 s "
             "| peak MiB | J / task (paper / total) |",
             "|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in summary.rows:
        steps = f"{r['steps']}" + (f" of {r['full_steps']}" if r["prefix"] and r["full_steps"] else "")
        share = f(r["share_of_best"], ".1%") + (" (pro rata)" if r["prefix"] and r["share_of_best"] else "")
        if r["preprocess_timeout"]:
            share += " (preprocessing late: 0)"
        lines.append(f"| {r['instance']} | {r['robots']} | {steps} | {r['scheduler']} + {r['executor']} "
                     f"| {r['tasks_finished']} | {f(r['best_known'], 'd')} | {share} | {r['timeouts']} "
                     f"| {r['step_p50_s']:.3f} | {r['step_p99_s']:.3f} | {r['peak_rss_mb']:.0f} "
                     f"| {r['paper_energy_per_task_j']:.3g} / {r['total_energy_per_task_j']:.3g} |")
    lines += ["", f"score {summary.score:.3f} of {summary.scored} (sum of shares over the scored instances; "
                  f"{summary.instances} in the round)"]
    return "\n".join(lines)
