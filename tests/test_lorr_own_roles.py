"""A user's own planner and scheduler (classes meeting agents.lorr.roles' Protocols) run as the package's do: in
run_lorr, in `mrmt lorr run --planner package.module:Class`, and in an entry file, under the clock and scored."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from agents.lorr.entry import load_entry
from agents.lorr.run import run_lorr
from agents.lorr.spec import PlannerSpec, SchedulerSpec
from mrmt_env.lorr.clock import StepLimit
from mrmt_env.lorr.instance import example_instance_path, read_instance
from mrmt_env.lorr.output import output_dict
from mrmt_env.lorr.roles import Planner, Scheduler

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
sys.path.insert(0, str(EXAMPLES))
from lorr_own_planner import ForwardPlanner  # noqa: E402

EXAMPLE = example_instance_path()


class KeepScheduler:
    """A scheduler of one's own with no compute accounting: the first open task to each free robot, in order."""

    def __init__(self, seed: int = 0) -> None:
        self.calls = 0

    def schedule(self, sim, deadline=None):
        self.calls += 1
        proposal = sim.tasks.assigned.copy()
        taken = set(proposal[proposal >= 0].tolist())
        free = iter(k for k in sim.tasks.open if k not in taken)
        for a in np.flatnonzero(proposal < 0).tolist():
            k = next(free, None)
            if k is None:
                break
            proposal[a] = k
        return proposal


def test_the_example_planner_meets_the_role_and_runs_valid_and_deterministic():
    inst = read_instance(EXAMPLE)
    assert isinstance(ForwardPlanner(inst.grid), Planner) and isinstance(KeepScheduler(), Scheduler)
    a, sim_a, _ = run_lorr(inst, "lorr-greedy", ForwardPlanner(inst.grid), steps=80)
    b, sim_b, _ = run_lorr(inst, "lorr-greedy", ForwardPlanner(inst.grid), steps=80)
    assert a["errors"] == 0 and a["tasks_finished"] == sim_a.finished == b["tasks_finished"] > 0
    assert output_dict(sim_a)["actualPaths"] == output_dict(sim_b)["actualPaths"]
    assert a["executor"] == "forward" and a["guidance"] is None  # its own name; it has no lanes
    # charged its measured host seconds only: no machine, no machine energy
    assert a["chip_calls"] == 0 and a["machine_energy_per_task_j"] == 0.0 and a["host_s"] > 0


def test_a_scheduler_of_ones_own_without_accounting_runs_under_the_clock():
    sched = KeepScheduler()
    record, sim, step_s = run_lorr(EXAMPLE, sched, "pibt", steps=40, limit=StepLimit(1.0))
    assert sched.calls == record["decisions"] == len(step_s) == 40
    assert record["scheduler"] == "KeepScheduler" and record["clock"] == "1 s per step"
    assert record["tasks_finished"] == sim.finished and record["schedule_errors"] == 0
    assert record["paper_energy_per_task_j"] == record["host_energy_per_task_j"]  # not accelerated: host x 15 W


def test_an_object_that_is_not_a_planner_is_refused_naming_the_role():
    with pytest.raises(ValueError, match="planner object does not meet the Planner role: a Planner has actions"):
        run_lorr(EXAMPLE, "lorr-greedy", object(), steps=5)
    with pytest.raises(ValueError, match="scheduler object does not meet the Scheduler role: a Scheduler has schedule"):
        run_lorr(EXAMPLE, object(), "pibt", steps=5)
    with pytest.raises(ValueError, match="options= goes with a scheduler and a planner named by strings"):
        run_lorr(EXAMPLE, "lorr-greedy", ForwardPlanner(read_instance(EXAMPLE).grid), steps=5, options={"replan": 1})


def test_a_class_by_name_in_an_entry_file_and_on_the_command_line(tmp_path):
    inst = read_instance(EXAMPLE)
    own, sim_own, _ = run_lorr(inst, "lorr-greedy", ForwardPlanner(inst.grid), steps=30)
    entry = tmp_path / "mine.toml"
    entry.write_text('name = "mine"\n[[rule]]\nscheduler = "lorr-greedy"\nplanner = "lorr_own_planner:ForwardPlanner"\n')
    choice = load_entry(entry).choose(inst)
    assert choice.planner == PlannerSpec("lorr_own_planner:ForwardPlanner", {})
    assert choice.scheduler == SchedulerSpec("lorr-greedy", {})
    by_entry, sim_entry, _ = run_lorr(inst, choice.scheduler, choice.planner, steps=30)
    assert output_dict(sim_entry)["actualPaths"] == output_dict(sim_own)["actualPaths"]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(EXAMPLES), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, "-m", "agents.cli", "lorr", "run", str(EXAMPLE), "--planner",
                           "lorr_own_planner:ForwardPlanner", "--steps", "30", "--json", "--no-progress"],
                          capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr
    row = json.loads(proc.stdout.strip().splitlines()[-1])
    assert (row["executor"], row["tasks_finished"]) == ("lorr_own_planner:ForwardPlanner", own["tasks_finished"])
    bad = subprocess.run([sys.executable, "-m", "agents.cli", "lorr", "run", str(EXAMPLE), "--planner",
                          "lorr_own_planner:STEP", "--steps", "5", "--no-progress"],
                         capture_output=True, text=True, env=env, timeout=300)
    assert bad.returncode == 2 and bad.stderr.strip() == "mrmt lorr: error: 'lorr_own_planner:STEP' is not a class"
