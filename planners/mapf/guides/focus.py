"""The robots at work: each step only the share of the team nearest its goal heads for it (issue 57, item 3).

Contract: ``active_goals(pos, goals, way, count)`` keeps the goals (flat cells) of the ``count`` robots with a goal
(goal != own cell) of least ``way`` (ties: the lower index) and gives every other robot its own cell: it has no goal
this step, stays, and is pushed aside when another needs its cell.  The 2024 winner's disabled agents (its
``DISABLE_AGENTS``: every robot holds a task, the planner drives those of least remaining way); the planners'
option ``active`` is the share, their way the goal field's distance (``planners.mapf.pibt.turning``), plus with
``active_by="task"`` each robot's task beyond its goal (``rest``; the winner's ranking by the task still to go).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planners.options import Options, option

__all__ = ["Focus", "FocusOptions", "active_goals", "active_count", "checked_rest"]


@dataclass(frozen=True)
class FocusOptions(Options):
    """Who is at work each step (module docstring)."""

    active: float = option(1.0, float, 0.001, 1, meaning="the share of the team that heads for its goal each step, "
                           "the robots of least way to it (planners.mapf.guides.focus; the others stay and are pushed "
                           "aside; 1 = all)")
    active_by: str = option("goal", str, words=("goal", "task"), meaning="with active < 1, the robots at work are "
                            "those of least way to their goal (goal) or of least task still to go: that way plus the "
                            "task's legs beyond its goal, given per step as actions(..., rest=...) (task; the 2024 "
                            "winner's ranking)")


class Focus:
    """The robots at work of one planner under ``opts`` (:class:`FocusOptions`): :meth:`steer` gives the others
    their own cell as goal.  :attr:`by_task`: the way counts each robot's task beyond its goal (``rest``)."""

    def __init__(self, opts: FocusOptions) -> None:
        self.active = opts.active
        self.by_task = opts.active_by == "task"

    def steer(self, pos, goals, rest, source, priorities) -> np.ndarray:
        """The flat goals a step heads for: under ``active`` < 1 only the robots at work keep theirs, those of least
        way by ``source``'s goal fields (:class:`~planners.mapf.guides.fields.FieldSource`; fields for the goals of
        the robots first in ``priorities``' order), plus ``rest`` when :attr:`by_task`."""
        if self.active >= 1:
            return goals
        cid = source.site.cid
        pc, gc = cid[pos], cid[goals]
        rows = source.fields.rows(gc, priorities.order(len(pos)))
        way = source.distance(pc, gc, rows) + (rest if self.by_task else 0)  # rest: checked by the planner
        return active_goals(pos, goals, way, active_count(self.active, len(pos)))


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


def checked_rest(rest, n_robots: int) -> np.ndarray:
    """``rest`` (each robot's task beyond its goal, moves) as an int64 array; ``ValueError`` naming what was given
    unless it is ``n_robots`` integers >= 0."""
    arr = None if rest is None else np.asarray(rest)
    if arr is None or arr.shape != (n_robots,) or arr.dtype.kind not in "iu" or (arr < 0).any():
        got = "none" if arr is None else f"shape {arr.shape} dtype {arr.dtype}" + (
            ", a negative length" if arr.dtype.kind in "iu" and arr.size and (arr < 0).any() else "")
        raise ValueError(f"active_by='task' needs rest: one task length >= 0 per robot, shape ({n_robots},) integers "
                         f"(mrmt_env.lorr.tasks.rest_under); got {got}")
    return arr.astype(np.int64, copy=False)
