"""A League planner of your own, run and scored as the package's are.

A planner is any class with ``actions(pos, orient, goals, deadline=None)`` returning one action per robot (0 forward,
1 turn clockwise, 2 turn counter-clockwise, 3 wait) that is a valid joint action; the runner builds it as
``Class(grid, seed=seed, **options)``.  This one is deliberately simple: in robot order, a robot facing a free cell
that brings it closer to its goal moves there, unless another robot stands there now or has claimed it; otherwise it
turns towards the neighbour closest to its goal.  Moving only into cells empty now, it never collides.

    python examples/lorr_own_planner.py
    PYTHONPATH=examples mrmt lorr run INSTANCE.json --planner lorr_own_planner:ForwardPlanner --steps 100
"""

from __future__ import annotations

import numpy as np

STEP = ((0, 1), (1, 0), (0, -1), (-1, 0))  # east, south, west, north: (row, column) of a move facing each way


class ForwardPlanner:
    """Greedy forward moves by Manhattan distance (module docstring)."""

    name = "forward"

    def __init__(self, grid, seed: int = 0) -> None:
        self.grid = np.asarray(grid, dtype=bool)  # True: blocked
        self.height, self.width = self.grid.shape

    def _ahead(self, cell: int, o: int) -> int:
        r, c = divmod(cell, self.width)
        r, c = r + STEP[o][0], c + STEP[o][1]
        if 0 <= r < self.height and 0 <= c < self.width and not self.grid[r, c]:
            return r * self.width + c
        return -1

    def _way(self, cell: int, goal: int) -> int:
        (r, c), (gr, gc) = divmod(cell, self.width), divmod(goal, self.width)
        return abs(r - gr) + abs(c - gc)

    def actions(self, pos, orient, goals, deadline=None) -> np.ndarray:
        taken = set(int(p) for p in pos)  # cells stood on now, then cells claimed
        act = np.full(len(pos), 3, dtype=np.int64)
        for k, (p, o, g) in enumerate(zip(pos.tolist(), orient.tolist(), goals.tolist())):
            if p == g:
                continue
            ahead = self._ahead(p, o)
            if ahead >= 0 and ahead not in taken and self._way(ahead, g) < self._way(p, g):
                act[k] = 0
                taken.add(ahead)
                continue
            best = min(range(4), key=lambda d: (self._way(n, g) if (n := self._ahead(p, d)) >= 0 else 1 << 30,
                                                (d - o) % 4 != 1))
            if best != o:
                act[k] = 1 if (best - o) % 4 in (1, 2) else 2
        return act


if __name__ == "__main__":
    from agents.lorr.run import run_lorr
    from mrmt_env.lorr.instance import example_instance_path, read_instance

    inst = read_instance(example_instance_path())
    mine, _, _ = run_lorr(inst, "lorr-greedy", ForwardPlanner(inst.grid), steps=100)
    theirs, _, _ = run_lorr(inst, "lorr-greedy", "pibt", steps=100)
    print(f"{inst.name}, 100 steps: forward {mine['tasks_finished']} tasks ({mine['errors']} errors), "
          f"pibt {theirs['tasks_finished']} tasks")
