"""The start kit's step, once, for the env and the runner (``CompetitionSystem``'s loop).

Contract: ``StepLoop(sim, scheduler)``; per step :meth:`StepLoop.propose` (the scheduler's proposal for the
coming step on 2024 instances, with the step's deadline under a clock), then the joint move towards
:meth:`StepLoop.goals` (chosen by the env's agent or by the runner's planner), then :meth:`StepLoop.advance`:
a decision late by ``late`` steps costs that many timeouts first (every robot waits, no task changes), then
the simulator moves and applies the proposal.  2023 instances assign tasks by their rule and take no proposal.
"""

from __future__ import annotations

import numpy as np

from mrmt_env.lorr.roles import Scheduler
from mrmt_env.lorr.sim import LoRRSimulator
from mrmt_env.lorr.tasks import goals_under, rest_keywords

__all__ = ["StepLoop"]


class StepLoop:
    """One run's steps on ``sim`` with ``scheduler`` (a :class:`~mrmt_env.lorr.roles.Scheduler`, its optional
    ``reset(sim)`` called first; or ``None``: only proposals given to :meth:`hold`).  :attr:`pending` is the proposal
    the coming step applies (``None``: none)."""

    def __init__(self, sim: LoRRSimulator, scheduler: Scheduler | None = None) -> None:
        self.sim = sim
        self.scheduler = scheduler
        self.pending: np.ndarray | None = None
        if scheduler is not None and hasattr(scheduler, "reset"):
            scheduler.reset(sim)

    def propose(self, deadline: float | None = None) -> np.ndarray | None:
        """The scheduler's proposal for the coming step (``deadline``: the step's ``time.perf_counter()``
        deadline, passed on only under a clock), held as :attr:`pending`; ``None`` on a 2023 instance or
        without a scheduler."""
        sim, sched = self.sim, self.scheduler
        if sched is None or sim.inst.strategy is not None:
            self.pending = None
        else:
            proposal = sched.schedule(sim) if deadline is None else sched.schedule(sim, deadline=deadline)
            self.pending = np.asarray(proposal, dtype=np.int64)
        return self.pending

    def hold(self, schedule) -> None:
        """Hold ``schedule`` (one task id or -1 per robot) as the coming step's proposal; ``ValueError`` naming a
        wrong shape or type, or a 2023 instance (its rule assigns)."""
        sim = self.sim
        if sim.inst.strategy is not None:
            raise ValueError(f"{sim.inst.name} assigns tasks by its {sim.inst.strategy!r} rule; it takes no schedule")
        s = np.asarray(schedule)
        if s.shape != (sim.n_robots,) or s.dtype.kind not in "iu":
            raise ValueError(f"a schedule is one task id (or -1) per robot: expected ({sim.n_robots},) integers, "
                             f"got shape {s.shape} dtype {s.dtype}")
        self.pending = s.astype(np.int64)

    def goals(self) -> np.ndarray:
        """Each robot's goal under the pending proposal: its task's next errand, -1 without one."""
        return goals_under(self.sim.tasks, self.pending)

    def goal_cells(self) -> np.ndarray:
        """The cell each robot heads for: its goal (:meth:`goals`), else its own cell."""
        goals = self.goals()
        return np.where(goals >= 0, goals, self.sim.pos)

    def rest_for(self, planner) -> dict:
        """The keyword ``planner.actions`` takes beyond the goals: ``{"rest": ...}`` (each robot's task beyond its
        goal under the pending proposal, :func:`~mrmt_env.lorr.tasks.rest_under`) for a planner whose
        ``takes_rest`` is set, else nothing."""
        return rest_keywords(planner, self.sim.tasks, self.sim.width, self.pending)

    def advance(self, actions, late: int = 0, steps: int | None = None) -> int:
        """``late`` timeouts, then the move with the pending proposal applied, none of them past ``steps``
        (default: no bound); the tasks finished."""
        sim = self.sim
        end = np.inf if steps is None else steps
        before = sim.finished
        for _ in range(int(min(late, end - sim.t))):
            sim.time_out()
        if sim.t < end:
            sim.step(actions, self.pending)
        return sim.finished - before
