"""Parking at density (agents/lorr/parking.py): at most a share of the team holds tasks, the nearest new
assignments kept, held tasks never dropped; any scheduler takes the option; bad values named."""

from __future__ import annotations

import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from agents.lorr.parking import Parked
from agents.lorr.run import run_lorr
from agents.lorr.schedulers import make_scheduler
from mrmt_env.lorr.instance import example_instance_path, read_instance
from planners.compute import ComputeReport


class _Fixed:
    """A scheduler proposing a fixed schedule (the inner one under test)."""

    name, accelerated, last_compute = "fixed", False, ComputeReport()

    def __init__(self, proposal):
        self.proposal = np.asarray(proposal, dtype=np.int64)

    def reset(self, sim):
        pass

    def schedule(self, sim, deadline=None):
        return self.proposal.copy()


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 10**6), st.integers(1, 12), st.floats(0.05, 1.0))
def test_parking_keeps_held_tasks_and_the_nearest_new_ones(seed, robots, busy):
    """Oracle: held tasks stay; of the new assignments, the ``busy x team - held`` nearest (Manhattan way to the
    task's first errand, ties by robot) stay, the others are dropped."""
    rng = np.random.default_rng(seed)
    width = 7
    assigned = np.where(rng.random(robots) < 0.4, rng.permutation(robots), -1)
    proposal = np.where(rng.random(robots) < 0.7, rng.permutation(robots) + 100, -1)
    keep_old = rng.random(robots) < 0.5
    proposal = np.where((assigned >= 0) & keep_old, assigned, proposal)
    first = {int(k): int(rng.integers(0, 49)) for k in np.concatenate([proposal, assigned]).tolist() if k >= 0}
    sim = SimpleNamespace(width=width, pos=rng.integers(0, 49, robots),
                          tasks=SimpleNamespace(assigned=assigned, remaining=lambda k: np.array([first[k]])))
    out = Parked(_Fixed(proposal), busy).schedule(sim)
    held = [a for a in range(robots) if proposal[a] >= 0 and proposal[a] == assigned[a]]
    new = [a for a in range(robots) if proposal[a] >= 0 and a not in held]
    room = max(int(busy * robots) - len(held), 0)

    def way(a):
        c, g = int(sim.pos[a]), first[int(proposal[a])]
        return abs(c // width - g // width) + abs(c % width - g % width), a

    kept = sorted(new, key=way)[:room]
    expected = np.full(robots, -1)
    for a in held + kept:
        expected[a] = proposal[a]
    assert np.array_equal(out, expected)


def test_a_parked_run_holds_no_more_busy_robots_than_its_share():
    """On the example (8 robots), busy = 0.5: every step's proposal has at most 4 busy robots beyond those whose
    task was held, no schedule error, and the run re-checks; busy = 1 is the scheduler itself."""
    inst = read_instance(example_instance_path())
    from agents.lorr.roles import Scheduler

    sched = make_scheduler("lorr-greedy", busy=0.5)
    assert isinstance(sched, Parked) and isinstance(sched, Scheduler)  # the start kit's role, as every scheduler
    assert not isinstance(make_scheduler("lorr-greedy", busy=1), Parked)
    record, sim, _ = run_lorr(inst, "lorr-greedy", "pibt", steps=60, options={"scheduler_options": {"busy": 0.5}})
    assert record["schedule_errors"] == 0 and record["tasks_finished"] > 0
    counts = np.zeros(61, dtype=np.int64)
    for row in sim.tasks.actual_schedule:  # (step, task) changes per robot: the robots holding a task each step
        for (t0, k), nxt in zip(row, row[1:] + [(61, -1)]):
            if k >= 0:
                counts[t0:nxt[0]] += 1
    assert counts.max() <= 4
    full, _, _ = run_lorr(inst, "lorr-greedy", "pibt", steps=60, options={"scheduler_options": {"busy": 1.0}})
    plain, _, _ = run_lorr(inst, "lorr-greedy", "pibt", steps=60)
    assert full["tasks_finished"] == plain["tasks_finished"]


@pytest.mark.parametrize("busy", [0, -0.5, 1.5, float("nan"), True, "half"])
def test_a_bad_share_is_named(busy):
    with pytest.raises(ValueError, match=r"busy = .* in \(0, 1\]"):
        make_scheduler("strong", busy=busy)


def test_the_command_line_refuses_a_bad_share_in_one_line():
    out = subprocess.run([sys.executable, "-m", "agents.cli", "lorr", "run", str(example_instance_path()),
                          "--scheduler", "lorr-greedy", "--scheduler-option", "busy=2", "--steps", "5"],
                         capture_output=True, text=True)
    assert out.returncode == 2 and "busy = 2" in out.stderr and "Traceback" not in out.stderr


def test_the_greedy_way_weight_one_is_the_start_kits_and_bad_weights_are_named():
    """``way`` (lorr-greedy): 1 is the start kit's greedy to the step; another weight runs valid; bad ones named."""
    inst = read_instance(example_instance_path())
    plain, _, _ = run_lorr(inst, "lorr-greedy", "pibt", steps=60)
    one, _, _ = run_lorr(inst, "lorr-greedy", "pibt", steps=60, options={"scheduler_options": {"way": 1}})
    five, _, _ = run_lorr(inst, "lorr-greedy", "pibt", steps=60, options={"scheduler_options": {"way": 5, "busy": 0.5}})
    assert one["tasks_finished"] == plain["tasks_finished"] and one["errands"] == plain["errands"]
    assert five["schedule_errors"] == 0 and five["errors"] == 0
    for way in (0, 65, 2.5, True):
        with pytest.raises(ValueError, match=rf"way = {way!r} must be an integer in \[1, 64\]"):
            make_scheduler("lorr-greedy", way=way)
    with pytest.raises(ValueError, match="lorr-greedy takes no option 'jam'; its options: way, busy"):
        make_scheduler("lorr-greedy", jam=4)
