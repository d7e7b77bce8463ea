"""The start kit's two roles as Protocols: the scheduler (``TaskScheduler::plan``) and the one-step planner
(``MAPFPlanner::plan``), each called once a step with the step's deadline (the kit's ``time_limit``).

The step loop, ``agents.lorr.run.run_lorr``, ``mrmt lorr run --planner package.module:Class`` and entry files take
any object that meets them, the package's and a user's alike (``examples/lorr_own_planner.py``).
Design notes (the optional members): docs/design/lorr_simulator.md#the-two-roles.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

__all__ = ["Scheduler", "Planner"]


@runtime_checkable
class Scheduler(Protocol):
    """Which robot takes which task: ``schedule`` returns the proposal (a task id or -1 per robot)."""

    def schedule(self, sim, deadline: float | None = None) -> np.ndarray: ...


@runtime_checkable
class Planner(Protocol):
    """One step of every robot: ``actions`` returns an action per robot (0 F, 1 R, 2 C, 3 W) towards its goal cell,
    a valid joint action."""

    def actions(self, pos, orient, goals, deadline: float | None = None) -> np.ndarray: ...
