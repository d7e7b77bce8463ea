"""A stand-in of the 2024 start kit's C++ side for the adapter's tests (test code only).

The fields of the kit's ``SharedEnvironment`` as its Python binding shows them (``python/common/MAPFbinding.cpp``:
``rows``, ``cols``, ``map`` with 1 for a blocked cell, ``map_name``, ``num_of_agents``, ``curr_timestep``,
``curr_states`` of ``State(location, timestep, orientation)``, ``task_pool`` as a map from task id to ``Task``
(``task_id``, ``locations``, ``idx_next_loc``, ``t_revealed``, ``agent_assigned``), ``curr_task_schedule``,
``new_tasks``, ``new_freeagents``, ``goal_locations`` of ``(cell, t_revealed)`` pairs, ``plan_start_time`` and
``plan_current_time()`` on a steady clock) and the kit's step (``Entry::compute``: the scheduler's plan, the
goal locations set from the proposal, the planner's plan), with the package's own simulator as the rules.
"""

from __future__ import annotations

import datetime
import time
from dataclasses import dataclass

from mrmt_env.lorr.sim import LoRRSimulator


@dataclass
class State:
    location: int
    timestep: int
    orientation: int


@dataclass
class Task:
    task_id: int
    locations: list
    idx_next_loc: int
    t_revealed: int
    agent_assigned: int


class SharedEnvironment:
    """The kit's shared environment, synchronised from a :class:`LoRRSimulator` as the kit's simulator does."""

    def __init__(self, inst) -> None:
        self.rows, self.cols = (int(v) for v in inst.grid.shape)
        self.map = [int(v) for v in inst.grid.reshape(-1)]
        self.map_name = inst.map_name
        self.num_of_agents = inst.team_size
        self.file_storage_path = ""
        self.curr_timestep = 0
        # what the kit has not set yet when it calls initialize (it reveals the first tasks after it)
        self.curr_states, self.task_pool, self.curr_task_schedule = [], {}, []
        self.new_tasks, self.new_freeagents, self.goal_locations = [], [], []
        self.plan_start_time = SharedEnvironment.plan_current_time()

    @staticmethod
    def plan_current_time() -> datetime.timedelta:
        return datetime.timedelta(seconds=time.monotonic())

    def sync(self, sim: LoRRSimulator) -> None:
        tasks = sim.tasks
        self.goal_locations = self.goal_locations or [[] for _ in range(sim.n_robots)]
        self.curr_timestep = sim.t
        self.curr_states = [State(int(p), sim.t, int(o)) for p, o in zip(sim.pos.tolist(), sim.orient.tolist())]
        self.task_pool = {k: Task(k, [int(c) for c in tasks.errands_of(k).tolist()], tasks.next_idx[k],
                                  tasks.revealed_at[k], tasks.holder[k]) for k in reversed(list(tasks.open))}
        self.curr_task_schedule = [int(k) for k in tasks.assigned.tolist()]
        self.new_tasks = list(tasks.new_tasks)
        self.new_freeagents = list(tasks.new_free)

    def update_goal_locations(self, proposal: list) -> None:
        """``Entry::update_goal_locations``: the proposal recorded, each robot's goal its task's next errand."""
        self.curr_task_schedule = list(proposal)
        for a, k in enumerate(proposal):
            self.goal_locations[a] = []
            if k != -1:
                task = self.task_pool[k]
                self.goal_locations[a].append((task.locations[task.idx_next_loc], task.t_revealed))


class SharedEnvironment2026(SharedEnvironment):
    """The 2026 kit's (v3.1) fields as far as a one-step planner sees them: no ``plan_start_time`` nor
    ``plan_current_time`` in its binding, and ``curr_timestep`` 0 (the planning snapshot's own start)."""

    def __init__(self, inst, window_ticks: int | None = None) -> None:
        super().__init__(inst)
        del self.plan_start_time
        if window_ticks is not None:  # the kit's rhythm: a call every window_ticks ticks of 100 ms, an action a tick
            self.min_planner_communication_time, self.action_time, self.max_counter = 100 * window_ticks, 100, 1

    plan_current_time = property(lambda self: _absent("plan_current_time"))

    def sync(self, sim: LoRRSimulator) -> None:
        super().sync(sim)
        self.curr_timestep = 0


def _absent(name):
    raise AttributeError(f"'SharedEnvironment' object has no attribute {name!r}")


def run_standin(inst, steps: int, scheduler_cls, planner_cls, time_limit_ms: int = 3_600_000, kit: int = 2024,
                window_ticks: int | None = None, **role) -> LoRRSimulator:
    """``steps`` steps of ``inst`` as the kit runs a Python entry: roles built with the env (2026: built bare, the
    env set before ``initialize``), initialized, then per step the scheduler's and the planner's ``plan`` (every
    answer checked to be a list of plain ints; 2026: a one-action window per robot, executed one action a tick)."""
    sim = LoRRSimulator(inst)
    if kit == 2026:
        env = SharedEnvironment2026(inst, window_ticks)
        scheduler, planner = scheduler_cls(**role), planner_cls(**role)
        scheduler.env = planner.env = env
    else:
        env = SharedEnvironment(inst)
        scheduler, planner = scheduler_cls(env, **role), planner_cls(env, **role)
    assert scheduler.initialize(30_000) and planner.initialize(30_000)  # before the kit shows any task
    while sim.t < steps:
        env.sync(sim)
        if kit == 2024:
            env.plan_start_time = env.plan_current_time()
        proposal = scheduler.plan(time_limit_ms)
        assert isinstance(proposal, list) and all(type(k) is int for k in proposal)
        env.update_goal_locations(proposal)
        actions = planner.plan(time_limit_ms)
        if kit == 2026:  # a window per robot, one action a tick until the next call, the proposal applied at the first
            assert isinstance(actions, list) and all(type(w) is list and len(w) >= (window_ticks or 1)
                                                     for w in actions)
            for j in range(window_ticks or 1):
                if sim.t == steps:
                    break
                tick = [w[j] for w in actions]
                assert all(type(a) is int and 0 <= a <= 3 for a in tick)
                sim.step(tick, proposal if j == 0 else [int(k) for k in sim.tasks.assigned.tolist()])
            continue
        assert isinstance(actions, list) and all(type(a) is int and 0 <= a <= 3 for a in actions)
        sim.step(actions, proposal)
    return sim
