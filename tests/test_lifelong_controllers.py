"""Lifelong controllers: assignment rules, conflict-free execution, chip charging, ``mrmt compare``."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import mrmt_env  # noqa: F401  (registers the ids)
from agents.cli import main
from agents.lifelong.controllers import GreedyAssigner, PipelineAssigner, make_lifelong_controller
from agents.lifelong.evaluation import evaluate_lifelong, summarize
from planners.mapf.common import GoalFields

SMALL = dict(height=12, width=14, n_robots=6, n_targets=9, layout="warehouse",
             layout_options={"shelf_length": 4, "margin": 1})
WAREHOUSE = "mrmt_env/MRMT-Lifelong-Warehouse-v0"


def test_greedy_gives_each_idle_robot_in_turn_its_nearest_unclaimed_task():
    grid = np.zeros((1, 10), dtype=bool)
    fields = GoalFields(grid)
    tasks = np.array([1, 4, 9])
    queues, compute = GreedyAssigner().assign(grid, fields, np.array([3, 2, 8, 0]), tasks, seed=0)
    # robot at 3 takes 4 (1 away); robot at 2 takes 1; robot at 8 takes 9; nothing left for the last
    assert queues == [[1], [0], [2], []] and compute.chip_calls == 0


@pytest.mark.parametrize("spec", ["greedy", "strong", "ising"])
@pytest.mark.parametrize("executor", ["pibt", "windowed"])
def test_controllers_serve_tasks_without_a_single_refused_move(spec, executor):
    env = gym.make(WAREHOUSE, **SMALL, max_episode_steps=60)
    obs, _ = env.reset(seed=2)
    ctrl = make_lifelong_controller(spec, seed=1, executor=executor)
    chip = getattr(getattr(getattr(ctrl.assigner, "pipeline", None), "sharing", None), "chip", None)
    assert (chip is not None) == (spec == "ising")
    charged = 0
    for _ in range(60):
        before = chip.ledger.snapshot() if chip is not None else None
        obs, _, term, trunc, info = env.step(ctrl.act(obs))
        charged += ctrl.last_compute.chip_calls + ctrl.last_compute.logical_calls
        if chip is not None:  # the step's decision is charged exactly what the chip's ledger recorded
            assert _report_counts(ctrl.last_compute) == _ledger_counts(chip.ledger.since(before))
        if trunc:
            break
    # the executor's joint moves are conflict-free, so the env never has to refuse one
    assert info["blocked_moves"] == 0 and info["conflicts"] == 0 and info["invalid_moves"] == 0
    assert info["tasks_completed"] >= 10 and ctrl.replans > 0
    assert (charged > 0) == (spec == "ising")  # every chip call is charged to the decision that made it


def test_pipeline_assigner_commits_the_first_task_of_each_route_and_names_bad_options():
    grid = np.zeros((5, 5), dtype=bool)
    fields = GoalFields(grid)
    queues, compute = PipelineAssigner("strong").assign(grid, fields, np.array([0, 24]), np.array([1, 2, 23, 22]),
                                                        seed=0)
    assert queues == [[0], [2]] and compute.cpu_s > 0
    whole, _ = PipelineAssigner("strong", commit=None, candidates=None).assign(
        grid, fields, np.array([0, 24]), np.array([1, 2, 23, 22]), seed=0)
    assert whole == [[0, 1], [2, 3]]
    with pytest.raises(ValueError, match="unknown lifelong controller 'ssa'"):
        PipelineAssigner("ssa")
    with pytest.raises(ValueError, match=r"group_size = 0 must be an integer in \[1, 1048576\]"):
        PipelineAssigner("strong", group_size=0)
    with pytest.raises(ValueError, match="strong takes no option 'groups'; its options: group_size, commit"):
        PipelineAssigner("strong", groups=2)
    with pytest.raises(ValueError, match="unknown executor 'cbs'"):
        make_lifelong_controller("greedy", executor="cbs")


def _ledger_counts(ledger) -> tuple:
    return ledger.physical_calls, ledger.batches, ledger.logical_calls, ledger.retries


def _report_counts(compute) -> tuple:
    return compute.chip_calls, compute.chip_batches, compute.logical_calls, compute.retries


def test_pipeline_assigner_charges_every_groups_chip_calls_exactly():
    """More idle robots than ``group_size``: several planning calls, one per group; the decision's report
    holds every group's calls, equal to what the chip's own ledger recorded (not only the last group's)."""
    grid = np.zeros((10, 10), dtype=bool)
    fields = GoalFields(grid)
    idle = np.array([0, 9, 90, 99, 22, 27, 72, 77], dtype=np.int64)  # 8 idle robots, far apart
    tasks = np.array([1, 2, 11, 8, 18, 19, 80, 81, 91, 89, 98, 88, 33, 34, 36, 63, 65, 66], dtype=np.int64)
    assigner = PipelineAssigner("ising", group_size=2, candidates=None, commit=None)
    chip = assigner.pipeline.sharing.chip
    assert assigner.pipeline.tour.chip is chip  # one machine, one ledger
    assigner.pipeline.warmup()  # before the wrapper below: the warm-up plans on a copy of the pipeline
    per_call = []
    plan = assigner.pipeline.plan

    def recording_plan(world, seed=None):  # each group's planning call and the ledger it moved
        before = chip.ledger.snapshot()
        out = plan(world, seed=seed)
        per_call.append((_report_counts(out.compute), _ledger_counts(chip.ledger.since(before))))
        return out

    assigner.pipeline.plan = recording_plan
    for seed in range(2):
        per_call.clear()
        before = chip.ledger.snapshot()
        queues, compute = assigner.assign(grid, fields, idle, tasks, seed=seed)
        spent = chip.ledger.since(before)
        assert sorted(t for q in queues for t in q) == list(range(len(tasks)))  # every task, once
        assert len(per_call) == 4 and all(rep == led for rep, led in per_call)
        assert sum(led[0] + led[2] > 0 for _, led in per_call) >= 2  # several groups used the chip
        assert _report_counts(compute) == _ledger_counts(spent)
        assert compute.chip_calls + compute.logical_calls > 0
        assert compute.chip_time_s == pytest.approx(spent.chip_time_s)
        assert compute.accelerator_energy_j == pytest.approx(spent.energy_j)


def test_evaluation_records_and_summary(monkeypatch):
    import ising_backend

    built = []  # every machine a controller builds, in order (an episode's is the last before its row)

    def recording_build(chip):
        machine = build(chip)
        built.append(machine)
        return machine

    build = ising_backend.build_machine
    monkeypatch.setattr(ising_backend, "build_machine", recording_build)
    rows = evaluate_lifelong(["greedy", "ising"], WAREHOUSE, [0, 1], 25, SMALL)
    # the ising episodes' records charge exactly what their chips' ledgers recorded
    assert len(built) >= 2
    for row, machine in zip(rows[2:], built[-2:]):
        ledger = machine.ledger
        assert row["chip_calls"] == ledger.physical_calls + ledger.logical_calls > 0
        assert row["accelerator_energy_j"] == pytest.approx(ledger.energy_j)
    assert [(r["controller"], r["seed"]) for r in rows] == [("greedy", 0), ("greedy", 1), ("ising", 0), ("ising", 1)]
    for r in rows:
        assert r["steps"] == 25 and len(r["latencies"]) == 25 and r["conflicts"] == 0
        assert 0 < r["decision_latency_p50_s"] <= r["decision_latency_p99_s"]
        assert r["total_energy_per_task_j"] >= r["paper_energy_per_task_j"] > 0
    greedy, ising = summarize(rows)
    assert greedy["chip_calls_per_task"] == 0 and ising["chip_calls_per_task"] > 0
    # paper convention: the accelerator's energy only for the chip controller, host CPU for the classical one
    assert greedy["paper_energy_per_task_j"] == pytest.approx(greedy["total_energy_per_task_j"])
    assert ising["paper_energy_per_task_j"] < ising["total_energy_per_task_j"]
    keys = ("tasks_completed", "throughput", "service_time_mean", "chip_calls", "replans")
    again = evaluate_lifelong(["greedy", "ising"], WAREHOUSE, [0], 25, SMALL)
    for a, b in zip(again, (rows[0], rows[2])):  # deterministic episodes and plans, the chip's included
        assert {k: a[k] for k in keys} == {k: b[k] for k in keys}


def test_mrmt_compare_on_a_lifelong_id(tmp_path, capsys):
    args = ["compare", "--env-id", WAREHOUSE, "--controllers", "greedy,strong", "--worlds", "1", "--max-steps", "15",
            "--height", "12", "--width", "14", "--robots", "6", "--targets", "9", "--no-progress",
            "--out", str(tmp_path)]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "greedy" in out and "strong" in out and "lat_p99_ms" in out
    rows = json.loads((tmp_path / "lifelong.json").read_text())
    assert len(rows) == 2 and (tmp_path / "lifelong.csv").exists()
    assert main(["compare", "--env-id", WAREHOUSE, "--controllers", "greedy,nope", "--worlds", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "unknown lifelong controller 'nope'" in err


@pytest.mark.parametrize("extra, msg", [
    (["--controllers", "greedy,ppo:/no/such.zip"], "model file '/no/such.zip' does not exist"),
    (["--controllers", "greedy", "--robots", "500"], "500 robots + 10 targets need 510 distinct free cells, but a "
                                                     "10x10 grid with 20 obstacles has only 80"),
    (["--controllers", "greedy,foo+3opt"], "unknown sharing planner 'foo'"),
])
def test_mrmt_compare_on_a_lifelong_id_checks_before_the_progress_bar(extra, msg, capsys):
    assert main(["compare", "--env-id", "mrmt_env/MRMT-Lifelong-v0", "--worlds", "2", "--max-steps", "5", *extra]) == 2
    err = capsys.readouterr().err
    assert err.startswith("mrmt compare: error: ") and err.count("\n") == 1, err  # no bar before it (tqdm: stderr)
    assert msg in err and "lifelong episodes" not in err and "Traceback" not in err


def test_mrmt_watch_writes_a_lifelong_gif(tmp_path, capsys):
    pytest.importorskip("imageio")
    out = tmp_path / "life.gif"
    assert main(["watch", "--env-id", "mrmt_env/MRMT-Lifelong-v0", "--controller", "greedy", "--steps", "8",
                 "--cell", "8", "--out", str(out)]) == 0
    assert "8 frames" in capsys.readouterr().out and out.stat().st_size > 0
    assert main(["watch", "--env-id", "mrmt_env/MRMT-Lifelong-v0", "--controller", "nope", "--out", str(out)]) == 2
    assert "unknown lifelong controller 'nope'" in capsys.readouterr().err
