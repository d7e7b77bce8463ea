"""``benchmarks/lorr_jams.py``: its replay and counts against the run it reads."""

from __future__ import annotations

from benchmark_modules import load

import numpy as np

from agents.lorr.run import run_lorr
from mrmt_env.lorr.instance import example_instance_path, read_instance
from mrmt_env.lorr.output import output_dict

jams = load("lorr_jams")


def test_replay_and_holding_equal_the_simulator_at_every_step():
    inst = read_instance(example_instance_path())
    _, sim, _ = run_lorr(inst, "lorr-greedy", "pibt", steps=60)
    output = output_dict(sim)
    states = jams.replay(inst, output, range(1, 61))
    for t in range(1, 61):
        s = run_lorr(inst, "lorr-greedy", "pibt", steps=t)[1]  # the same run's first t steps
        pos, orient, moved = states[t]
        assert pos.tolist() == s.pos.tolist() and orient.tolist() == s.orient.tolist()
        assert moved.tolist() == [p.split(",")[:t].count("F") for p in output["actualPaths"]]
        assert jams.holding(output, t).tolist() == (s.tasks.assigned >= 0).tolist()


def test_rows_count_the_stuck_robots_by_their_moves():
    inst = read_instance(example_instance_path())
    _, sim, _ = run_lorr(inst, "lorr-greedy", "pibt", steps=60)
    output = output_dict(sim)
    (row,) = jams.rows(inst, output, every=60, window=20, moves=3, block=2)
    held = sim.tasks.assigned >= 0
    recent = np.array([p.split(",")[40:60].count("F") for p in output["actualPaths"]])
    assert row["step"] == 60 and row["holding"] == int(held.sum())
    assert row["stuck"] == int((held & (recent < 3)).sum())
    sizes = jams.blocks(sim.pos, inst.width)
    assert sum(sizes) == len(sim.pos)
    assert row["in_blocks"] == sum(s for s in sizes if s >= 2) and row["largest"] == max([0] + [s for s in sizes if s >= 2])


def test_blocks_join_cells_that_touch_and_not_across_a_row_end():
    # a 5-wide map: 0-1-2 touch along row 0, 0-5-10 down column 0; 4 (end of row 0) does not touch 5 (start of
    # row 1), nor 22 anything
    assert jams.blocks(np.array([0, 1, 2, 4, 5, 10, 22]), 5) == [5, 1, 1]
    assert jams.blocks(np.array([4, 9, 14]), 5) == [3] and jams.blocks(np.array([], dtype=np.int64), 5) == []
