"""The robots at work: each step only the share of the team nearest its goal heads for it (issue 57, item 3).

Contract: ``active_goals(pos, goals, way, count)`` keeps the goals (flat cells) of the ``count`` robots with a goal
(goal != own cell) of least ``way`` (ties: the lower index) and gives every other robot its own cell: it has no goal
this step, stays, and is pushed aside when another needs its cell.  The 2024 winner's disabled agents (its
``DISABLE_AGENTS``: every robot holds a task, the planner drives those of least remaining way); the planners'
option ``active`` is the share, their way the goal field's distance (``planners.mapf.pibt.turning``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["active_goals", "active_count"]


def active_count(active: float, n_robots: int) -> int:
    """Robots at work in a team of ``n_robots`` under the share ``active`` (at least one)."""
    return max(int(active * n_robots), 1)


def active_goals(pos: np.ndarray, goals: np.ndarray, way: np.ndarray, count: int) -> np.ndarray:
    """``goals`` with every robot with a goal beyond the ``count`` of least ``way`` given its own cell ``pos``."""
    busy = np.flatnonzero(goals != pos)
    if len(busy) <= count:
        return goals
    keep = busy[np.lexsort((busy, way[busy]))[:count]]
    out = pos.copy()
    out[keep] = goals[keep]
    return out
