"""Robots at work by the task still to go (``active_by="task"``): each robot's task beyond its goal
(:func:`mrmt_env.lorr.tasks.rest_under`), handed by the step loop to a planner that takes it, and the at-work choice
it feeds (:meth:`planners.mapf.planner.TurningPlanner.steer`)."""

from __future__ import annotations

import numpy as np
import pytest

from agents.lorr.run import make_roles, run_lorr
from agents.lorr.spec import PlannerSpec, SchedulerSpec
from mrmt_env.lorr.instance import example_instance_path, read_instance
from mrmt_env.lorr.loop import StepLoop
from mrmt_env.lorr.sim import LoRRSimulator
from mrmt_env.lorr.tasks import rest_under
from planners.mapf import make_turning_planner


def _legs_by_coordinates(inst, line: int, done: int) -> int:
    """The task's Manhattan legs after its next errand, from the instance's (row, col) of each errand."""
    rc = [divmod(int(c), inst.width) for c in inst.task_errands(line)][done:]
    return sum(abs(r0 - r1) + abs(c0 - c1) for (r0, c0), (r1, c1) in zip(rc, rc[1:]))


def test_the_rest_is_the_legs_beyond_each_robots_goal_counted_from_its_errand_events():
    inst = read_instance(example_instance_path())
    _record, sim, _ = run_lorr(inst, "lorr-greedy", "pibt", steps=30, seed=0)
    tasks = sim.tasks
    done = {}  # errands done per task, from the written events alone
    for _t, _a, task, n in tasks.events:
        done[task] = max(done.get(task, 0), n)
    expected = np.zeros(sim.n_robots, dtype=np.int64)
    for a, k in enumerate(tasks.assigned.tolist()):
        if k >= 0:
            expected[a] = _legs_by_coordinates(inst, tasks.line[k], done.get(k, 0))
    rest = rest_under(tasks, inst.width)
    assert rest.tolist() == expected.tolist()
    assert (rest > 0).any() and (rest == 0).any()  # tasks of several errands and robots on their last leg


def test_under_a_proposal_a_new_task_counts_from_its_first_errand():
    inst = read_instance(example_instance_path())
    loop = StepLoop(LoRRSimulator(inst))
    tasks = loop.sim.tasks
    many = [k for k in tasks.open if len(tasks.errands_of(k)) >= 3]
    proposal = np.full(loop.sim.n_robots, -1, dtype=np.int64)
    proposal[2] = many[0]
    loop.hold(proposal)
    rest = loop.rest_for(type("P", (), {"takes_rest": True})())["rest"]
    assert rest[2] == _legs_by_coordinates(inst, tasks.line[many[0]], 0) > 0
    assert rest.tolist().count(0) == loop.sim.n_robots - 1  # the others hold no task
    assert loop.rest_for(object()) == {}  # a planner that does not take it gets nothing


def _corridor(n: int = 9):
    grid = np.ones((3, n), dtype=bool)  # True: blocked
    grid[1, :] = False  # one open row
    return grid


@pytest.mark.parametrize("planner", ["pibt", "epibt"])
def test_the_robots_at_work_are_those_of_least_way_plus_rest(planner):
    grid = _corridor()
    w = grid.shape[1]
    pos = np.array([w + 1, w + 3, w + 5, w + 7], dtype=np.int64)
    goals = pos + np.array([-1, 1, -1, 1])  # every robot one move from its goal
    rest = np.array([9, 0, 4, 2], dtype=np.int64)
    by_task = make_turning_planner(planner, grid, active=0.5, active_by="task")
    assert by_task.takes_rest
    steered = by_task.steer(pos, goals, rest)
    assert (steered != pos).tolist() == [False, True, False, True]  # the two of least rest keep their goals
    by_goal = make_turning_planner(planner, grid, active=0.5)
    assert not by_goal.takes_rest and (by_goal.steer(pos, goals) != pos).tolist() == [True, True, False, False]
    assert not make_turning_planner(planner, grid, active_by="task").takes_rest  # everyone at work: nothing to rank


@pytest.mark.parametrize("rest, got", [(None, "got none"), (np.zeros(3, dtype=np.int64), "shape (3,)"),
                                       (np.zeros(4), "dtype float64"), (np.array([0, -1, 0, 0]), "a negative length")])
def test_a_planner_ranking_by_task_names_a_missing_or_bad_rest(rest, got):
    grid = _corridor()
    ex = make_turning_planner("epibt", grid, active=0.5, active_by="task")
    pos = np.array([10, 12, 14, 16], dtype=np.int64)
    with pytest.raises(ValueError, match="active_by='task' needs rest") as err:
        ex.actions(pos, np.zeros(4, dtype=np.int64), pos + 1, rest=rest)
    assert got in str(err.value)


def test_a_run_ranking_by_task_is_deterministic_and_differs_from_ranking_by_goal():
    inst = read_instance(example_instance_path())
    opts = {"executor_options": {"active": 0.5, "active_by": "task"}}
    a, sim_a, _ = run_lorr(inst, "lorr-greedy", "epibt", steps=60, seed=1, options=opts)
    b, sim_b, _ = run_lorr(inst, "lorr-greedy", "epibt", steps=60, seed=1, options=opts)
    c, sim_c, _ = run_lorr(inst, "lorr-greedy", "epibt", steps=60, seed=1,
                           options={"executor_options": {"active": 0.5}})
    paths = [np.array(s.actual).tolist() for s in (sim_a, sim_b, sim_c)]
    assert paths[0] == paths[1] and paths[0] != paths[2]
    assert a["tasks_finished"] == sim_a.finished
    _sched, ex = make_roles(inst.grid, SchedulerSpec("lorr-greedy"), PlannerSpec.of("epibt", opts["executor_options"]))
    assert ex.takes_rest
