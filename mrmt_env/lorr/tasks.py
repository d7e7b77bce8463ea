"""LoRR task rules: the 2024 task pool with schedules (start kit ``src/TaskManager.cpp``) and the
2023 system assignment ``roundrobin`` (2023 start kit ``InfAssignSystem``).

Both keep, per robot, its current task and that task's next errand (:attr:`goal`, -1 without one), mark errands
reached in order after every move, finish tasks and reveal new ones.
Design notes (reveals, schedule checks): docs/design/lorr_simulator.md#task-rules.
"""

from __future__ import annotations

import numpy as np

__all__ = ["TaskPool", "RoundRobin", "make_tasks", "goals_under", "rest_under", "rest_keywords", "legs"]


def _note(table: list, last: np.ndarray, values: np.ndarray, t: int) -> None:
    """Append ``(t, value)`` to each robot's list where ``value`` differs from its last entry."""
    for a in np.flatnonzero(values != last).tolist():
        table[a].append((t, int(values[a])))
        last[a] = values[a]


class TaskPool:
    """The 2024 rules (see the module docstring) for ``instance`` (a :class:`LoRRInstance`)."""

    def __init__(self, instance) -> None:
        self.inst = instance
        r = instance.team_size
        self.target = instance.open_target()
        self.assigned = np.full(r, -1, dtype=np.int64)   # current task per robot
        self.goal = np.full(r, -1, dtype=np.int64)       # its next errand (flat cell)
        self.line: list[int] = []       # task id -> file line
        self.next_idx: list[int] = []   # task id -> errands done
        self.revealed_at: list[int] = []
        self.holder: list[int] = []     # task id -> robot or -1
        self.open: dict[int, None] = {}  # open task ids in reveal order
        self.finished = 0
        self.errands_done = 0
        self.events: list[tuple[int, int, int, int]] = []
        self.schedule_errors: list[tuple[str, int, int, int, int]] = []
        self.planner_schedule: list[list[tuple[int, int]]] = [[] for _ in range(r)]
        self.actual_schedule: list[list[tuple[int, int]]] = [[] for _ in range(r)]
        self._last_planned = np.full(r, -2, dtype=np.int64)
        self._last_actual = np.full(r, -2, dtype=np.int64)
        self.new_tasks: list[int] = []
        self.new_free: list[int] = list(range(r))
        self.reveal(0)

    # -- queries
    def errands_of(self, task: int) -> np.ndarray:
        return self.inst.task_errands(self.line[task])

    def remaining(self, task: int) -> np.ndarray:
        """The errands of ``task`` still to visit, in order."""
        return self.errands_of(task)[self.next_idx[task]:]

    def is_opened(self, task: int) -> bool:
        return self.next_idx[task] > 0

    def open_tasks(self) -> np.ndarray:
        return np.fromiter(self.open, dtype=np.int64, count=len(self.open))

    # -- rules
    def reveal(self, t: int) -> None:
        self.new_tasks = []
        while len(self.open) < self.target:
            k = len(self.line)
            self.line.append(k % self.inst.n_tasks)
            self.next_idx.append(0)
            self.revealed_at.append(t)
            self.holder.append(-1)
            self.open[k] = None
            self.new_tasks.append(k)

    def check(self, proposal: np.ndarray, t: int):
        """The start kit's first schedule error of ``proposal`` or ``None``."""
        seen: dict[int, int] = {}
        for a, task in enumerate(proposal.tolist()):
            if task != -1 and task not in self.open:
                return ("task already finished", task, a, -1, t)
            if task != -1 and task in seen:
                return ("task is already assigned by the second agent at the same time", task, a, seen[task], t)
            cur = int(self.assigned[a])
            if cur != -1 and self.next_idx[cur] > 0 and task != cur:
                return ("task is already opened by the second agent", task, a, self.holder[cur], t)
            if task != -1:
                seen[task] = a
        return None

    def propose(self, proposal, t: int) -> bool:
        """Apply a proposed schedule at step ``t`` (after the move); False (and one schedule error)
        when the start kit would reject it."""
        proposal = np.asarray(proposal, dtype=np.int64).reshape(-1)
        if proposal.shape[0] != len(self.assigned):
            self.schedule_errors.append(("incorrect vector size", -1, -1, -1, t))
            return False
        _note(self.planner_schedule, self._last_planned, proposal, t)
        changed = np.flatnonzero(proposal != self.assigned)
        if len(changed):
            error = self.check(proposal, t)
            if error is not None:
                self.schedule_errors.append(error)
                return False
        for a in changed.tolist():
            old, new = int(self.assigned[a]), int(proposal[a])
            if old != -1 and self.holder[old] == a:
                self.holder[old] = -1
            if new != -1:
                self.holder[new] = a
            self.assigned[a] = new
            self.goal[a] = -1 if new == -1 else int(self.remaining(new)[0])
        _note(self.actual_schedule, self._last_actual, self.assigned, t)
        return True

    def arrive(self, pos: np.ndarray, t: int) -> int:
        """Mark errands reached at step ``t``; returns the tasks finished."""
        self.new_free = []
        hit = np.flatnonzero((self.goal >= 0) & (pos == self.goal))
        done = 0
        for a in hit.tolist():
            task = int(self.assigned[a])
            self.next_idx[task] += 1
            self.errands_done += 1
            rest = self.remaining(task)
            if len(rest) == 0:
                self.assigned[a] = -1
                self.goal[a] = -1
                del self.open[task]
                self.finished += 1
                done += 1
                self.new_free.append(a)
            else:
                self.goal[a] = int(rest[0])
            self.events.append((t, a, task, self.next_idx[task]))
        return done

    def update(self, pos: np.ndarray, proposal, t: int) -> int:
        """The start kit's ``update_tasks``: schedule, arrivals, reveal; returns tasks finished."""
        if proposal is not None:
            self.propose(proposal, t)
        done = self.arrive(pos, t)
        self.reveal(t)
        return done

    def task_records(self, width: int) -> list:
        """Output ``tasks``: ``[id, revealed at, [row, col, row, col, ...]]`` per revealed task."""
        out = []
        for k in range(len(self.line)):
            cells = self.inst.task_errands(self.line[k])
            out.append([k, self.revealed_at[k], [int(v) for c in cells.tolist() for v in divmod(c, width)]])
        return out


class RoundRobin:
    """The 2023 ``roundrobin`` system assignment (see the module docstring)."""

    def __init__(self, instance) -> None:
        self.inst = instance
        r = instance.team_size
        self.per_robot = int(instance.reveal)
        self.queues: list[list[tuple[int, int]]] = [[] for _ in range(r)]  # (task id, cell)
        self.counter = np.zeros(r, dtype=np.int64)
        self.goal = np.full(r, -1, dtype=np.int64)
        self.assigned = np.full(r, -1, dtype=np.int64)
        self.n_ids = 0
        self.cells: list[int] = []
        self.revealed_at: list[int] = []
        self.finished = 0
        self.errands_done = 0
        self.events: list[tuple[int, int, int, int]] = []
        self.schedule_errors: list = []
        self.reveal(0)

    def reveal(self, t: int) -> None:
        r = len(self.queues)
        for k in range(r):
            q = self.queues[k]
            while len(q) < self.per_robot:
                line = int(self.counter[k]) * r + k
                cell = int(self.inst.task_errands(line)[0])
                q.append((self.n_ids, cell))
                self.cells.append(cell)
                self.revealed_at.append(t)
                self.n_ids += 1
                self.counter[k] += 1
            self.assigned[k], self.goal[k] = q[0]

    def update(self, pos: np.ndarray, proposal, t: int) -> int:
        hit = np.flatnonzero(pos == self.goal)
        for a in hit.tolist():
            task, _ = self.queues[a].pop(0)
            self.events.append((t, a, task, 1))
        self.finished += len(hit)
        self.errands_done += len(hit)
        self.reveal(t)
        return len(hit)

    def task_records(self, width: int) -> list:
        return [[k, self.revealed_at[k], list(divmod(c, width))] for k, c in enumerate(self.cells)]


def rest_under(tasks, width: int, proposal=None) -> np.ndarray:
    """Each robot's task beyond its next errand under ``proposal`` (as :func:`goals_under`): the Manhattan legs
    from that errand through the task's later ones, in moves; 0 without a task or on its last errand (the 2024
    winner ranks its robots by the whole task still to go: the way to the next errand plus this).  ``width``: the
    map's columns (errands are flat cells)."""
    assigned = tasks.assigned if proposal is None else np.asarray(proposal)
    rest = np.zeros(len(assigned), dtype=np.int64)
    if not hasattr(tasks, "remaining"):  # one errand a task (the 2023 rules): nothing beyond the goal
        return rest
    for a, k in enumerate(assigned.tolist()):
        if k < 0 or k not in tasks.open:
            continue
        rest[a] = legs(tasks.remaining(k).tolist(), width)
    return rest


def rest_keywords(planner, tasks, width: int, proposal=None) -> dict:
    """The keyword a planner's ``actions`` takes beyond the goals: ``{"rest": rest_under(...)}`` for a planner whose
    ``takes_rest`` is set (``active_by="task"``), else nothing."""
    return {"rest": rest_under(tasks, width, proposal)} if getattr(planner, "takes_rest", False) else {}


def legs(errands: list, width: int) -> int:
    """The Manhattan legs from the first of ``errands`` (flat cells, in order) through the others, in moves."""
    return sum(abs(p // width - q // width) + abs(p % width - q % width) for p, q in zip(errands, errands[1:]))


def make_tasks(instance):
    """The task rules of ``instance``: :class:`RoundRobin` for 2023 ``roundrobin``, else :class:`TaskPool`."""
    return RoundRobin(instance) if instance.strategy == "roundrobin" else TaskPool(instance)


def goals_under(tasks, proposal=None) -> np.ndarray:
    """Each robot's next errand under ``proposal`` (a task id or -1 per robot; ``None``: the schedule as it is),
    -1 without one: the proposed task's next errand where the proposal changes a robot's task (-1 for an id
    not open), else its task's."""
    goal = tasks.goal.copy()
    if proposal is None:
        return goal
    proposal = np.asarray(proposal)
    for a in np.flatnonzero(proposal != tasks.assigned).tolist():
        k = int(proposal[a])
        goal[a] = int(tasks.remaining(k)[0]) if k in tasks.open else -1
    return goal
