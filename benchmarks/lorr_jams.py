"""Jams over a League run: which robots holding a task stand still, and the packed blocks they stand in.

Reads a run's ``output.json`` (``mrmt lorr run ... --out DIR``) beside its instance and replays the robots' cells
from ``actualPaths`` (the rules' moves; a late step ``T`` moves nobody) and the tasks they hold from
``actualSchedule`` and ``events`` (a robot holds the task of its last schedule entry until that task's last errand
is done).  Every ``--every`` steps: the robots holding a task, those *stuck* among them (fewer than ``--moves``
forward moves in the last ``--window`` steps), the share of the stuck facing an occupied cell, the occupied
neighbours of the stuck and of the others holding a task (mean of 4), the share of the stuck whose robot ahead
holds no task, and the packed blocks (4-connected occupied cells) of at least ``--block`` robots: how many, the
robots in them, the largest.  Reading only, no run.

    python benchmarks/lorr_jams.py INSTANCE.json DIR/output.json --every 500
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from mrmt_env.lorr.instance import read_instance
from mrmt_env.lorr.rules import FORWARD, ORIENT_LETTERS, TIMEOUT, WAIT, next_states, parse_actions

_STEP = (1, 0), (0, 1), (-1, 0), (0, -1)  # (column, row) per orientation: east, south, west, north


def replay(instance, output: dict, times) -> dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """``time -> (flat cells, orientations, forward moves so far)`` after ``time`` steps, for each of ``times``."""
    w = instance.width
    pos = np.array([r * w + c for r, c, _ in output["start"]], dtype=np.int64)
    orient = np.array([ORIENT_LETTERS.index(o) for _, _, o in output["start"]], dtype=np.int64)
    acts = np.stack([parse_actions(p, f"robot {k}") for k, p in enumerate(output["actualPaths"])], axis=1)
    moved = np.zeros(len(pos), dtype=np.int64)
    out, wanted = {}, set(times)
    if 0 in wanted:
        out[0] = (pos.copy(), orient.copy(), moved.copy())
    for t, a in enumerate(acts, start=1):
        a = np.where(a == TIMEOUT, WAIT, a)
        pos, orient = next_states(pos, orient, a, w)
        moved += a == FORWARD
        if t in wanted:
            out[t] = (pos.copy(), orient.copy(), moved.copy())
    return out


def holding(output: dict, time: int) -> np.ndarray:
    """Per robot: whether it holds a task after ``time`` steps (module docstring)."""
    errands = {tid: len(locs) // 2 for tid, _revealed, locs in output["tasks"]}
    done = {task: t for t, _robot, task, n in output["events"] if n == errands[task]}
    out = np.zeros(len(output["actualSchedule"]), dtype=bool)
    for robot, text in enumerate(output["actualSchedule"]):
        last = -1
        for item in filter(None, text.split(",")):
            t, task = (int(x) for x in item.split(":"))
            if t <= time:
                last = task
        out[robot] = last >= 0 and done.get(last, time + 1) > time
    return out


def blocks(cells: np.ndarray, width: int) -> list[int]:
    """Sizes of the 4-connected groups of occupied flat ``cells``, largest first."""
    left = set(int(c) for c in cells)
    sizes = []
    while left:
        stack, size = [left.pop()], 0
        while stack:
            c = stack.pop()
            size += 1
            for n in (c + 1 if (c + 1) % width else -1, c - 1 if c % width else -1, c + width, c - width):
                if n in left:
                    left.remove(n)
                    stack.append(n)
        sizes.append(size)
    return sorted(sizes, reverse=True)


def rows(instance, output: dict, every: int, window: int, moves: int, block: int) -> list[dict]:
    """One row every ``every`` steps from ``window`` on (module docstring)."""
    steps = len(output["actualPaths"][0].split(",")) if output["actualPaths"] and output["actualPaths"][0] else 0
    times = [t for t in range(every, steps + 1, every) if t >= window]
    states = replay(instance, output, set(times) | {t - window for t in times})
    h, w = instance.grid.shape
    out = []
    for t in times:
        pos, orient, moved = states[t]
        held = holding(output, t)
        stuck = held & (moved - states[t - window][2] < moves)
        who = np.full(h * w, -1, dtype=np.int64)
        who[pos] = np.arange(len(pos))
        row, col = pos // w, pos % w
        around = np.zeros(len(pos), dtype=np.int64)
        ahead = np.full(len(pos), -1, dtype=np.int64)
        for o, (dc, dr) in enumerate(_STEP):
            r2, c2 = row + dr, col + dc
            inside = (r2 >= 0) & (r2 < h) & (c2 >= 0) & (c2 < w)
            there = np.where(inside, who[np.where(inside, r2 * w + c2, 0)], -1)
            around += there >= 0
            ahead = np.where(orient == o, there, ahead)
        sizes = [s for s in blocks(pos, w) if s >= block]
        front = ahead[stuck]
        out.append({"step": t, "holding": int(held.sum()), "stuck": int(stuck.sum()),
                    "facing_occupied": float((front >= 0).mean()) if stuck.any() else 0.0,
                    "neighbours_stuck": float(around[stuck].mean()) if stuck.any() else 0.0,
                    "neighbours_moving": float(around[held & ~stuck].mean()) if (held & ~stuck).any() else 0.0,
                    "ahead_without_task": float((~held[front[front >= 0]]).mean()) if (front >= 0).any() else 0.0,
                    "blocks": len(sizes), "in_blocks": int(sum(sizes)), "largest": sizes[0] if sizes else 0})
    return out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("instance")
    parser.add_argument("output")
    parser.add_argument("--every", type=int, default=500, help="steps per row (default 500)")
    parser.add_argument("--window", type=int, default=250, help="steps a robot's forward moves are counted over")
    parser.add_argument("--moves", type=int, default=50, help="a robot holding a task with fewer is stuck")
    parser.add_argument("--block", type=int, default=20, help="robots of the smallest packed block counted")
    args = parser.parse_args(argv)
    for name in ("every", "window", "moves", "block"):
        if getattr(args, name) < 1:
            parser.error(f"--{name} {getattr(args, name)} must be at least 1")
    with open(args.output) as f:
        output = json.load(f)
    print("| step | holding a task | stuck | facing an occupied cell | occupied neighbours, stuck (others) "
          "| robot ahead without a task | packed blocks | robots in them | largest |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows(read_instance(args.instance), output, args.every, args.window, args.moves, args.block):
        print(f"| {r['step']:,} | {r['holding']:,} | {r['stuck']:,} | {r['facing_occupied']:.0%} | "
              f"{r['neighbours_stuck']:.1f} ({r['neighbours_moving']:.1f}) | {r['ahead_without_task']:.0%} | "
              f"{r['blocks']} | {r['in_blocks']:,} | {r['largest']:,} |")


if __name__ == "__main__":
    main()
