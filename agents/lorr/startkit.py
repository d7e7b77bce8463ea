"""The package's scheduler and planner inside the League's own simulator (the 2024 start kit's Python track).

:class:`KitScheduler` and :class:`KitPlanner` are the start kit's ``pyTaskScheduler`` and ``pyMAPFPlanner``; the
entry (``MRMT_LORR_ENTRY``, default ``default``; seed ``MRMT_LORR_SEED``) chooses what runs. Steps to build the kit
and run it: docs/lorr.md ("Inside the start kit"); design notes: docs/design/lorr_runs.md#inside-the-start-kit.
"""

from __future__ import annotations

import datetime
import os
import time
from pathlib import Path

import numpy as np

__all__ = ["KitScheduler", "KitPlanner", "KitPlanner2026", "KitInstance", "KitTasks", "KitState", "view_of", "TRACK_DIR",
           "TRACK_DIR_2026"]

#: The folder holding ``pyMAPFPlanner.py`` and ``pyTaskScheduler.py`` for the kit's ``config.json``
#: (``{"python_path": "<this folder>"}``).
TRACK_DIR = Path(__file__).resolve().parent / "startkit_track"
#: The 2026 kit's (v3.1) modules: it imports ``python/user_planner/pyMAPFPlanner.py`` and
#: ``python/user_scheduler/pyTaskScheduler.py`` from its own folder, which these replace.
TRACK_DIR_2026 = Path(__file__).resolve().parent / "startkit_track_2026"
#: Most actions a robot in one 2026 window.
MAX_WINDOW = 100


class KitInstance:
    """What an entry and the schedulers read of an instance, from the kit's ``env`` (the map, the team, each
    task's errands as the kit's task pool shows them).  At ``initialize`` the kit has set only the map, its
    name and the team: the tasks come with the first step."""

    strategy = None  # 2024 rules: a scheduler assigns

    def __init__(self, env) -> None:
        self.height, self.width = int(env.rows), int(env.cols)
        self.grid = np.asarray(list(env.map), dtype=np.int64).reshape(self.height, self.width) == 1
        self.team_size = int(env.num_of_agents)
        self.map_name = Path(str(env.map_name)).name
        self.name = Path(self.map_name).stem
        self.errands: dict[int, np.ndarray] = {}  # task id -> its errand cells (a task's errands never change)
        self.env = env
        self.target: int | None = None

    def task_errands(self, task: int) -> np.ndarray:
        return self.errands[task]

    def open_target(self) -> int:
        """The open tasks the kit keeps (``numTasksReveal x teamSize``): its pool's size from the first step."""
        if self.target is None:
            self.target = max(len(self.env.task_pool), 1)
        return self.target


class KitTasks:
    """The kit's task pool as the package's schedulers read a :class:`~mrmt_env.lorr.tasks.TaskPool`: open
    tasks in reveal order (ids rise as the kit reveals), each one's errands done and holder, every robot's
    task and next errand, the tasks and free robots new this step.  A task's ``line`` is its id.

    Read incrementally (at 10,000 robots a full read of the pool costs a tenth of the step): a task's errands
    once, when it appears; its errands done again only where its holder stands on its next errand (the kit
    advances a task only there); the holders from the schedule."""

    def __init__(self, env, inst: KitInstance) -> None:
        self.env = env
        self.inst = inst
        self.open: dict[int, None] = {}  # in reveal order: a new task's id is above every id before it
        self.line: dict[int, int] = {}
        self.next_idx: dict[int, int] = {}
        self._cell: dict[int, int] = {}  # task id -> its next errand (a Python int: the loop below reads many)

    def refresh(self, pos: np.ndarray, every: bool = False) -> "KitTasks":
        """This step's pool and schedule from the kit, the robots standing at ``pos``; ``every``: each held task's
        errands done read again, not only where its holder stands (robots moved several ticks since the last read)."""
        env, inst = self.env, self.inst
        pool = env.task_pool
        now = set(pool.keys())
        for k in [k for k in self.open if k not in now]:  # finished: out of every cache
            del self.open[k], self.line[k], self.next_idx[k], self._cell[k], inst.errands[k]
        for k in sorted(now.difference(self.open)):  # new
            task = pool[k]
            locations = list(task.locations)
            inst.errands[k] = np.asarray(locations, dtype=np.int64)
            self.next_idx[k] = i = int(task.idx_next_loc)
            self._cell[k] = int(locations[i])
            self.open[k] = None
            self.line[k] = k
        cell, next_idx = self._cell, self.next_idx
        schedule = list(env.curr_task_schedule)
        goal = [-1] * len(schedule)
        self.holder = dict.fromkeys(self.open, -1)
        for a, (k, p) in enumerate(zip(schedule, pos.tolist())):
            if k < 0:
                continue
            if every or p == cell[k]:  # it arrived: the kit may have moved the task on
                i = next_idx[k] = int(pool[k].idx_next_loc)
                cell[k] = int(inst.errands[k][i])
            goal[a] = cell[k]
            self.holder[k] = a
        self.assigned = np.array(schedule, dtype=np.int64)
        self.goal = np.array(goal, dtype=np.int64)
        self.new_tasks = [int(k) for k in env.new_tasks]
        self.new_free = [int(a) for a in env.new_freeagents]
        return self

    def goals(self, schedule, pos: np.ndarray) -> np.ndarray:
        """Each robot's goal under ``schedule`` (the kit's ``goal_locations``, read from the view: the next errand of
        its task, or its own cell without one)."""
        cell = self._cell
        return np.array([cell.get(k, p) for k, p in zip(schedule, pos.tolist())], dtype=np.int64)

    def errands_of(self, task: int) -> np.ndarray:
        return self.inst.errands[task]

    def remaining(self, task: int) -> np.ndarray:
        return self.inst.errands[task][self.next_idx[task]:]

    def is_opened(self, task: int) -> bool:
        return self.next_idx[task] > 0

    def open_tasks(self) -> np.ndarray:
        return np.fromiter(self.open, dtype=np.int64, count=len(self.open))


class KitState:
    """The read-only view of the run the roles get, one object for the whole run (a scheduler may keep state
    between steps of the same run): the instance, and as of :meth:`refresh` the tasks, each robot's cell and
    orientation, the step.  The two roles of one kit share it (:func:`view_of`): the robots are read once a
    step (a pybind attribute a robot: 10,000 robots take tens of milliseconds)."""

    def __init__(self, env, inst: KitInstance) -> None:
        self.env = env
        self.inst = inst
        self.width = inst.width
        self.n_robots = inst.team_size
        self._tasks = KitTasks(env, inst)
        self.t: int | None = None
        self.tasks: KitTasks | None = None
        self.fresh = False  # read by the scheduler of this step, not yet used by the planner
        self.windows = False  # the planner returns several actions a call: read every held task's progress
        self._kit_t: int | None = None
        self._reads = 0

    def refresh(self, tasks: bool = True, again: bool = False) -> "KitState":
        """This step's fields from the kit's ``env``: read when the step is new or ``again`` (the scheduler,
        first in the kit's step, reads them; the planner after it in the same step reuses them); the tasks
        when asked.  A step is new when the kit's ``curr_timestep`` moved (2024) or, where it stays 0 (the 2026
        kit's planning snapshot), when no scheduler read it since the planner's last call.  :attr:`t` is the kit's
        step, or where the kit keeps it at 0 the count of steps read before this one."""
        env = self.env
        t = int(env.curr_timestep)
        if again or t != self._kit_t or not self.fresh:
            states = env.curr_states
            self.pos = np.fromiter((s.location for s in states), dtype=np.int64, count=len(states))
            self.orient = np.fromiter((s.orientation for s in states), dtype=np.int64, count=len(states))
            self._kit_t = t
            self.t = t if t > 0 else self._reads
            self._reads += 1
            self.tasks = None
        if tasks and self.tasks is None:
            self.tasks = self._tasks.refresh(self.pos, every=self.windows)
        self.fresh = again
        return self


_VIEW: list = [None]  # the view of the kit this process runs (one kit, two roles)


def view_of(env) -> KitState:
    """The one view of the kit's ``env`` its roles share (a new ``env``: a new view)."""
    view = _VIEW[0]
    if view is None or view.env is not env:
        view = _VIEW[0] = KitState(env, KitInstance(env))
    return view


def deadline_of(env, time_limit: int) -> float:
    """The ``time.perf_counter()`` second by which the kit wants this step's answer: ``time_limit`` ms after
    ``env.plan_start_time`` on the kit's clock (2024); from now where the kit shows no start (2026)."""
    if not hasattr(env, "plan_current_time"):
        return time.perf_counter() + int(time_limit) / 1000.0
    left = env.plan_start_time + datetime.timedelta(milliseconds=int(time_limit)) - env.plan_current_time()
    return time.perf_counter() + left.total_seconds()


class _Role:
    """What both roles share: the kit's ``env``, the entry's choice on it, the seed."""

    def __init__(self, env=None, entry: str | None = None, seed: int | None = None) -> None:
        self.env = env
        self.entry = entry if entry is not None else os.environ.get("MRMT_LORR_ENTRY", "default")
        self.seed = int(seed if seed is not None else os.environ.get("MRMT_LORR_SEED", "0"))
        self.inst: KitInstance | None = None  # with the choice and the state, set by _choose
        self.choice = None

    def _choose(self):
        """The entry's choice on the kit's instance (an :class:`~agents.lorr.entry.Choice`: the two specs)."""
        from agents.lorr.entry import load_entry

        self.state = view_of(self.env)
        self.inst = self.state.inst
        self.choice = load_entry(self.entry).choose(self.inst)
        return self.choice


class KitScheduler(_Role):
    """The start kit's ``pyTaskScheduler`` (module docstring)."""

    def initialize(self, preprocess_time_limit: int) -> bool:
        self.scheduler = self._choose().scheduler.build(self.seed)
        self.started = False
        return True

    def plan(self, time_limit: int) -> list[int]:
        deadline = deadline_of(self.env, time_limit)
        state = self.state.refresh(again=True)
        if not self.started:  # the robots and tasks come with the first step
            self.scheduler.reset(state)
            self.started = True
        proposal = self.scheduler.schedule(state, deadline=deadline)
        return [int(k) for k in np.asarray(proposal).tolist()]


class KitPlanner(_Role):
    """The start kit's ``pyMAPFPlanner`` (module docstring): each robot heads for its ``env.goal_locations``, the
    next errand of its task in the schedule the kit has set from the proposal (read from the shared view: the
    kit's goal list is a Python list a robot a step), or stays without one."""

    def initialize(self, preprocess_time_limit: int) -> bool:
        self.planner = self._choose().planner.build(self.state.inst.grid, self.seed)
        return True

    def plan(self, time_limit: int) -> list[int]:
        deadline = deadline_of(self.env, time_limit)
        state = self.state.refresh()
        schedule = list(self.env.curr_task_schedule)
        goals = state.tasks.goals(schedule, state.pos)
        from mrmt_env.lorr.tasks import rest_keywords

        extra = rest_keywords(self.planner, state.tasks, state.inst.width, np.asarray(schedule, dtype=np.int64))
        actions = self.planner.actions(state.pos, state.orient, goals, deadline=deadline, **extra)
        return [int(a) for a in np.asarray(actions).tolist()]


class KitPlanner2026(_Role):
    """The 2026 start kit's (v3.1) ``pyMAPFPlanner``: built without arguments (the kit sets ``env`` before
    ``initialize``), it plans from the kit's planning snapshot (``curr_states``: the states the kit's executor
    predicts after its staged actions) a window of actions per robot (``plan.actions[i]``) that the kit's executor
    stages and times.  The window is the kit's executor's, ``min_planner_communication_time // (action_time x
    max_counter) + 1`` actions (the ticks to the kit's next call and one more; 1 where the kit shows none of these
    fields; ``MRMT_LORR_WINDOW`` sets it): the one-step planner rolled out that many steps on the rules' moves, each
    robot's goal moving on to its task's next errand where it arrives, the call's time shared evenly among the
    steps.  The kit's executor drops the waits and keeps each cell's order of visits."""

    def window(self) -> int:
        """Actions a robot per call (class docstring); ``ValueError`` naming a bad ``MRMT_LORR_WINDOW``."""
        given = os.environ.get("MRMT_LORR_WINDOW")
        if given is not None:
            if not given.isdigit() or not 1 <= int(given) <= MAX_WINDOW:
                raise ValueError(f"MRMT_LORR_WINDOW = {given!r} must be an integer in 1..{MAX_WINDOW}")
            return int(given)
        env = self.env
        try:
            comm, tick, counter = (int(getattr(env, f)) for f in ("min_planner_communication_time", "action_time",
                                                                   "max_counter"))
        except AttributeError:
            return 1
        if comm <= 0 or tick <= 0:
            return 1
        return min(MAX_WINDOW, comm // (tick * max(counter, 1)) + 1)

    def initialize(self, preprocess_time_limit: int) -> bool:
        self.planner = self._choose().planner.build(self.state.inst.grid, self.seed)
        self.state.windows = self.window() > 1
        return True

    def plan(self, time_limit: int) -> list[list[int]]:
        from mrmt_env.lorr.rules import next_states
        from mrmt_env.lorr.tasks import legs

        deadline = deadline_of(self.env, time_limit)
        k = self.window()  # fixed for the run: the view reads every held task's progress since initialize when > 1
        state = self.state.refresh()
        schedule = list(self.env.curr_task_schedule)
        pos, orient = state.pos.copy(), state.orient.copy()
        goals = state.tasks.goals(schedule, pos)
        todo = [state.tasks.remaining(task).tolist() if task >= 0 else [] for task in schedule]  # errands left
        free = np.array([not q for q in todo], dtype=bool)  # no task: its goal is where it stands
        out = np.empty((len(pos), k), dtype=np.int64)
        t0 = time.perf_counter()
        rest = getattr(self.planner, "takes_rest", False)
        for j in range(k):
            extra = {"rest": np.array([legs(q, state.width) for q in todo], dtype=np.int64)} if rest else {}
            actions = np.asarray(self.planner.actions(pos, orient, goals, deadline=t0 + (deadline - t0) * (j + 1) / k,
                                                      **extra))
            out[:, j] = actions
            pos, orient = next_states(pos, orient, actions, state.width)
            for i in np.flatnonzero(pos == goals).tolist():  # arrived: on to the task's next errand, if any
                if todo[i] and todo[i][0] == pos[i]:
                    todo[i].pop(0)
                    free[i] = not todo[i]
                    goals[i] = todo[i][0] if todo[i] else pos[i]
            goals[free] = pos[free]
        return out.tolist()
