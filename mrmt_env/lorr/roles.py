"""The start kit's two roles as Protocols: the scheduler (``TaskScheduler::plan``) and the one-step planner
(``MAPFPlanner::plan``), each called once a step with the step's deadline (the kit's ``time_limit``).

The step loop (:mod:`mrmt_env.lorr.loop`), ``agents.lorr.run.run_lorr``, ``mrmt lorr run --planner
package.module:Class`` and an entry file take any object that meets them: the package's own schedulers and planners
and a user's alike, under the same clock and score.  The required members are the methods below; the optional ones
a role may have are read where present:

* ``reset(sim)`` (scheduler): called once before the first step;
* ``last_compute`` (both): the last call's ``planners.compute.ComputeReport`` (a role without one is charged its
  measured host seconds only);
* ``accelerated`` (scheduler): an Ising machine decides (energy counted the paper's way);
* ``takes_rest`` (planner): ``actions`` is also given ``rest=`` (each robot's task beyond its goal,
  :func:`mrmt_env.lorr.tasks.rest_under`);
* ``guidance`` (planner): reported in the run's record.

``examples/lorr_own_planner.py`` shows a planner of a user's own.
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
