"""The start kit's two roles as Protocols: the scheduler (``TaskScheduler::plan``) and the one-step planner
(``MAPFPlanner::plan``), each called once a step with the step's deadline (the kit's ``time_limit``).

Every LoRR scheduler of :func:`agents.lorr.schedulers.make_scheduler` and every planner of
:func:`planners.mapf.make_turning_executor` satisfies them (``tests/test_lorr_weighted.py`` checks each); a
user's own class needs only these members to run in :func:`agents.lorr.run.run_lorr`'s step loop.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

__all__ = ["Scheduler", "Planner"]


@runtime_checkable
class Scheduler(Protocol):
    """Which robot takes which task: ``schedule`` returns the proposal (a task id or -1 per robot)."""

    name: str
    accelerated: bool    # an Ising machine decides (energy counted the paper's way)
    last_compute: object  # the last call's :class:`~planners.compute.ComputeReport`

    def reset(self, sim) -> None: ...

    def schedule(self, sim, deadline: float | None = None) -> np.ndarray: ...


@runtime_checkable
class Planner(Protocol):
    """One step of every robot: ``actions`` returns an action per robot (F, R, C, W) towards its goal cell.  A
    planner whose ``takes_rest`` is true is also given ``rest=`` (each robot's task beyond its goal,
    :func:`mrmt_env.lorr.tasks.rest_under`); without the attribute it is not."""

    guidance: int
    last_compute: object

    def actions(self, pos, orient, goals, deadline: float | None = None) -> np.ndarray: ...
