"""The LoRR simulator: one instance's robots, tasks and record, stepped as the start kit steps it.

Contract: ``LoRRSimulator(instance)``; :meth:`LoRRSimulator.step` ``(actions, proposal=None) -> tasks finished``;
:meth:`LoRRSimulator.time_out` is a step the entry's decision was late for. The record is what
:mod:`mrmt_env.lorr.output` writes. Design notes: docs/design/lorr_simulator.md#the-simulator.
"""

from __future__ import annotations

import numpy as np

from mrmt_env.lorr.instance import LoRRInstance
from mrmt_env.lorr.rules import TIMEOUT, WAIT, first_error, n_actions, next_cells_four, next_states
from mrmt_env.lorr.tasks import make_tasks

__all__ = ["LoRRSimulator"]


class LoRRSimulator:
    """One run of ``instance`` (see the module docstring).  State: :attr:`pos`, :attr:`orient`
    (``(R,)`` int64), :attr:`t`, :attr:`tasks` (the task rules, with ``goal``, ``assigned``,
    ``finished``, ``events``)."""

    def __init__(self, instance: LoRRInstance, record: bool = True, action_model: str = "MAPF_T") -> None:
        self.n_actions = n_actions(action_model)
        self.action_model = action_model
        self.inst = instance
        self.width = instance.width
        self.blocked = np.ascontiguousarray(instance.grid.reshape(-1))
        self.pos = instance.starts.copy()
        self.orient = np.zeros(instance.team_size, dtype=np.int64)
        self.start_pos = self.pos.copy()
        self.start_orient = self.orient.copy()
        self.t = 0
        self.tasks = make_tasks(instance)
        self.errors: list[tuple[str, int, int, int]] = []
        self.timeouts = 0
        self.record = bool(record)
        self.planned: list[np.ndarray] = []
        self.actual: list[np.ndarray] = []
        self.busy = np.zeros(instance.team_size, dtype=np.int64)

    @property
    def n_robots(self) -> int:
        return len(self.pos)

    @property
    def finished(self) -> int:
        return self.tasks.finished

    @property
    def makespan(self) -> int:
        return int(self.busy.max()) if len(self.busy) else 0

    def check_actions(self, actions) -> np.ndarray:
        """``actions`` as ``(R,)`` int64 codes; ``ValueError`` naming a wrong length or code."""
        a = np.asarray(actions)
        if a.shape != (self.n_robots,):
            raise ValueError(f"a joint action holds one action per robot: expected shape ({self.n_robots},), "
                             f"got {a.shape}")
        if a.dtype.kind not in "iu":
            if a.dtype.kind == "f" and np.all(np.isfinite(a)) and np.all(a == np.round(a)):
                a = a.astype(np.int64)
            else:
                raise ValueError(f"actions must be integers 0..{self.n_actions - 1}, got dtype {a.dtype}")
        n = self.n_actions
        bad = np.flatnonzero((a < 0) | (a >= n))
        if len(bad):
            k = int(bad[0])
            names = "F, R, C, W" if self.action_model == "MAPF_T" else "stay, up, down, left, right"
            raise ValueError(f"robot {k}: action {a[k]} is not one of 0..{n - 1} ({names})")
        return a.astype(np.int64)

    def time_out(self) -> None:
        """One step without a decision (see the module docstring)."""
        self.busy += self.tasks.goal >= 0
        if self.record:
            na = np.full(self.n_robots, TIMEOUT, dtype=np.int8)
            self.planned.append(na)
            self.actual.append(na)
        self.timeouts += 1
        self.t += 1

    def step(self, actions, proposal=None) -> int:
        """Move the robots (all wait on an invalid joint action), then update tasks with ``proposal``
        (``(R,)`` task ids or -1; ``None`` keeps the schedule).  Returns the tasks finished."""
        a = self.check_actions(actions)
        self.busy += self.tasks.goal >= 0
        if self.action_model == "MAPF_T":
            nxt, nori = next_states(self.pos, self.orient, a, self.width)
        else:
            nxt, nori = next_cells_four(self.pos, a, self.width), self.orient
        error = first_error(self.pos, nxt, self.blocked)
        if self.record:
            self.planned.append(a.astype(np.int8))
        if error is not None:
            self.errors.append((error[0], error[1], error[2], self.t + 1))
            a = np.full(self.n_robots, WAIT if self.action_model == "MAPF_T" else 0, dtype=np.int64)
        else:
            self.pos, self.orient = nxt, nori
        if self.record:
            self.actual.append(a.astype(np.int8))
        self.t += 1
        return self.tasks.update(self.pos, proposal, self.t)
