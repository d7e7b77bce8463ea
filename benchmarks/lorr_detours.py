"""The routes of League runs against the shortest ways, leg by leg: forward moves, turns and waits (issue 80, item 4).

A leg is a robot's way from one errand reached (or the start) to the next one it reaches; its lower bound is the
least number of actions from the robot's cell and orientation at the leg's start to the errand's cell, turns
counted (a BFS over (cell, orientation), scipy's csgraph).  For each output file (the package's, ``mrmt lorr run
--out``, or an archive's record run, 2023 or 2024 format, ``.zip`` read too) the actions are replayed from the
start states and every leg is set against its bound: the forward moves against the cells' distance, the turns
against the turns the bound needs, and the waits.  Under the 2023 rules (tasks given round robin) the legs are the
planner's alone; under the 2024 rules a leg also holds the scheduler's choice.

    python benchmarks/lorr_detours.py ../shared/lorr/2023-main/random.domain/MR23-I-04.json \\
        record=../shared/lorr/2023-main/best_solutions/MR23-I-04.json.zip entry=runs/mr23/output.json
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

DIRS = ((0, 1), (1, 0), (0, -1), (-1, 0))  # east, south, west, north: the rules' orientations


def state_graph(grid: np.ndarray):
    """The reversed action graph over (cell, orientation) states ``4 * cell + o``: an edge from each state to
    every state one action before it (forward, clockwise, counter-clockwise), weight 1."""
    from scipy.sparse import csr_matrix

    h, w = grid.shape
    src, dst = [], []
    for r in range(h):
        for c in range(w):
            if grid[r, c]:
                continue
            p = r * w + c
            for o, (dr, dc) in enumerate(DIRS):
                s = 4 * p + o
                for t in ((o + 1) % 4, (o + 3) % 4):  # a turn from (p, o) reaches (p, t)
                    src.append(4 * p + t)
                    dst.append(s)
                rr, cc = r + dr, c + dc
                if 0 <= rr < h and 0 <= cc < w and not grid[rr, cc]:
                    src.append(4 * (rr * w + cc) + o)  # forward from (p, o) reaches (q, o)
                    dst.append(s)
    n = 4 * h * w
    return csr_matrix((np.ones(len(src)), (src, dst)), shape=(n, n))


class Bounds:
    """Least actions to a goal cell from every (cell, orientation), and the cells' distance (per goal, not kept:
    a large map's fields for every goal would not fit in memory)."""

    def __init__(self, grid: np.ndarray, turns: bool = True) -> None:
        self.grid, self.width = grid, grid.shape[1]
        self.graph = state_graph(grid) if turns else None  # without: the bound is the cells' distance

    def __call__(self, goal: int) -> tuple[np.ndarray, np.ndarray]:
        from scipy.sparse.csgraph import dijkstra

        from mrmt_env.distances import bfs_distance_field

        cells = bfs_distance_field(self.grid, divmod(goal, self.width)).reshape(-1)
        if self.graph is None:
            return cells[:, None], cells
        d = dijkstra(self.graph, indices=[4 * goal + o for o in range(4)], min_only=True, unweighted=True)
        return d.reshape(-1, 4), cells


def legs(data: dict, width: int) -> list[tuple[int, int, int, int, bool]]:
    """``(robot, start step, end step, goal cell, first)`` of every errand reached in output ``data`` (both formats;
    ``first``: the task's first errand, the leg the scheduler's choice sets)."""
    tasks = data["tasks"]
    cells: dict[int, list[int]] = {}
    for t in tasks:
        if isinstance(t[2], list):  # 2024: [id, revealed, [row, col, row, col, ...]]
            cells[t[0]] = [t[2][i] * width + t[2][i + 1] for i in range(0, len(t[2]), 2)]
        else:  # 2023: [id, row, col]
            cells[t[0]] = [t[1] * width + t[2]]
    reached = []  # (t, robot, goal)
    events = data["events"]
    if events and isinstance(events[0], list) and events[0] and isinstance(events[0][0], list):
        for r, evs in enumerate(events):  # 2023 record: per robot [task, t, "assigned" | "finished"]
            reached += [(t, r, cells[task][0], True) for task, t, kind in evs if kind == "finished"]
    else:  # the package's: (t, robot, task, errands of the task reached so far)
        reached = [(t, r, cells[task][idx - 1], idx == 1) for t, r, task, idx in events]
    last: dict[int, int] = defaultdict(int)
    out = []
    for t, r, goal, first in sorted(reached):
        out.append((r, last[r], t, goal, first))
        last[r] = t
    return out


def measure(instance, data: dict, bounds: Bounds, windows: int = 1) -> list[dict]:
    """Per window of steps (a leg in the window it ends in): legs, steps, lower bound, forward moves, the cells'
    distance, turns, waits of one output."""
    from mrmt_env.lorr.rules import TIMEOUT, WAIT, next_states, parse_actions

    w = instance.width
    rows = np.array([parse_actions(p, f"robot {k}") for k, p in enumerate(data["actualPaths"])])
    pos = np.array([s[0] * w + s[1] for s in data["start"]], dtype=np.int64)
    ori = np.array(["ESWN".index(s[2]) for s in data["start"]], dtype=np.int64)
    states = [(pos, ori)]
    for t in range(rows.shape[1]):
        a = rows[:, t].astype(np.int64)
        pos, ori = next_states(pos, ori, np.where(a == TIMEOUT, WAIT, a), w)
        states.append((pos, ori))
    cuts = np.linspace(0, rows.shape[1], windows + 1)
    ms: list[dict] = [defaultdict(int) for _ in range(windows)]
    by_goal = defaultdict(list)
    for leg in legs(data, w):
        by_goal[leg[3]].append(leg)
    for goal, goal_legs in by_goal.items():
        oriented, cells = bounds(goal)
        for r, t0, t1, _, first in goal_legs:
            k = min(int(np.searchsorted(cuts, t1, side="left")) - 1, windows - 1)
            o = states[t0][1][r] if oriented.shape[1] == 4 else 0  # the cells' distance: one column
            leg_into(ms[k], (int(cuts[k]) + 1, int(cuts[k + 1])), rows[r, t0:t1], (oriented, cells),
                     (states[t0][0][r], o), t1 - t0, first)
    return [dict(m) for m in ms if m]


def leg_into(m: dict, window: tuple, acts: np.ndarray, bound: tuple, start: tuple, steps: int, first: bool) -> None:
    """One leg's counts added to window ``m`` (``first``: a leg to a task's first errand, counted apart too)."""
    from mrmt_env.lorr.rules import CLOCKWISE, COUNTER, FORWARD, TIMEOUT, WAIT

    oriented, cells = bound
    p, o = start
    m["first"], m["last"] = window
    m["legs"] += 1
    m["steps"] += steps
    m["bound"] += int(oriented[p, o])
    m["distance"] += int(cells[p])
    m["forward"] += int((acts == FORWARD).sum())
    m["turns"] += int(((acts == CLOCKWISE) | (acts == COUNTER)).sum())
    m["waits"] += int(((acts == WAIT) | (acts == TIMEOUT)).sum())
    if first:
        m["first_legs"] += 1
        m["first_bound"] += int(oriented[p, o])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("instance", type=Path)
    ap.add_argument("outputs", nargs="+", help="LABEL=PATH of an output file")
    ap.add_argument("--windows", type=int, default=1, help="the steps cut into this many windows (a leg counts in "
                    "the window it ends in)")
    ap.add_argument("--no-turns", action="store_true", help="bound by the cells' distance alone (large maps: a BFS "
                    "per goal over cells, not over (cell, orientation))")
    args = ap.parse_args(argv)

    from mrmt_env.lorr.instance import read_instance
    from mrmt_env.lorr.output import read_output

    inst = read_instance(args.instance)
    bounds = Bounds(inst.grid, turns=not args.no_turns)
    print(f"{inst.name}: legs from errand to errand against the least actions (turns counted)\n")
    print("| run | steps | tasks | legs | steps in legs | lower bound | bound / leg | to a first errand / leg | "
          "steps / bound | forward / cells' distance | turns / turns needed | waits |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for spec in args.outputs:
        label, _, path = spec.rpartition("=")
        data = read_output(path)
        for m in measure(inst, data, bounds, args.windows):
            needed = m["bound"] - m["distance"]
            turns = f"{m['turns'] / needed:.3f}" if needed > 0 else "-"
            print(f"| {label or path} | {m['first']}-{m['last']} | {data.get('numTaskFinished', '')} | {m['legs']:,} | "
                  f"{m['steps']:,} | {m['bound']:,} | {m['bound'] / m['legs']:.1f} | "
                  f"{m.get('first_bound', 0) / max(m.get('first_legs', 0), 1):.1f} | {m['steps'] / m['bound']:.3f} | "
                  f"{m['forward'] / m['distance']:.3f} | {turns} | {m['waits']:,} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
