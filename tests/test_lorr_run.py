"""LoRR runs: schedulers x the turning executor, the output file, ``mrmt lorr run`` / ``check``."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mrmt_env.lorr.output import check_output, output_dict, read_output
from agents.lorr.run import MEASURED_KEYS, RUN_KEYS, run_lorr
from mrmt_env.lorr.instance import example_instance_path, read_instance

SHARED = Path(__file__).resolve().parents[2] / "shared" / "lorr"
needs_shared = pytest.mark.skipif(not SHARED.is_dir(), reason="the LoRR instances (shared/lorr) are not beside the checkout")
EXAMPLE = example_instance_path()


def _mrmt(*args, timeout=600):
    return subprocess.run([sys.executable, "-m", "agents.cli", *args], capture_output=True, text=True, timeout=timeout)


@pytest.mark.parametrize("scheduler, executor", [("lorr-greedy", "pibt"), ("strong", "pibt"),
                                                 ("lorr-greedy", "pibt-flow")])
def test_a_run_finishes_tasks_without_errors_and_its_file_rechecks_to_its_count(scheduler, executor):
    record, sim, step_s = run_lorr(EXAMPLE, scheduler, executor, steps=120, seed=0)
    assert record["executor"] == executor
    assert set(RUN_KEYS) <= set(record)
    assert record["errors"] == 0 and record["schedule_errors"] == 0
    assert record["tasks_finished"] == sim.finished > 5
    assert len(step_s) == 120 and (step_s > 0).all()
    data = json.loads(json.dumps(output_dict(sim, step_s)))
    result = check_output(read_instance(EXAMPLE), data)
    assert result.tasks_finished == record["tasks_finished"] == data["numTaskFinished"]
    assert result.errors == 0 and result.steps == 120
    # events: one per errand reached, independently counted from the tasks' errand lists
    per_task = {}
    for t, a, task, done in data["events"]:
        per_task[task] = done
    finished = sum(1 for task, done in per_task.items() if done == len(data["tasks"][task][2]) // 2)
    assert finished == record["tasks_finished"] and len(data["events"]) == record["errands"]


def test_runs_are_deterministic_for_a_seed():
    a, sim_a, _ = run_lorr(EXAMPLE, "lorr-greedy", "pibt", steps=80, seed=3)
    b, sim_b, _ = run_lorr(EXAMPLE, "lorr-greedy", "pibt", steps=80, seed=3)
    assert a["tasks_finished"] == b["tasks_finished"]
    assert [x.tolist() for x in sim_a.actual] == [x.tolist() for x in sim_b.actual]


def test_guidance_reaches_the_executor_and_the_record():
    plain, sim_plain, _ = run_lorr(EXAMPLE, "lorr-greedy", "pibt", steps=60, seed=1, options={"guidance": 0})
    lanes, sim_lanes, _ = run_lorr(EXAMPLE, "lorr-greedy", "pibt", steps=60, seed=1)
    assert plain["guidance"] == 0 and lanes["guidance"] == 2  # pibt's default
    assert [x.tolist() for x in sim_plain.actual] != [x.tolist() for x in sim_lanes.actual]
    again, sim_again, _ = run_lorr(EXAMPLE, "lorr-greedy", "pibt", steps=60, seed=1, options={"guidance": 2})
    assert [x.tolist() for x in sim_again.actual] == [x.tolist() for x in sim_lanes.actual]
    assert run_lorr(EXAMPLE, "lorr-greedy", "epibt", steps=5, seed=1)[0]["guidance"] == 0


def test_check_counts_a_tampered_file_not_its_claim():
    _, sim, step_s = run_lorr(EXAMPLE, "lorr-greedy", "pibt", steps=60, seed=0)
    data = output_dict(sim, step_s)
    claimed = data["numTaskFinished"]
    data["numTaskFinished"] = claimed + 100
    paths = [p.split(",") for p in data["plannerPaths"]]
    # robot 0 never moves: its errands are not reached, and whoever needed its cell may collide
    paths[0] = ["W"] * len(paths[0])
    data["plannerPaths"] = [",".join(p) for p in paths]
    result = check_output(read_instance(EXAMPLE), data)
    assert result.claimed == claimed + 100 and result.tasks_finished != claimed + 100


@needs_shared
def test_check_command_on_the_2023_record(tmp_path):
    proc = _mrmt("lorr", "check", str(SHARED / "2023-main/random.domain/MR23-I-04.json"),
                 str(SHARED / "2023-main/best_solutions/MR23-I-04.json.zip"), "--json")
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout) == {"numTaskFinished": 1741, "errors": 0, "steps": 500, "errands": 1741,
                                       "scheduleErrors": 0, "claimedTaskFinished": 1741,
                                       "eventsAgree": None, "numEntryTimeouts": 0,
                                       "firstErrorStep": None}


def test_executor_options_reach_the_executor_and_the_record(tmp_path):
    """``--planner-option`` builds the executor with its own options (the run then differs from the
    default one and equals the API run with the same options), and the record names them."""
    row = lambda proc: json.loads(proc.stdout.splitlines()[0])  # noqa: E731
    base = ["lorr", "run", str(EXAMPLE), "--planner", "epibt", "--steps", "40", "--no-progress", "--json"]
    plain = _mrmt(*base, "--out", str(tmp_path / "plain"))
    opted = _mrmt(*base, "--planner-option", "op_len=2", "--planner-option", "flow=false", "--out", str(tmp_path / "o"))
    assert plain.returncode == 0 and opted.returncode == 0, plain.stderr + opted.stderr
    assert row(plain)["executor_options"] == {} and row(opted)["executor_options"] == {"op_len": 2, "flow": False}
    paths = lambda d: read_output(tmp_path / d / "output.json")["actualPaths"]  # noqa: E731
    assert paths("plain") != paths("o")
    _, sim, _ = run_lorr(EXAMPLE, "lorr-greedy", "epibt", steps=40, options={"executor_options": {"op_len": 2, "flow": False}})
    assert output_dict(sim)["actualPaths"] == paths("o")


def test_run_command_writes_a_file_that_check_reads_back(tmp_path):
    proc = _mrmt("lorr", "run", str(EXAMPLE), "--scheduler", "lorr-greedy", "--steps", "50", "--out", str(tmp_path),
                 "--no-progress", "--json")
    assert proc.returncode == 0, proc.stderr
    row = json.loads(proc.stdout.splitlines()[0])
    out = tmp_path / "output.json"
    data = read_output(out)
    assert data["numTaskFinished"] == row["tasks_finished"] and len(data["plannerTimes"]) == 50
    assert set(data["start"][0][2]) <= set("ESWN") and data["actionModel"] == "MAPF_T"
    check = _mrmt("lorr", "check", str(EXAMPLE), str(out), "--json")
    assert check.returncode == 0, check.stderr
    assert json.loads(check.stdout)["numTaskFinished"] == row["tasks_finished"]


@pytest.mark.parametrize("args, needle", [
    (["run", "no/such.json"], "no/such.json: no such instance file"),
    (["run", str(EXAMPLE), "--scheduler", "telepathy"], "unknown scheduler 'telepathy'; known: lorr-greedy, lorr-weighted, lorr-ising, strong, "
                                                       "ising, fast, ising-paper, a sharing+tour pair or ppo:MODEL.zip"),
    (["run", str(EXAMPLE), "--scheduler", "ssa+telepathy"], "a sharing+tour pair or ppo:MODEL.zip (unknown tour "
                                                           "planner 'telepathy'"),
    (["run", str(EXAMPLE), "--planner", "teleport"], "unknown planner 'teleport'"),
    (["run", str(EXAMPLE), "--steps", "0"], "--steps must be >= 1, got 0"),
    (["run", str(EXAMPLE), "--guidance", "17"], "--guidance: guidance = 17 must be an integer in [0, 16]"),
    (["run", str(EXAMPLE), "--scheduler", "ppo:/no/such.zip"], "/no/such.zip"),
    (["run", str(EXAMPLE), "--scheduler", "strong", "--no-keep"], "--no-keep acts on --replan: add --replan"),
    (["run", str(EXAMPLE), "--planner", "epibt", "--planner-option", "weight_power"],
     "--planner-option 'weight_power' must look like KEY=VALUE"),
    (["run", str(EXAMPLE), "--planner", "epibt", "--planner-option", "warp=9"],
     "epibt takes no option 'warp'; its options: guidance, corridors, congestion, refresh, flow, replans"),
    (["run", str(EXAMPLE), "--planner", "epibt", "--planner-option", "weight_power=3"],
     "--planner-option weight_power = 3 must be an integer in [0, 2]"),
    (["check", str(EXAMPLE), "/no/such/output.json"], "no such output file"),
])
def test_bad_input_is_one_line_and_exit_2(args, needle):
    proc = _mrmt("lorr", *args, "--json") if args[0] == "check" else _mrmt("lorr", *args, "--no-progress")
    assert proc.returncode == 2, proc.stdout + proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in proc.stderr


def test_inline_and_process_backends_give_the_same_runs(tmp_path):
    base = ["lorr", "run", str(EXAMPLE), "--scheduler", "lorr-greedy,fast", "--steps", "40", "--seeds", "2",
            "--no-progress", "--json"]
    inline = _mrmt(*base, "--backend", "inline")
    pool = _mrmt(*base, "--backend", "process", "--jobs", "2")
    assert inline.returncode == 0 and pool.returncode == 0, inline.stderr + pool.stderr
    keys = ("instance", "scheduler", "seed", "tasks_finished", "errands", "errors")
    rows = [[{k: json.loads(x)[k] for k in keys} for x in p.stdout.splitlines()] for p in (inline, pool)]
    assert rows[0] == rows[1] and len(rows[0]) == 4


def test_ray_backend_gives_the_inline_runs():
    pytest.importorskip("ray")
    base = ["lorr", "run", str(EXAMPLE), "--scheduler", "lorr-greedy", "--steps", "30", "--seeds", "2",
            "--no-progress", "--json"]
    inline = _mrmt(*base, "--backend", "inline")
    ray = _mrmt(*base, "--backend", "ray", "--jobs", "2")
    assert inline.returncode == 0 and ray.returncode == 0, inline.stderr + ray.stderr
    rows = [[{k: v for k, v in json.loads(x).items() if k not in MEASURED_KEYS} for x in p.stdout.splitlines()]
            for p in (inline, ray)]
    assert rows[0] == rows[1] and [r["seed"] for r in rows[0]] == [0, 1]


def test_a_portfolio_on_threads_runs_as_on_one_and_is_charged_its_cpu_seconds():
    """``epibt`` with ``portfolio=3``: the same run on one thread and on two (the plans do not depend on the
    threads); the host energy is charged on the CPU seconds of every thread, at least the wall seconds."""
    runs = [run_lorr(EXAMPLE, "lorr-greedy", "epibt", steps=40, seed=2,
                     options={"executor_options": {"portfolio": 3, "threads": k}}) for k in (1, 2)]
    assert [x.tolist() for x in runs[0][1].actual] == [x.tolist() for x in runs[1][1].actual]
    for record, sim, _ in runs:
        assert record["errors"] == 0 and record["host_cpu_s"] >= record["host_s"] > 0
        done = max(sim.finished, 1)
        assert record["total_energy_per_task_j"] == pytest.approx(record["host_cpu_s"] * 15.0 / done)


def test_ising_scheduler_charges_the_chip_per_step(monkeypatch):
    """The record's chip calls, chip seconds and chip joules (summed per decision by the runner) are the machine's
    own ledger over the run (counted by the machine as it is called)."""
    import agents.lorr.run as run

    built, real = [], run.make_roles

    def keep(*args, **kwargs):
        built.append(real(*args, **kwargs))
        return built[-1]

    monkeypatch.setattr(run, "make_roles", keep)
    record, sim, _ = run_lorr(EXAMPLE, "ising", "pibt", steps=40, seed=0)
    ledger = built[-1][0].assigner.pipeline.sharing.chip.ledger  # the run's machine (the tour layer shares it)
    assert built[-1][0].assigner.pipeline.tour.chip is built[-1][0].assigner.pipeline.sharing.chip
    assert ledger.physical_calls > 0 and record["errors"] == 0
    assert record["chip_calls"] == ledger.physical_calls + ledger.logical_calls
    assert record["chip_s"] == pytest.approx(ledger.chip_time_parallel_s, rel=1e-12)
    done = max(sim.finished, 1)
    assert record["machine_energy_per_task_j"] == pytest.approx(ledger.energy_j / done, rel=1e-12)
    assert record["paper_energy_per_task_j"] == record["machine_energy_per_task_j"]  # an Ising scheduler: the chip's


def test_shortlist_keeps_each_free_robots_least_makespan_tasks():
    from lorr_reference import bfs as grid_bfs

    from agents.lorr.schedulers import make_scheduler
    from mrmt_env.lorr.sim import LoRRSimulator

    inst = read_instance(EXAMPLE)
    sim = LoRRSimulator(inst)
    sched = make_scheduler("strong", shortlist=2)
    sched.reset(sim)
    grid = inst.grid

    def bfs(src):
        return grid_bfs(grid, src)

    ids = np.array(sorted(sim.tasks.open), dtype=np.int64)
    cells = np.array([sim.tasks.errands_of(int(k))[0] for k in ids])
    keep, _ = sched._shortlist(sim.tasks, ids, cells, sim.pos)
    length = [sum(bfs(int(a))[int(b)] for a, b in zip(e[:-1], e[1:])) for e in (sim.tasks.errands_of(int(k)) for k in ids)]
    want = set()
    for p in sim.pos.tolist():
        d = bfs(p)
        cost = [(d[c] + length[j], j) for j, c in enumerate(cells.tolist())]
        costs = sorted(c for c, _ in cost)
        cut = costs[1]
        # any two of least makespan (ties at the cut may go either way)
        chosen = {j for c, j in cost if c < cut}
        assert chosen <= set(keep.tolist())
        want |= {j for c, j in cost if c <= cut}
    assert set(keep.tolist()) <= want
    with pytest.raises(ValueError, match=r"shortlist = 0 must be an integer in \[1, 1048576\] or null$"):
        make_scheduler("strong", shortlist=0)


@needs_shared
def test_an_executor_that_cannot_take_the_team_is_refused_before_the_run():
    warehouse = SHARED / "2024-main" / "warehouse.domain" / "WAREHOUSE.json"
    proc = _mrmt("lorr", "run", str(warehouse), "--planner", "pibt-flow", "--planner-option", "field_bytes=500000000",
                 "--steps", "2", timeout=120)
    assert proc.returncode == 2 and proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and ("10000 robots x 38586 free cells need 781,960,000 bytes, over field_bytes = "
                                "500,000,000") in lines[0]


def test_run_help_names_every_turning_executor(capsys, monkeypatch):
    import argparse

    monkeypatch.setenv("COLUMNS", "2000")  # argparse wraps at hyphens too: a name split over two lines is not a word

    from agents.commands.lorr import add_arguments
    from planners.mapf import TURNING_PLANNERS

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    with pytest.raises(SystemExit):
        parser.parse_args(["run", "--help"])
    words = set(capsys.readouterr().out.replace(",", " ").replace("(", " ").split())
    assert [name for name in TURNING_PLANNERS if name not in words] == []


def test_a_replanned_robot_keeps_its_task_unless_given_a_shorter_one_or_its_task_goes_to_another():
    """``keep``: after a re-plan, a robot moved off its unopened task takes it back unless another robot got
    it or the robot's new task has a strictly smaller makespan (checked against BFS makespans computed here)."""
    from lorr_reference import bfs as grid_bfs

    from agents.lorr.schedulers import make_scheduler
    from mrmt_env.lorr.sim import LoRRSimulator

    inst = read_instance(EXAMPLE)
    sim = LoRRSimulator(inst)
    sched = make_scheduler("strong", replan=True)
    sched.reset(sim)
    tasks = sim.tasks

    def makespan(task, cell):
        e = tasks.errands_of(task)
        return int(grid_bfs(inst.grid, cell)[int(e[0])]) + sum(int(grid_bfs(inst.grid, int(a))[int(b)])
                                                               for a, b in zip(e[:-1], e[1:]))

    ids = sorted(tasks.open)
    a, b = 0, 1
    ranked = sorted((makespan(k, int(sim.pos[a])), k) for k in ids)
    worse, better = ranked[-1][1], ranked[0][1]
    ref = makespan(worse, int(sim.pos[a]))
    assert makespan(better, int(sim.pos[a])) < ref  # a strictly shorter task exists for robot a
    for old_cost_task, new_task, other, want in [
        (better, worse, -1, better),  # the new task is longer: robot a keeps its task, the new one is free
        (worse, better, -1, better),  # the new task is shorter: robot a takes it
        (better, worse, better, worse),  # robot b got a's task: a keeps its new one
        (better, -1, -1, better),  # the re-plan left a without a task: it keeps its own
    ]:
        before = np.full(inst.team_size, -1, dtype=np.int64)
        before[a] = old_cost_task
        proposal = np.full(inst.team_size, -1, dtype=np.int64)
        proposal[a], proposal[b] = new_task, other
        sched._keep(tasks, sim.pos, before, proposal)
        assert proposal[a] == want and proposal[b] == other
        assert sched.makespan(tasks, int(proposal[a]), int(sim.pos[a])) == makespan(int(proposal[a]), int(sim.pos[a]))
    off, sim_off, _ = run_lorr(EXAMPLE, "strong", "pibt", steps=80, options={"replan": True, "keep": False})
    on, sim_on, _ = run_lorr(EXAMPLE, "strong", "pibt", steps=80, options={"replan": True})
    assert on["errors"] == off["errors"] == 0 and on["schedule_errors"] == off["schedule_errors"] == 0
    assert [x.tolist() for x in sim_on.actual] != [x.tolist() for x in sim_off.actual]
    with pytest.raises(ValueError, match="keep = 1 must be true or false$"):
        make_scheduler("strong", replan=True, keep=1)


def test_the_old_flag_names_still_run_and_say_they_are_deprecated():
    new = _mrmt("lorr", "run", str(EXAMPLE), "--planner", "epibt", "--planner-option", "op_len=2", "--steps", "20",
                "--no-progress", "--json")
    old = _mrmt("lorr", "run", str(EXAMPLE), "--executor", "epibt", "--executor-option", "op_len=2", "--steps", "20",
                "--no-progress", "--json")
    assert new.returncode == old.returncode == 0, old.stderr
    assert json.loads(new.stdout.splitlines()[0])["tasks_finished"] == json.loads(old.stdout.splitlines()[0])["tasks_finished"]
    assert "--executor is deprecated; use --planner" in old.stderr
    assert "--executor-option is deprecated; use --planner-option" in old.stderr and "deprecated" not in new.stderr
    both = _mrmt("lorr", "run", str(EXAMPLE), "--executor", "pibt", "--planner", "pibt", "--steps", "5")
    assert both.returncode == 2 and "--executor is the old name of --planner: give --planner only" in both.stderr
