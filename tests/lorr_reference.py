"""Test-side oracles for the League of Robot Runners tests: a plain BFS over a bool grid."""

from __future__ import annotations

from collections import deque

import numpy as np


def bfs(grid: np.ndarray, src: int) -> np.ndarray:
    """Moves from flat cell ``src`` to every flat cell of ``grid`` (True = blocked), -1 unreachable."""
    h, w = grid.shape
    d = np.full(grid.size, -1)
    d[src] = 0
    q = deque([src])
    while q:
        p = q.popleft()
        r, c = divmod(p, w)
        for nr, nc in ((r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1)):
            if 0 <= nr < h and 0 <= nc < w and not grid[nr, nc] and d[nr * w + nc] < 0:
                d[nr * w + nc] = d[p] + 1
                q.append(nr * w + nc)
    return d


_STEP = ((0, 1), (1, 0), (0, -1), (-1, 0))  # east, south, west, north


def replay_cells(data: dict, width: int) -> list[list[int]]:
    """``cells[t][a]``: robot ``a``'s flat cell after ``t`` steps of an output file's ``actualPaths``
    (F, R, C, W, T), walked by hand from ``start``."""
    rows = [[r, c] for r, c, _ in data["start"]]
    orient = ["ESWN".index(o) for _, _, o in data["start"]]
    paths = [p.split(",") if p else [] for p in data["actualPaths"]]
    cells = [[r * width + c for r, c in rows]]
    for t in range(len(paths[0]) if paths else 0):
        for a, path in enumerate(paths):
            letter = path[t]
            if letter == "F":
                rows[a][0] += _STEP[orient[a]][0]
                rows[a][1] += _STEP[orient[a]][1]
            elif letter == "R":
                orient[a] = (orient[a] + 1) % 4
            elif letter == "C":
                orient[a] = (orient[a] + 3) % 4
            else:
                assert letter in ("W", "T"), letter
        cells.append([r * width + c for r, c in rows])
    return cells


def check_events(data: dict, width: int) -> int:
    """Every event ``[t, robot, task, n]`` of a 2024 output file against the robot's cell: at step ``t`` it
    stands on the task's ``n``-th errand, ``n`` rises 1, 2, ... per task, and ``t`` is the first step it
    stood there since it was given the task (``n`` = 1, from ``actualSchedule``) or since errand ``n - 1``.
    Returns the tasks whose last errand has an event (the tasks finished)."""
    cells = replay_cells(data, width)
    errands = {k: [cs[i] * width + cs[i + 1] for i in range(0, len(cs), 2)] for k, _, cs in data["tasks"]}
    given: dict[tuple[int, int], list[int]] = {}
    for a, text in enumerate(data["actualSchedule"]):
        for item in filter(None, text.split(",")):
            t, k = (int(x) for x in item.split(":"))
            given.setdefault((a, k), []).append(t)
    last: dict[int, tuple[int, int]] = {}
    finished = 0
    for t, a, k, n in data["events"]:
        prev_t, prev_n = last.get(k, (-1, 0))
        assert n == prev_n + 1, f"task {k}: errand {n} after {prev_n}"
        goal = errands[k][n - 1]
        assert cells[t][a] == goal, f"event {[t, a, k, n]}: robot {a} is at {cells[t][a]}, errand {n} is {goal}"
        since = max(s for s in given[(a, k)] if s <= t) if n == 1 else prev_t + 1
        early = [s for s in range(since, t) if cells[s][a] == goal]
        assert not early, f"event {[t, a, k, n]}: robot {a} stood on errand {n} at step {early[0]} already"
        last[k] = (t, n)
        finished += n == len(errands[k])
    return finished
