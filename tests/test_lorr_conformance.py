"""League of Robot Runners: rules pinned against the start kit where a plausible mistake would pass the other tests.

Each test here fails under one such mistake: errands counted in any order, task events written a step late, the
open-task count ``numTasksReveal x teamSize`` rounded the other way, a robot switching away from an opened task.
"""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from lorr_reference import check_events, replay_cells

from mrmt_env.lorr.output import check_output, output_dict
from agents.lorr.run import run_lorr
from mrmt_env.lorr.instance import example_instance_path, read_instance
from mrmt_env.lorr.sim import LoRRSimulator

EXAMPLE = example_instance_path()


def _corridor(tmp_path, reveal=1, team=1, tasks=("4,2", "0")):
    """A 1 x 5 corridor, ``team`` robots from its west end, ``tasks`` (errand columns)."""
    (tmp_path / "c.map").write_text("type octile\nheight 1\nwidth 5\nmap\n.....\n")
    (tmp_path / "c.agents").write_text(f"{team}\n" + "".join(f"{a}\n" for a in range(team)))
    (tmp_path / "c.tasks").write_text(f"{len(tasks)}\n" + "".join(f"{t}\n" for t in tasks))
    path = tmp_path / "CORRIDOR.json"
    path.write_text(json.dumps({"mapFile": "c.map", "agentFile": "c.agents", "teamSize": team, "taskFile": "c.tasks",
                                "numTasksReveal": reveal}))
    return path


#: A fixed output on the corridor: robot 0 takes task 0 (errands: column 4, then column 2) after the first step,
#: passes its last errand (column 2, step 2) before its first (column 4, step 4), turns, and reaches column 2
#: again at step 8.  Only then is the task finished.
FIXED = {"actionModel": "MAPF_T", "teamSize": 1, "start": [[0, 0, "E"]], "numTaskFinished": 1,
         "actualPaths": ["F,F,F,F,R,R,F,F"], "actualSchedule": ["1:0"],
         "events": [[4, 0, 0, 1], [8, 0, 0, 2]], "tasks": [[0, 0, [0, 4, 0, 2]], [1, 0, [0, 0]]]}


def _prefix(data: dict, steps: int) -> dict:
    out = dict(data)
    out["actualPaths"] = [",".join(p.split(",")[:steps]) for p in data["actualPaths"]]
    out["events"] = [e for e in data["events"] if e[0] <= steps]
    return out


def test_the_last_errand_counts_only_after_the_others_in_order(tmp_path):
    inst = read_instance(_corridor(tmp_path))
    full = check_output(inst, FIXED)
    assert (full.tasks_finished, full.errands, full.errors, full.events_agree) == (1, 2, 0, True)
    # seven steps: the robot has passed its last errand and reached its first; nothing is finished
    seven = check_output(inst, _prefix(FIXED, 7))
    assert (seven.tasks_finished, seven.errands, seven.events_agree) == (0, 1, True)
    assert check_events(FIXED, inst.width) == 1
    # the simulator itself: the same walk gives the same events, at the same steps
    sim = LoRRSimulator(inst)
    for t, letter in enumerate("FFFFRRFF"):
        sim.step(np.array(["FRCW".index(letter)]), np.array([0]) if t == 0 else None)
        if t == 6:
            assert sim.finished == 0 and sim.tasks.errands_done == 1
    assert [list(e) for e in sim.tasks.events] == FIXED["events"] and sim.finished == 1


def test_the_event_oracle_walks_the_fixed_output_by_hand(tmp_path):
    cells = replay_cells(FIXED, 5)
    assert [c[0] for c in cells] == [0, 1, 2, 3, 4, 4, 4, 3, 2]
    late = dict(FIXED, events=[[5, 0, 0, 1], [8, 0, 0, 2]])  # the first errand a step late
    with pytest.raises(AssertionError, match="stood on errand 1 at step 4"):
        check_events(late, 5)
    assert not check_output(read_instance(_corridor(tmp_path)), late).events_agree


@pytest.mark.parametrize("scheduler, executor", [("lorr-greedy", "pibt"), ("strong", "epibt")])
def test_every_event_of_a_run_is_where_and_when_the_robot_reached_its_errand(scheduler, executor):
    """The oracle of ``tests/lorr_reference.py``: the written output's ``actualPaths`` walked by hand, each
    event ``[t, robot, task, n]`` against the robot's cell at step ``t``, ``n`` rising 1, 2, ... per task."""
    _, sim, step_s = run_lorr(EXAMPLE, scheduler, executor, steps=150, seed=0)
    data = json.loads(json.dumps(output_dict(sim, step_s)))
    assert len(data["events"]) > 20
    assert check_events(data, sim.width) == data["numTaskFinished"] == sim.finished
    assert check_output(read_instance(EXAMPLE), data).events_agree


def test_open_tasks_are_numTasksReveal_times_teamSize_truncated_as_the_start_kit_stores_it(tmp_path):
    """The start kit (v2.1 ``TaskManager.h``) keeps ``int num_tasks_reveal = num * num_of_agents`` with ``num`` a
    float: the float product, truncated.  1.3 x 8 = 10.4 keeps 10 tasks open; 1.5 x 8 keeps 12."""
    src = EXAMPLE.parent
    for f in src.iterdir():
        shutil.copy(f, tmp_path / f.name)
    path = tmp_path / EXAMPLE.name
    for reveal, target in ((1.3, 10), (1.5, 12), (0.7, 5), (2, 16)):
        path.write_text(path.read_text().replace('"numTasksReveal": 1.5', f'"numTasksReveal": {reveal}')
                        if reveal != 1.5 else (src / EXAMPLE.name).read_text())
        sim = LoRRSimulator(read_instance(path))
        assert sim.tasks.target == target and len(sim.tasks.open) == target, reveal
        path.write_text((src / EXAMPLE.name).read_text())


def test_a_robot_with_an_opened_task_may_neither_drop_it_nor_switch_to_another():
    sim = LoRRSimulator(read_instance(EXAMPLE))
    pool = sim.tasks
    task = next(k for k in pool.open if len(pool.errands_of(k)) > 1)
    other = next(k for k in pool.open if k != task)
    first = int(pool.errands_of(task)[0])
    assert pool.propose(np.array([task] + [-1] * 7), 1)
    pool.arrive(np.array([first] + [-2] * 7), 1)  # robot 0 reaches the first errand: the task is opened
    assert pool.is_opened(task) and pool.goal[0] == int(pool.errands_of(task)[1])
    for bad in ([other] + [-1] * 7, [-1, task] + [-1] * 6, [-1] * 8):
        n = len(pool.schedule_errors)
        assert not pool.propose(np.array(bad), 2)
        assert len(pool.schedule_errors) == n + 1 and "opened" in pool.schedule_errors[-1][0]
        assert pool.assigned.tolist() == [task] + [-1] * 7
    # an unopened task may be switched: robot 1 takes ``other`` and then a third task
    third = next(k for k in pool.open if k not in (task, other))
    assert pool.propose(np.array([task, other] + [-1] * 6), 3)
    assert pool.propose(np.array([task, third] + [-1] * 6), 4)
