"""The start kit's step, once (:class:`mrmt_env.lorr.loop.StepLoop`): the env and the runner step the same way."""

from __future__ import annotations

import numpy as np
import pytest

from agents.lorr.run import make_roles, run_lorr
from agents.lorr.spec import PlannerSpec, SchedulerSpec
from mrmt_env.lorr.env import LoRREnv
from mrmt_env.lorr.greedy import GreedyScheduler
from mrmt_env.lorr.instance import example_instance_path, read_instance
from mrmt_env.lorr.loop import StepLoop
from mrmt_env.lorr.output import output_dict
from mrmt_env.lorr.sim import LoRRSimulator
from mrmt_env.lorr.rules import TIMEOUT, WAIT


def _waits(n):
    return np.full(n, WAIT, dtype=np.int64)


def test_late_decisions_cost_their_timeouts_before_the_move_and_never_pass_the_end():
    loop = StepLoop(LoRRSimulator(read_instance(example_instance_path())), GreedyScheduler())
    sim = loop.sim
    loop.propose()
    loop.advance(_waits(sim.n_robots), late=2, steps=10)
    assert (sim.t, sim.timeouts) == (3, 2)  # two steps every robot waited, then the move
    loop.propose()
    loop.advance(_waits(sim.n_robots), late=50, steps=10)
    assert (sim.t, sim.timeouts) == (10, 9)  # the run ends at 10: seven timeouts fit, the move does not
    written = [set(a.tolist()) for a in sim.actual]
    assert written[:2] == [{TIMEOUT}, {TIMEOUT}] and written[2] == {WAIT}  # timeouts first, then the move
    assert len(written) == 10 and written[3:].count({TIMEOUT}) == 7


def test_the_env_and_a_hand_loop_with_the_runners_planner_step_alike():
    """The env, given the runner's planner's actions towards its observed goals, writes the runner's output."""
    inst = read_instance(example_instance_path())
    record, sim, _ = run_lorr(inst, "lorr-greedy", "pibt", steps=40, seed=0)
    sched, ex = make_roles(inst.grid, SchedulerSpec("lorr-greedy"), PlannerSpec.of("pibt"), seed=0)
    env = LoRREnv(instance=inst, steps=40, scheduler=sched)
    obs, _ = env.reset(seed=0)
    for _ in range(40):
        goals = np.where(obs["goal"] >= 0, obs["goal"], obs["position"])
        obs, *_ = env.step(ex.actions(obs["position"], obs["orientation"], goals))
    assert env.sim.finished == record["tasks_finished"] > 0
    assert output_dict(env.sim) == output_dict(sim)


def test_a_held_schedule_is_checked_and_applied():
    loop = StepLoop(LoRRSimulator(read_instance(example_instance_path())))
    r = loop.sim.n_robots
    with pytest.raises(ValueError, match=rf"expected \({r},\) integers, got shape \(3,\)"):
        loop.hold([0, 1, 2])
    tasks = loop.sim.tasks
    held = np.array(sorted(tasks.open)[:r], dtype=np.int64)  # robot k takes the k-th open task
    loop.hold(held)
    assert loop.pending.tolist() == held.tolist()
    first = [int(tasks.remaining(int(k))[0]) for k in held]  # each task's first errand, read from the task
    assert loop.goals().tolist() == first and loop.goal_cells().tolist() == first
    loop.advance(np.full(r, WAIT, dtype=np.int64))
    assert tasks.assigned.tolist() == held.tolist()  # the move applied the held proposal
