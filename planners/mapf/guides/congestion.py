"""Goal fields that see the crowd (LoRR, issue 56): the 2024 winner's dynamic heuristic, rebuilt here.

With ``congestion=P`` a move into a cell a robot stands on now costs ``P`` more in the goal fields; each call
recomputes up to ``refresh`` of the fields its robots use, so a work-bounded run stays deterministic.
Design notes: docs/design/lifelong_turning.md#goal-fields-that-see-the-crowd.
"""

from __future__ import annotations

import time

import numpy as np

__all__ = ["Congestion"]


class Congestion:
    """The crowd's move costs and the fields' refresh (module docstring).

    Args:
        nbr: ``(n, 4)`` compact successor table (-1: no move).
        base: ``(n, 4)`` int64 move costs without the crowd (1, or the lanes' and corridors').
        weight: ``P``, the extra cost of a move into an occupied cell (>= 1).
        refresh: fields recomputed per call at most.
    """

    def __init__(self, nbr: np.ndarray, base: np.ndarray, weight: int, refresh: int) -> None:
        self.nbr = nbr
        self.base = np.asarray(base, dtype=np.int64)
        self.weight = int(weight)
        self.refresh = int(refresh)
        self.refreshed = 0  # fields recomputed so far by refreshes

    def bound(self) -> np.ndarray:
        """The costliest each move may get (for the fields' dtype)."""
        return self.base + self.weight

    def costs(self, pc: np.ndarray) -> np.ndarray:
        """``(n, 4)`` move costs with robots at compact cells ``pc``."""
        occupied = np.zeros(self.nbr.shape[0] + 1, dtype=np.int64)  # the last entry: no move, no robot
        occupied[pc] = self.weight
        return self.base + occupied[self.nbr]

    def update(self, fields, rows: np.ndarray, stop: float | None = None) -> int:
        """Recompute up to :attr:`refresh` of the fields in ``rows`` (the robots' goal rows; -1 none) not computed in
        this call, under ``fields.cost``: most robots x calls since computed first, then the oldest; returns how many."""
        has = rows >= 0
        used, count = np.unique(rows[has], return_counts=True)
        stale = fields.filled[used] < fields.calls
        used, count = used[stale], count[stale]
        if self.refresh == 0 or len(used) == 0:
            return 0
        age = fields.calls - fields.filled[used]
        pick = np.lexsort((fields.filled[used], -count * age))[:self.refresh]
        chosen = used[pick]
        done, longest = 0, 0.0
        while done < len(chosen):
            t0 = time.perf_counter()
            if stop is not None and t0 + longest >= stop:
                break
            part = chosen[done:done + 8]
            fields.refill(part)
            done += len(part)
            longest = max(longest, time.perf_counter() - t0)
        self.refreshed += done
        return done
