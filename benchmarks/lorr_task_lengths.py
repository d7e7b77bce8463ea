"""Task lengths over a League run: why the pace falls (the short tasks go first, or the robots jam).

Reads a run's ``output.json`` (``mrmt lorr run ... --out DIR``) beside its instance: each task's legs (BFS moves from
errand to errand on the instance's map), and per bin of steps the tasks finished (a task counts where its last
errand is done), their mean legs, the legs moved (their sum), the open tasks' mean legs at the bin's start and the
tasks revealed in it.  Reading only, no run.

    python benchmarks/lorr_task_lengths.py INSTANCE.json DIR/output.json --bin 500
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from mrmt_env.distances import bfs_flat
from mrmt_env.lorr.instance import read_instance


def task_legs(grid: np.ndarray, tasks: list) -> dict[int, tuple[int, int, int]]:
    """``task id -> (revealed at, legs, errands)`` of the output's ``tasks`` (``[id, revealed, [r, c, r, c, ...]]``)."""
    height, width = grid.shape
    flat = np.ascontiguousarray(grid.reshape(-1))
    field = np.empty(height * width, dtype=np.int64)
    queue = np.empty(height * width, dtype=np.int64)
    out = {}
    for tid, revealed, locs in tasks:
        cells = [locs[i] * width + locs[i + 1] for i in range(0, len(locs), 2)]
        legs = 0
        for a, b in zip(cells[:-1], cells[1:]):
            field[:] = -1
            field[a] = 0
            queue[0] = a
            bfs_flat(flat, width, field, queue, 1)
            legs += int(field[b])
        out[tid] = (int(revealed), legs, len(cells))
    return out


def rows(instance, output: dict, bin_steps: int) -> list[dict]:
    """Per bin of ``bin_steps`` steps (module docstring)."""
    tasks = task_legs(instance.grid, output["tasks"])
    errands, last = {}, {}
    for t, _robot, task, n in output["events"]:
        errands[task] = max(errands.get(task, 0), n)
        last[task] = max(last.get(task, -1), t)
    done = {k: last[k] for k, n in errands.items() if n == tasks[k][2]}
    out = []
    for b in range(0, int(output["makespan"]), bin_steps):
        legs = [tasks[k][1] for k, t in done.items() if b <= t < b + bin_steps]
        open_ = [L for k, (rev, L, _) in tasks.items() if rev <= b and (k not in done or done[k] >= b)]
        new = [L for k, (rev, L, _) in tasks.items() if b <= rev < b + bin_steps]
        out.append({"from": b, "finished": len(legs), "legs_mean": float(np.mean(legs)) if legs else 0.0,
                    "legs_moved": int(sum(legs)), "open_legs_mean": float(np.mean(open_)) if open_ else 0.0,
                    "revealed": len(new), "revealed_legs_mean": float(np.mean(new)) if new else 0.0})
    return out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("instance")
    parser.add_argument("output")
    parser.add_argument("--bin", type=int, default=500, help="steps per row (default 500)")
    args = parser.parse_args(argv)
    if args.bin < 1:
        parser.error(f"--bin {args.bin} must be at least 1")
    with open(args.output) as f:
        output = json.load(f)
    print("| steps | tasks finished | their legs, mean | legs moved | open tasks' legs, mean | revealed | their legs |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for r in rows(read_instance(args.instance), output, args.bin):
        print(f"| {r['from']:,}-{r['from'] + args.bin:,} | {r['finished']:,} | {r['legs_mean']:.0f} | "
              f"{r['legs_moved']:,} | {r['open_legs_mean']:.0f} | {r['revealed']:,} | {r['revealed_legs_mean']:.0f} |")


if __name__ == "__main__":
    main()
