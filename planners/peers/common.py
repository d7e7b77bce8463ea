"""What the peer routing layers share: budget checks and the routing problem's input checks."""

from __future__ import annotations

import math

import numpy as np

from planners.base import SharingResult

__all__ = ["MAX_SECONDS", "check_budget", "routing_input"]

#: Largest time budget accepted (one hour), so a typo is not a hung run.
MAX_SECONDS = 3600.0


def check_budget(solver: str, seconds, count_name: str, count) -> tuple[float | None, int | None]:
    """``(seconds, count)`` checked: seconds in ``(0, MAX_SECONDS]`` or None, ``count`` an integer
    ``>= 1`` or None, not both None; ``ValueError`` naming the bad value otherwise."""
    if seconds is not None:
        if isinstance(seconds, bool) or not isinstance(seconds, (int, float)) or not (
                math.isfinite(seconds) and 0 < seconds <= MAX_SECONDS):
            raise ValueError(f"{solver} seconds must be a number in (0, {MAX_SECONDS:g}] or None, got {seconds!r}")
        seconds = float(seconds)
    if count is not None:
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
            raise ValueError(f"{solver} {count_name} must be an integer >= 1 or None, got {count!r}")
        count = int(count)
    if seconds is None and count is None:
        raise ValueError(f"{solver} needs a budget: seconds, {count_name} or both (got neither)")
    return seconds, count


def routing_input(dist, n_robots) -> tuple[np.ndarray, int, SharingResult | None]:
    """``(d, r, done)``: the float matrix, the robot count, and the result when no search is needed
    (no targets, or a target no robot reaches: a failure); ``ValueError`` for a malformed input."""
    d = np.asarray(dist, dtype=np.float64)
    if d.ndim != 2 or d.shape[0] != d.shape[1]:
        raise ValueError(f"sharing dist must be a square (R+N, R+N) matrix, got shape {d.shape}")
    r = int(n_robots)
    if r != n_robots or not 1 <= r <= d.shape[0]:
        raise ValueError(f"n_robots must be an integer in 1..{d.shape[0]} (matrix size), got {n_robots!r}")
    empty = tuple(() for _ in range(r))
    if d.shape[0] == r:
        return d, r, SharingResult(assignment=empty)
    lost = np.flatnonzero(~np.isfinite(d[:r, r:]).any(axis=0))
    if len(lost):
        return d, r, SharingResult(assignment=empty, failure=f"targets {lost.tolist()} are reachable from no robot")
    return d, r, None
