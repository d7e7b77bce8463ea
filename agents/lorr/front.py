"""The host's front against the chip's points (``mrmt lorr sweep --budget``): tasks and joules per finished task.

A host point is a host planner under one step budget (the clock's seconds per step); a chip point is a chip planner
on one machine spec, at the largest budget (and the first spec, the paper's chip by default, at every budget), with
its host-rule twin beside it (the same groups, the host deciding, no call).  Joules: the host's CPU seconds x 15 W
and the machine's calls x its energy per call.  Design notes: docs/design/sweep.md#the-hosts-front.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import NamedTuple

from planners.compute import CPU_WATTS_PER_CORE

__all__ = ["FrontPoint", "FRONT_COLUMNS", "front_points", "front_task", "front_row", "summarise_front",
           "write_front", "read_rows", "row_key"]

#: The columns of ``front.csv``: one row per run.
FRONT_COLUMNS = ("instance", "kind", "planner", "n_spins", "solve_time_s", "budget_s", "seed", "steps", "tasks",
                 "host_j", "machine_j", "j_per_task", "chip_calls", "timeouts", "host_cpu_s", "code")
KINDS = ("host", "chip", "twin")


class FrontPoint(NamedTuple):
    """One run of the front: ``kind`` host (a host planner), chip (the machine decides) or twin (the host rule in
    the machine's place); ``spec_id`` indexes the machine grid (-1 for a host point)."""

    kind: str
    planner: str
    spec_id: int
    budget_s: float
    seed: int


def front_points(host_planners, chip_planner, specs, budgets, seeds) -> list[FrontPoint]:
    """Every run of a front: each host planner at each budget; the chip planner on every spec of ``specs`` (chip
    specs) at the largest budget and on ``specs[0]`` at every budget, each beside its twin; per seed.  A twin makes no
    call, so specs that differ only in the call's time and power share one twin."""
    from dataclasses import replace

    top = max(budgets)
    points = [FrontPoint("host", p, -1, b, s) for p in host_planners for b in budgets for s in seeds]
    if chip_planner is None:
        return points
    shape = [replace(sp, solve_time_s=specs[0].solve_time_s, power_w=specs[0].power_w) for sp in specs]
    twin_of = {i: shape.index(shape[i]) for i in range(len(specs))}
    runs = [(i, top) for i in range(len(specs))] + [(0, b) for b in budgets if b != top]
    for spec_id, b in runs:
        for s in seeds:
            points.append(FrontPoint("chip", chip_planner, spec_id, b, s))
            twin = FrontPoint("twin", chip_planner, twin_of[spec_id], b, s)
            if twin not in points:
                points.append(twin)
    return points


def front_task(instance: str, scheduler, planner, steps: int, seed: int, chip, kind: str, budget_s: float) -> dict:
    """One run of the front (module level, for the task runner): the specs ``scheduler`` and ``planner`` under a
    ``budget_s`` clock, on the machine ``chip`` (a chip or twin point), inside the host rule for a twin."""
    from contextlib import nullcontext

    from agents.lorr.run import run_lorr
    from ising_backend.audit.host_rule import HostRule
    from mrmt_env.lorr.clock import StepLimit

    if kind not in KINDS:
        raise ValueError(f"kind = {kind!r} must be one of {', '.join(KINDS)}")
    with HostRule("all") if kind == "twin" else nullcontext():
        record, _, _ = run_lorr(instance, scheduler, planner, steps=steps, seed=seed,
                                chip=chip if kind != "host" else None, limit=StepLimit(budget_s))
    return record


def front_row(point: FrontPoint, record: dict, spec, code: str) -> dict:
    """``front.csv``'s row of ``point`` from its run's ``record``: host joules = host CPU seconds x 15 W, machine
    joules = the run's machine energy (its calls x the spec's energy per call)."""
    tasks = int(record["tasks_finished"])
    host_j = float(record["host_cpu_s"]) * CPU_WATTS_PER_CORE
    machine_j = float(record["machine_energy_per_task_j"]) * max(tasks, 1)
    on_chip = point.kind != "host"
    return {"instance": record["instance"], "kind": point.kind, "planner": point.planner,
            "n_spins": int(spec.n_spins) if on_chip else "",
            "solve_time_s": float(spec.solve_time_s) if on_chip else "",
            "budget_s": point.budget_s, "seed": point.seed, "steps": int(record["steps"]), "tasks": tasks,
            "host_j": host_j, "machine_j": machine_j, "j_per_task": (host_j + machine_j) / max(tasks, 1),
            "chip_calls": int(record["chip_calls"]), "timeouts": int(record["timeouts"]),
            "host_cpu_s": float(record["host_cpu_s"]), "code": code}


def row_key(row: dict) -> tuple:
    """What names a run in ``front.csv`` (a resumed sweep keeps a row of the same key)."""
    spins = "" if row["n_spins"] in ("", None) else int(row["n_spins"])
    solve = "" if row["solve_time_s"] in ("", None) else float(row["solve_time_s"])
    return (row["instance"], row["kind"], row["planner"], spins, solve, float(row["budget_s"]), int(row["seed"]),
            int(row["steps"]))


def read_rows(path) -> list[dict]:
    """The rows of a ``front.csv`` (numbers as numbers); none when the file is absent."""
    path = Path(path)
    if not path.is_file():
        return []
    ints = ("seed", "steps", "tasks", "chip_calls", "timeouts")
    floats = ("budget_s", "host_j", "machine_j", "j_per_task", "host_cpu_s")
    rows = []
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            r.update({k: int(r[k]) for k in ints}, **{k: float(r[k]) for k in floats})
            r["n_spins"] = int(r["n_spins"]) if r["n_spins"] else ""
            r["solve_time_s"] = float(r["solve_time_s"]) if r["solve_time_s"] else ""
            rows.append(r)
    return rows


def _mean_points(rows: list[dict]) -> list[dict]:
    """Seed means per (instance, kind, planner, spec, budget): tasks, joules per task, calls, timeouts."""
    groups: dict = {}
    for r in rows:
        key = (r["instance"], r["kind"], r["planner"], r["n_spins"], r["solve_time_s"], r["budget_s"])
        groups.setdefault(key, []).append(r)
    out = []
    for (inst, kind, planner, spins, solve, budget), rs in groups.items():
        n = len(rs)
        tasks = sum(r["tasks"] for r in rs) / n
        out.append({"instance": inst, "kind": kind, "planner": planner, "n_spins": spins, "solve_time_s": solve,
                    "budget_s": budget, "seeds": n, "tasks": tasks,
                    "host_j_per_task": sum(r["host_j"] for r in rs) / max(sum(r["tasks"] for r in rs), 1),
                    "machine_j_per_task": sum(r["machine_j"] for r in rs) / max(sum(r["tasks"] for r in rs), 1),
                    "j_per_task": sum(r["host_j"] + r["machine_j"] for r in rs) / max(sum(r["tasks"] for r in rs), 1),
                    "chip_calls": sum(r["chip_calls"] for r in rs) / n, "timeouts": sum(r["timeouts"] for r in rs)})
    return out


def pareto(points: list[dict]) -> list[dict]:
    """The points no other beats (at least as many tasks at no more joules per task, one of them strictly), by
    joules per task."""
    keep = [p for p in points if not any(q["tasks"] >= p["tasks"] and q["j_per_task"] <= p["j_per_task"]
                                         and (q["tasks"] > p["tasks"] or q["j_per_task"] < p["j_per_task"])
                                         for q in points)]
    return sorted(keep, key=lambda p: p["j_per_task"])


def summarise_front(rows: list[dict], margin: float = 1.05) -> dict:
    """Per instance: the host's front, the best host point (most tasks), and each chip point (seed means) with its
    twin, whether no host point beats it (``beyond``) and whether it ``pays``: tasks >= ``margin`` x the best host
    point's at no more joules per task than that point."""
    means = _mean_points(rows)
    out: dict = {}
    for inst in dict.fromkeys(p["instance"] for p in means):
        host = [p for p in means if p["instance"] == inst and p["kind"] == "host"]
        chips = [p for p in means if p["instance"] == inst and p["kind"] == "chip"]
        twins = {(p["planner"], p["n_spins"], p["budget_s"]): p for p in means  # a twin makes no call
                 if p["instance"] == inst and p["kind"] == "twin"}
        best = max(host, key=lambda p: (p["tasks"], -p["j_per_task"])) if host else None
        rated = []
        for c in chips:
            beaten = any(h["tasks"] >= c["tasks"] and h["j_per_task"] <= c["j_per_task"] for h in host)
            pays = best is not None and c["tasks"] >= margin * best["tasks"] and c["j_per_task"] <= best["j_per_task"]
            twin = twins.get((c["planner"], c["n_spins"], c["budget_s"]))
            rated.append({**c, "beyond": not beaten, "pays": pays,
                          "twin_tasks": None if twin is None else twin["tasks"],
                          "twin_j_per_task": None if twin is None else twin["j_per_task"]})
        out[inst] = {"front": pareto(host), "host": host, "best_host": best, "chips": rated}
    return out


def _markdown(summary: dict, title: str) -> str:
    lines = [f"# {title}", ""]
    f = (lambda x, spec: "-" if x is None or x == "" else format(x, spec))
    for inst, s in summary.items():
        lines += [f"## {inst}", "", "| kind | planner | n_spins | solve_time_s | budget s | seeds | tasks | "
                  "host J / task | machine J / task | J / task | chip calls | timeouts | twin tasks | beyond the front | pays |",
                  "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---|"]
        front = {id(p) for p in s["front"]}
        for p in s["host"] + s["chips"]:
            kind = p["kind"] + (" (front)" if id(p) in front else "")
            lines.append(f"| {kind} | {p['planner']} | {p['n_spins']} | {f(p['solve_time_s'], 'g')} | "
                         f"{p['budget_s']:g} | {p['seeds']} | {p['tasks']:,.1f} | {p['host_j_per_task']:.3f} | "
                         f"{p['machine_j_per_task']:.2e} | {p['j_per_task']:.3f} | {p['chip_calls']:,.0f} | "
                         f"{p['timeouts']} | {f(p.get('twin_tasks'), ',.1f')} | "
                         f"{'yes' if p.get('beyond') else ('no' if 'beyond' in p else '')} | "
                         f"{'yes' if p.get('pays') else ('no' if 'pays' in p else '')} |")
        lines.append("")
    return "\n".join(lines)


def _figure(summary: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import LogLocator, NullFormatter, ScalarFormatter

    fig, axes = plt.subplots(1, len(summary), figsize=(5.5 * len(summary), 4.2), squeeze=False)
    for ax, (inst, s) in zip(axes[0], summary.items()):
        for planner in dict.fromkeys(p["planner"] for p in s["host"]):
            pts = sorted((p for p in s["host"] if p["planner"] == planner), key=lambda p: p["budget_s"])
            ax.plot([p["j_per_task"] for p in pts], [p["tasks"] for p in pts], ".:", alpha=0.6,
                    label=f"host {planner} (budgets)")
        front = s["front"]
        ax.plot([p["j_per_task"] for p in front], [p["tasks"] for p in front], "k-", lw=2, label="host front")
        for c in s["chips"]:
            label = f"n={c['n_spins']}, {c['solve_time_s'] * 1e6:g} us, {c['budget_s']:g} s"
            ax.plot([c["j_per_task"]], [c["tasks"]], "*" if c["pays"] else "o", ms=9, label=label)
            if c["twin_tasks"] is not None:
                ax.plot([c["twin_j_per_task"]], [c["twin_tasks"]], "x", color="grey")
        ax.set_xscale("log")
        ax.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("joules per finished task (host CPU x 15 W + machine)")
        ax.set_ylabel("tasks finished (seed mean)")
        ax.set_title(f"{inst} (x: host-rule twins)")
        ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def write_front(rows: list[dict], out, title: str) -> dict:
    """``front.csv``, ``front.json``, ``front.md`` and ``front.png`` into ``out``; returns the summary."""
    from agents.lorr.sweep import write_rows

    out = Path(out)
    write_rows(out / "front.csv", rows, FRONT_COLUMNS)
    summary = summarise_front(rows)
    (out / "front.json").write_text(json.dumps(summary, indent=1, default=str))
    (out / "front.md").write_text(_markdown(summary, title))
    if summary:
        _figure(summary, out / "front.png")
    return summary
