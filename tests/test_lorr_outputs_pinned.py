"""Work-bounded League runs pinned to their output files: every planner and scheduler kept by the League wing's
recomposition (planners from parts, one spec from file to planner) writes, for the same seed, the file it wrote before
it (hashes taken at commit d828c49, before the change).  A change that moves any of these plans fails here and says
which; a deliberate one updates the hash and says why in its commit."""

from __future__ import annotations

import hashlib
import json

import pytest

from agents.lorr.run import run_lorr
from mrmt_env.lorr.instance import example_instance_path
from mrmt_env.lorr.output import write_output

CASES = [  # scheduler, planner, options, sha1[:12] of the output file without its seconds, tasks, chip calls
    ("lorr-greedy", "pibt", {}, "722d33f44647", 17, 0),
    ("lorr-greedy", "pibt-flow", {}, "2dbb6dc19400", 20, 0),
    ("lorr-greedy", "epibt", {}, "0f3a41e18087", 21, 0),
    ("lorr-greedy", "epibt-chain", {}, "5fbb0be4c77a", 21, 0),
    ("lorr-weighted", "epibt", {"planner_options": {"active": 0.3, "active_by": "task", "congestion": 2,
                                                    "flow": False, "weight_power": 2}}, "1a2bffbfafc4", 12, 0),
    ("lorr-greedy", "epibt-ising", {}, "0f3a41e18087", 21, 576),
    # moved at the chip rounds' fix (a group's cost below zero, as the push chains' are, no longer read as "none")
    ("lorr-greedy", "epibt-chain-ising", {}, "37314c36b20e", 22, 73920),
    ("lorr-greedy", "pibt-ising", {}, "64820c8d5d00", 22, 256),
    ("lorr-ising", "pibt", {}, "94ab9633c754", 22, 1120),
]


def digest(path) -> str:
    data = json.loads(path.read_text())
    for key in [k for k in data if "time" in k.lower()]:  # measured seconds differ run to run
        data.pop(key)
    return hashlib.sha1(json.dumps(data, sort_keys=True).encode()).hexdigest()[:12]


@pytest.mark.parametrize("scheduler, planner, options, sha, tasks, calls", CASES,
                         ids=[f"{c[0]}+{c[1]}" + ("+options" if c[2] else "") for c in CASES])
def test_a_work_bounded_run_writes_the_file_it_wrote_before(tmp_path, scheduler, planner, options, sha, tasks, calls):
    record, sim, _ = run_lorr(example_instance_path(), scheduler, planner, steps=40, seed=1, options=options)
    write_output(sim, tmp_path / "o.json")
    assert (digest(tmp_path / "o.json"), record["tasks_finished"], record["chip_calls"]) == (sha, tasks, calls)
