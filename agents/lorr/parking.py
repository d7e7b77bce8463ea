"""Parking at density: at most a share of the team holds tasks; the rest wait where they stand (issue 57).

Contract: ``Parked(inner, busy)`` is a scheduler (:class:`~agents.lorr.roles.Scheduler`) proposing what ``inner``
proposes, except that robots given a new task beyond ``busy x team`` busy robots get none this step (nearest
first by Manhattan way to the task's first errand, ties by robot); tasks held stay held.  A parked robot keeps
no task, so the one-step planner treats it as any robot without a goal: it stays and is pushed aside when
another needs its cell (not sent to a parking place: over a full run parked robots gather in the aisles;
measured in ``benchmarks/RESULTS.md``, "Parking at density").  ``make_scheduler(name, busy=...)`` wraps any
scheduler.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["Parked", "check_busy"]


def check_busy(busy) -> float:
    """``busy`` as a float in (0, 1]; ``ValueError`` naming the value and the range otherwise."""
    if isinstance(busy, bool) or not isinstance(busy, (int, float)) or not math.isfinite(busy) or not 0 < busy <= 1:
        raise ValueError(f"busy = {busy!r} must be the share of the team that may hold tasks, in (0, 1]")
    return float(busy)


class Parked:
    """``inner`` with at most ``busy`` of the team busy (module docstring)."""

    def __init__(self, inner, busy: float) -> None:
        self.inner = inner
        self.busy = check_busy(busy)
        self.name = inner.name
        self.accelerated = inner.accelerated

    @property
    def last_compute(self):
        return self.inner.last_compute

    def reset(self, sim) -> None:
        self.inner.reset(sim)

    def schedule(self, sim, deadline: float | None = None) -> np.ndarray:
        proposal = np.array(self.inner.schedule(sim, deadline=deadline), dtype=np.int64)
        tasks = sim.tasks
        held = (proposal >= 0) & (proposal == tasks.assigned)
        new = np.flatnonzero((proposal >= 0) & ~held)
        room = max(int(self.busy * len(proposal)) - int(held.sum()), 0)
        if len(new) > room:
            w = sim.width
            first = np.array([int(tasks.remaining(int(k))[0]) for k in proposal[new].tolist()], dtype=np.int64)
            here = sim.pos[new]
            way = np.abs(here // w - first // w) + np.abs(here % w - first % w)
            order = np.lexsort((new, way))
            proposal[new[order[room:]]] = -1
        return proposal
