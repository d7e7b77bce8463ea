"""``benchmarks/lorr_task_lengths.py``: its counts against the run it reads."""

from __future__ import annotations

from benchmark_modules import load
from lorr_reference import bfs

from agents.lorr.run import run_lorr
from mrmt_env.lorr.instance import example_instance_path, read_instance
from mrmt_env.lorr.output import output_dict

lengths = load("lorr_task_lengths")


def test_rows_count_the_runs_tasks_and_their_legs():
    inst = read_instance(example_instance_path())
    _, sim, _ = run_lorr(inst, "lorr-greedy", "pibt", steps=60)
    output = output_dict(sim)
    rows = lengths.rows(inst, output, 20)
    assert [r["from"] for r in rows] == [0, 20, 40]
    assert sum(r["finished"] for r in rows) == sim.finished > 0
    width = inst.grid.shape[1]
    for tid, _rev, locs in output["tasks"]:  # each task's legs, by the plain BFS of the tests
        cells = [locs[i] * width + locs[i + 1] for i in range(0, len(locs), 2)]
        want = sum(int(bfs(inst.grid, a)[b]) for a, b in zip(cells[:-1], cells[1:]))
        assert lengths.task_legs(inst.grid, [[tid, 0, locs]])[tid][1] == want
    assert rows[0]["revealed"] == len([t for t in output["tasks"] if t[1] < 20])
