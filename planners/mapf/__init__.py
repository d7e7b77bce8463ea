"""Collision-free execution for lifelong operation: one conflict-free joint move per step.

:class:`PIBT` (priority inheritance with backtracking, compiled) and
:class:`WindowedPlanner` (prioritized space-time A* over a short window,
compiled); both take flat robot cells and goal cells and return next cells or
env actions.  :func:`make_executor` builds one by name (:data:`EXECUTORS`).
"""

from __future__ import annotations

from planners.mapf.pibt import PIBT
from planners.mapf.windowed import WindowedPlanner

__all__ = ["PIBT", "WindowedPlanner", "EXECUTORS", "make_executor"]

EXECUTORS = {"pibt": PIBT, "windowed": WindowedPlanner}


def make_executor(name: str, grid, seed: int = 0, **options):
    """The executor ``name`` (``pibt`` or ``windowed``) on ``grid``; ``ValueError`` naming the known ones."""
    try:
        cls = EXECUTORS[name]
    except KeyError:
        raise ValueError(f"unknown executor {name!r}; known: {', '.join(EXECUTORS)}") from None
    return cls(grid, seed=seed, **options)
