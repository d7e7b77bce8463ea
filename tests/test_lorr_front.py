"""The host's front against the chip's points (``mrmt lorr sweep --budget``, agents/lorr/front.py): which runs, the
joules (machine joules = chip calls x the spec's energy per call), the front and the verdicts, the command."""

from __future__ import annotations

import csv

import pytest

from agents.cli import main
from agents.lorr.front import FrontPoint, front_points, front_row, front_task, pareto, summarise_front
from ising_backend import ChipSpec
from mrmt_env.lorr.instance import example_instance_path
from planners.compute import CPU_WATTS_PER_CORE


def test_the_front_runs_each_host_planner_at_each_budget_and_the_chip_at_the_top_and_on_the_first_spec():
    specs = [ChipSpec(), ChipSpec(solve_time_s=5e-6), ChipSpec(n_spins=64)]
    pts = front_points(["epibt", "epibt-chain"], "epibt-ising", specs, [0.05, 0.2, 1.0], [0, 1])
    host = [p for p in pts if p.kind == "host"]
    assert len(host) == 2 * 3 * 2
    chip = {(p.spec_id, p.budget_s, p.seed) for p in pts if p.kind == "chip"}
    assert chip == {(i, 1.0, s) for i in range(3) for s in (0, 1)} | {(0, b, s) for b in (0.05, 0.2) for s in (0, 1)}
    # a twin makes no call: the 5 us spec shares the paper chip's; the 64-spin one shapes its groups apart
    twins = {(p.spec_id, p.budget_s, p.seed) for p in pts if p.kind == "twin"}
    assert twins == {(0, 1.0, s) for s in (0, 1)} | {(2, 1.0, s) for s in (0, 1)} | \
        {(0, b, s) for b in (0.05, 0.2) for s in (0, 1)}
    assert len(pts) == len(set(pts))


@pytest.mark.parametrize("solve_time_s", [50e-6, 5e-6])
def test_a_chip_points_machine_joules_are_its_calls_times_the_specs_energy_per_call(solve_time_s):
    from agents.lorr.spec import PlannerSpec, SchedulerSpec

    spec = ChipSpec(solve_time_s=solve_time_s)
    record = front_task(str(example_instance_path()), SchedulerSpec.of("lorr-greedy"), PlannerSpec.of("epibt-ising"),
                        4, 0, spec, "chip", 1.0)
    row = front_row(FrontPoint("chip", "epibt-ising", 0, 1.0, 0), record, spec, "test")
    assert row["chip_calls"] == record["chip_calls"] > 0
    assert row["machine_j"] == pytest.approx(row["chip_calls"] * spec.power_w * spec.solve_time_s, rel=1e-9)
    assert row["host_j"] == pytest.approx(record["host_cpu_s"] * CPU_WATTS_PER_CORE)
    assert row["j_per_task"] == pytest.approx((row["host_j"] + row["machine_j"]) / max(row["tasks"], 1))
    twin = front_task(str(example_instance_path()), SchedulerSpec.of("lorr-greedy"), PlannerSpec.of("epibt-ising"),
                      4, 0, spec, "twin", 1.0)
    assert twin["chip_calls"] == 0 and twin["machine_energy_per_task_j"] == 0


def _row(kind, tasks, host_j, machine_j=0.0, budget=1.0, seed=0, spins="", solve=""):
    return {"instance": "I", "kind": kind, "planner": "p" if kind == "host" else "c", "n_spins": spins,
            "solve_time_s": solve, "budget_s": budget, "seed": seed, "steps": 10, "tasks": tasks, "host_j": host_j,
            "machine_j": machine_j, "j_per_task": (host_j + machine_j) / tasks, "chip_calls": 0, "timeouts": 0,
            "host_cpu_s": host_j / 15, "code": "x"}


def test_a_chip_point_beyond_the_front_and_one_that_pays_are_told_apart():
    rows = [_row("host", 100, 100.0, budget=1.0), _row("host", 80, 40.0, budget=0.2),
            _row("host", 50, 40.0, budget=0.05),
            # beyond the front (no host point has as many tasks at as few joules) but not 1.05x the best's tasks
            _row("chip", 90, 50.0, 0.01, spins=45, solve=5e-5),
            # pays: 110 >= 1.05 x 100 tasks at 0.9 J / task <= the best host point's 1.0
            _row("chip", 110, 99.0, 0.0, spins=256, solve=5e-6),
            # beaten: the 0.2 s host point has more tasks at fewer joules
            _row("chip", 70, 60.0, 0.0, spins=1024, solve=5e-6)]
    s = summarise_front(rows)["I"]
    assert [(p["tasks"], p["budget_s"]) for p in s["front"]] == [(80, 0.2), (100, 1.0)]  # the 0.05 s point is beaten
    assert s["best_host"]["tasks"] == 100
    verdict = {c["n_spins"]: (c["beyond"], c["pays"]) for c in s["chips"]}
    assert verdict == {45: (True, False), 256: (True, True), 1024: (False, False)}
    assert pareto([{"tasks": 1, "j_per_task": 1.0}, {"tasks": 1, "j_per_task": 1.0}]) == \
        [{"tasks": 1, "j_per_task": 1.0}] * 2  # equal points do not beat each other


@pytest.mark.parametrize("args, words", [
    (["--budget", "0"], "--budget: 0 s must be in (0, 60]"),
    (["--budget", "fast"], "'fast' is not a number"),
    (["--budget", "1,1"], "1 s given twice"),
    (["--budget", "1", "--host-planner", "epibt-ising"], "a chip planner"),
    (["--budget", "1", "--host-planner", "nope"], "unknown planner 'nope'"),
    (["--budget", "1", "--planner", "epibt"], "give --planner one of"),
    (["--resume"], "add --budget"),
    (["--budget", "1", "--step-limit", "rules"], "drop --step-limit"),
])
def test_the_front_refuses_bad_input_in_one_line(tmp_path, capsys, args, words):
    base = ["lorr", "sweep", str(example_instance_path()), "--out", str(tmp_path / "o"), "--steps", "2"]
    if "--planner" not in args:
        base += ["--planner", "epibt-ising"]
    assert main(base + args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and words in err


def test_the_front_command_writes_its_table_and_figure_and_resumes(tmp_path, capsys):
    out = tmp_path / "front"
    argv = ["lorr", "sweep", str(example_instance_path()), "--planner", "epibt-ising", "--host-planner", "epibt",
            "--budget", "0.5,1", "--chip", "solve_time_s=5e-5,5e-6", "--steps", "3", "--out", str(out),
            "--no-progress"]
    assert main(argv) == 0
    with open(out / "front.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    # host: 2 budgets; chip: 2 specs at 1 s + the paper chip at 0.5 s; twins: the paper chip's at 1 s and 0.5 s
    assert sorted((r["kind"], r["solve_time_s"], r["budget_s"]) for r in rows) == sorted([
        ("host", "", "0.5"), ("host", "", "1.0"), ("chip", "5e-05", "1.0"), ("chip", "5e-06", "1.0"),
        ("chip", "5e-05", "0.5"), ("twin", "5e-05", "1.0"), ("twin", "5e-05", "0.5")])
    for r in rows:
        assert float(r["machine_j"]) == pytest.approx(int(r["chip_calls"]) * 9e-3 * (float(r["solve_time_s"] or 0)))
    assert (out / "front.png").stat().st_size > 0 and "| beyond the front | pays |" in (out / "front.md").read_text()
    printed = capsys.readouterr().out
    assert "beyond the front" in printed and "best host point" in printed
    before = (out / "front.csv").read_text()
    assert main(argv + ["--resume"]) == 0  # nothing left to run: the rows stay as they were
    assert (out / "front.csv").read_text() == before
    lines = before.splitlines()  # a row of another commit runs again, the rest stay
    (out / "front.csv").write_text("\n".join(lines[:2] + [lines[2].rsplit(",", 1)[0] + ",0ther"] + lines[3:]) + "\n")
    capsys.readouterr()
    assert main(argv + ["--resume"]) == 0
    assert "1 row(s) of front.csv ran at another commit" in capsys.readouterr().err
    again = (out / "front.csv").read_text().splitlines()
    assert len(again) == len(lines) and "0ther" not in "".join(again) and again[1] == lines[1]
