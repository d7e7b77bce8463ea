"""A League run over a grid of Ising machines, each beside its host-rule twin (``mrmt lorr sweep``).

Per instance x machine spec x seed, two runs of the same scheduler and planner: the machine deciding, and the host
rule in its place (:class:`~ising_backend.audit.host_rule.HostRule` ``all``: the same groups posed, the host answers,
no call).  The machine's size and range change what a decision may hold (``epibt-ising``'s neighbourhoods, the
``ising`` scheduler's programs); the twin shows what the machine's answers are worth there.  The summary sums the
tasks over seeds per instance and spec.
"""

from __future__ import annotations

import csv
import json
from contextlib import nullcontext
from pathlib import Path

__all__ = ["DECIDERS", "sweep_task", "sweep_rows", "summarise", "write_sweep", "write_rows", "COLUMNS"]

#: Who decides in a sweep's run: the machine, or the host rule in its place.
DECIDERS = ("machine", "host rule")
#: The columns of ``sweep.csv``.
COLUMNS = ("instance", "spec_id", "spec", "decider", "seed", "steps", "clock", "tasks_finished", "share_of_best",
           "timeouts", "step_p50_s", "step_p99_s", "chip_calls", "calls_per_step", "chip_s",
           "host_energy_per_task_j", "machine_energy_per_task_j")


def sweep_task(instance: str, scheduler, planner, steps, seed: int, chip, decider: str, limit=None) -> dict:
    """One run (module level, for the task runner) of the specs ``scheduler`` and ``planner``
    (:mod:`agents.lorr.spec`): :func:`~agents.lorr.run.run_lorr` with the machine ``chip``, inside the host rule for
    ``decider == "host rule"``."""
    from agents.lorr.run import run_lorr
    from ising_backend.audit.host_rule import HostRule

    if decider not in DECIDERS:
        raise ValueError(f"decider = {decider!r} must be one of {', '.join(DECIDERS)}")
    with HostRule("all") if decider == "host rule" else nullcontext():
        record, _, _ = run_lorr(instance, scheduler, planner, steps=steps, seed=seed, chip=chip, limit=limit)
    return record


def sweep_rows(records: list[dict], labels: list[tuple[int, str, str]]) -> list[dict]:
    """``sweep.csv``'s rows: each record with its ``(spec_id, spec, decider)`` label, calls per step."""
    rows = []
    for rec, (spec_id, spec, decider) in zip(records, labels, strict=True):
        row = {k: rec.get(k) for k in COLUMNS if k in rec}
        row.update(spec_id=spec_id, spec=spec, decider=decider, calls_per_step=rec["chip_calls"] / rec["decisions"])
        rows.append(row)
    return rows


def summarise(rows: list[dict]) -> list[dict]:
    """Per instance and spec (in the rows' order): the machine's and the twin's tasks summed over seeds, their
    ratio, timeouts, the machine's calls per step and joules per task (host and machine apart, seed means)."""
    groups: dict = {}
    for r in rows:
        groups.setdefault((r["instance"], r["spec_id"], r["spec"]), {}).setdefault(r["decider"], []).append(r)
    out = []
    for (instance, spec_id, spec), by in groups.items():
        m, h = by.get("machine", []), by.get("host rule", [])
        tm, th = sum(r["tasks_finished"] for r in m), sum(r["tasks_finished"] for r in h)
        mean = (lambda key, rs: sum(r[key] for r in rs) / len(rs) if rs else None)
        out.append({"instance": instance, "spec_id": spec_id, "spec": spec, "seeds": len(m),
                    "machine_tasks": tm, "host_rule_tasks": th, "ratio": tm / th if th else None,
                    "machine_timeouts": sum(r["timeouts"] for r in m),
                    "host_rule_timeouts": sum(r["timeouts"] for r in h),
                    "calls_per_step": mean("calls_per_step", m), "host_j_per_task": mean("host_energy_per_task_j", m),
                    "machine_j_per_task": mean("machine_energy_per_task_j", m),
                    "host_rule_host_j_per_task": mean("host_energy_per_task_j", h)})
    return out


def _markdown(summary: list[dict], title: str) -> str:
    lines = [f"# {title}", "",
             "| instance | spec | seeds | tasks (machine) | tasks (host rule) | machine / host rule | timeouts "
             "(machine / host rule) | calls per step | host J per task | machine J per task | host J per task "
             "(host rule) |", "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    f = (lambda x, spec: "-" if x is None else format(x, spec))
    for s in summary:
        lines.append(f"| {s['instance']} | {s['spec']} | {s['seeds']} | {s['machine_tasks']:,} | "
                     f"{s['host_rule_tasks']:,} | {f(s['ratio'], '.3f')} | {s['machine_timeouts']} / "
                     f"{s['host_rule_timeouts']} | {f(s['calls_per_step'], ',.0f')} | "
                     f"{f(s['host_j_per_task'], '.2f')} | "
                     f"{f(s['machine_j_per_task'], '.4f')} | {f(s['host_rule_host_j_per_task'], '.2f')} |")
    return "\n".join(lines) + "\n"


def _figure(summary: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    instances = list(dict.fromkeys(s["instance"] for s in summary))
    fig, axes = plt.subplots(1, len(instances), figsize=(5 * len(instances), 3.6), squeeze=False)
    for ax, name in zip(axes[0], instances):
        rows = [s for s in summary if s["instance"] == name]
        x = range(len(rows))
        ax.plot(x, [s["machine_tasks"] for s in rows], "o-", label="machine decides")
        ax.plot(x, [s["host_rule_tasks"] for s in rows], "s--", label="host rule in its place")
        ax.set_xticks(list(x), [s["spec"] for s in rows], rotation=30, ha="right", fontsize=8)
        ax.set_title(name)
        ax.set_ylabel("tasks finished (sum over seeds)")
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def write_rows(path: Path, rows: list[dict], columns) -> None:
    """``rows`` as a CSV file at ``path`` (its folder made), one column per name of ``columns``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)


def write_sweep(rows: list[dict], out, title: str) -> list[dict]:
    """``sweep.csv``, ``sweep.json``, ``summary.md`` and ``sweep.png`` into ``out``; returns the summary."""
    out = Path(out)
    write_rows(out / "sweep.csv", rows, COLUMNS)
    summary = summarise(rows)
    (out / "sweep.json").write_text(json.dumps({"rows": rows, "summary": summary}, indent=1))
    (out / "summary.md").write_text(_markdown(summary, title))
    _figure(summary, out / "sweep.png")
    return summary
