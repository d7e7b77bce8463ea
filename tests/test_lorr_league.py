"""The League under its rules: the start kit's clock, an entry, a round scored as the competition scores it."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import time

import numpy as np
import pytest
from lorr_reference import check_events

from agents.lorr.entry import EntryError, load_entry
from mrmt_env.lorr.output import check_output, output_dict
from agents.lorr.round import best_known_table, round_instances
from agents.lorr.run import run_lorr
from mrmt_env.lorr.clock import StepLimit, step_limit
from mrmt_env.lorr.instance import example_instance_path, read_instance
from mrmt_env.lorr.shape import Shape

EXAMPLE = example_instance_path()


def _mrmt(*args, timeout=600):
    return subprocess.run([sys.executable, "-m", "agents.cli", *args], capture_output=True, text=True, timeout=timeout)


# ---------------------------------------------------------------- the clock
@pytest.mark.parametrize("decision, timeouts", [(0.0, 0), (0.4, 0), (1.0, 0), (1.0001, 1), (2.5, 2), (3.0, 2)])
def test_a_decision_costs_a_timeout_per_limit_it_overruns(decision, timeouts):
    """The start kit waits ``planTimeLimit`` at a time; each wait without the decision is one timeout."""
    assert StepLimit(1.0).timeouts(decision) == timeouts
    assert StepLimit(0.5).timeouts(decision / 2) == timeouts


@pytest.mark.parametrize("text, needle", [("0", "step limit '0' must be"), ("soon", "'soon'"),
                                          ("-1", "'-1'"), ("4000", "'4000'")])
def test_bad_step_limits_are_named(text, needle):
    with pytest.raises(ValueError, match=needle):
        step_limit(text)
    assert step_limit("rules") == StepLimit(1.0, 30.0) and step_limit("0.25").step_s == 0.25


class _Slow:
    """An executor wrapper that takes ``seconds`` over every decision (a planner late by construction)."""

    def __init__(self, inner, seconds):
        self.inner, self.seconds = inner, seconds

    def __getattr__(self, name):
        return getattr(self.inner, name)

    def actions(self, pos, orient, goals, deadline=None):
        time.sleep(self.seconds)
        return self.inner.actions(pos, orient, goals, deadline=deadline)


def test_a_late_decision_is_every_robot_waiting_counted_and_written(monkeypatch):
    """A planner taking 0.23 s under a 0.1 s limit: each decision costs two timeouts (T for every robot, no task
    update), then runs; the output's timeouts are exactly its all-T steps and re-check to the count."""
    from planners.mapf import make_turning_planner

    slow = _Slow(make_turning_planner("pibt", read_instance(EXAMPLE).grid, seed=0), 0.23)  # a planner object, as a user's
    record, sim, step_s = run_lorr(EXAMPLE, "lorr-greedy", slow, steps=20, seed=0, limit=StepLimit(0.1))
    assert record["clock"] == "0.1 s per step" and len(step_s) == record["decisions"] == 7
    assert record["timeouts"] == sim.timeouts == 14 and sim.t == 20  # 6 x (2 + 1) steps, then 2 timeouts end it
    data = json.loads(json.dumps(output_dict(sim, step_s)))
    all_t = [t for t in range(20) if all(p.split(",")[t] == "T" for p in data["actualPaths"])]
    assert len(all_t) == data["numEntryTimeouts"] == 14 and all_t[:2] == [0, 1]
    assert len(data["plannerTimes"]) == 7
    result = check_output(read_instance(EXAMPLE), data)
    assert (result.timeouts, result.tasks_finished, result.events_agree) == (14, record["tasks_finished"], True)
    assert check_events(data, sim.width) == record["tasks_finished"]


def test_without_a_limit_a_run_is_work_bounded_and_says_so():
    a, sim_a, _ = run_lorr(EXAMPLE, "lorr-greedy", "pibt", steps=40, seed=2)
    b, sim_b, _ = run_lorr(EXAMPLE, "lorr-greedy", "pibt", steps=40, seed=2, limit=StepLimit(60.0))
    assert a["clock"] == "work-bounded" and a["timeouts"] == 0 and b["timeouts"] == 0
    # a generous clock changes nothing of a fast run's plans
    assert [x.tolist() for x in sim_a.actual] == [x.tolist() for x in sim_b.actual]


def test_epibt_cuts_its_portfolio_at_the_deadline_and_runs_all_of_it_without_one():
    from planners.mapf import make_turning_planner

    inst = read_instance(EXAMPLE)
    goals = np.roll(inst.starts, 1)
    orient = np.zeros(inst.team_size, dtype=np.int64)
    planner = make_turning_planner("epibt", inst.grid, seed=0, portfolio=6, threads=1)
    full = planner.decider
    planner.actions(inst.starts, orient, goals)
    assert len(full.portfolio_costs) == 6
    cutting = make_turning_planner("epibt", inst.grid, seed=0, portfolio=6, threads=1)
    cut = cutting.decider
    act = cutting.actions(inst.starts, orient, goals, deadline=time.perf_counter() - 1.0)  # already late
    assert len(cut.portfolio_costs) == 1 and act.shape == (inst.team_size,)
    # a call that ended past its deadline shrinks the next calls' search; one that left time enough grows it back
    assert full.lns_scale == 1.0 and cut.lns_scale == pytest.approx(0.7)
    assert full.lns == cut.lns == 8 * 50  # 50 iterations per robot
    cutting.actions(inst.starts, orient, goals, deadline=time.perf_counter() - 1.0)
    assert cut.lns == int(400 * 0.7) and cut.lns_scale == pytest.approx(0.49)
    cutting.actions(inst.starts, orient, goals, deadline=time.perf_counter() + 60.0)
    assert cut.lns == int(400 * (0.7 * 0.7)) and cut.lns_scale == pytest.approx(0.539)


# ---------------------------------------------------------------- the entry
def _own(choice) -> dict:
    """A choice's planner options given (beside its defaults), without guidance."""
    return {k: v for k, v in choice.planner.given.items() if k != "guidance"}


def test_the_default_entry_chooses_by_team_fill_cells_and_corridors():
    entry = load_entry("default")
    inst = read_instance(EXAMPLE)
    small = entry.choose(inst)
    assert (small.scheduler.name, small.planner.name, small.rule) == ("lorr-weighted", "epibt-chain", 4)
    assert _own(small) == {"portfolio": 2}
    # the way x 10, its turns counted, the matching of least total cost
    assert small.scheduler.options == {"weight": 10, "turns": True, "optimal": True}
    assert small.planner.options.guidance == 2  # every robot at work where the team is sparse, on crisscross lanes
    # no rule keys on a map's name; every condition is one of what an instance shows at preprocessing
    for rule in entry.rules:
        assert set(rule.conditions) <= {f"{end}_{m}" for end in ("min", "max")
                                        for m in ("robots", "cells", "fill", "corridors", "narrow")}
    # Shape(robots, cells, fill, corridors, narrow); the 2024 maps: RANDOM 1,024 cells, corridors 0.088, narrow 0.221
    maze = entry.rules[0]  # mazes 70 % full: the start kit's default configuration
    assert maze.holds(Shape(383, 1024, 0.75, 0.658, 0.949)) and not maze.holds(Shape(307, 1024, 0.6, 0.658, 0.949))
    assert not maze.holds(Shape(800, 1024, 0.98, 0.088, 0.221)) and not maze.holds(Shape(10000, 70000, 0.75, 0.631, 0.641))
    assert (maze.choice.scheduler.name, maze.choice.planner.name, _own(maze.choice)) == ("lorr-greedy", "pibt-flow", {})
    crowd = entry.rules[1]  # RANDOM-04 and -05 (85 and 98 % of the free cells): one rule, 57 % at work, 100 pushes
    assert crowd.holds(Shape(800, 1024, 0.98, 0.088, 0.221)) and crowd.holds(Shape(700, 1024, 0.85, 0.088, 0.221))
    assert not crowd.holds(Shape(400, 1024, 0.49, 0.088, 0.221)) and not crowd.holds(Shape(1500, 1024, 0.9, 0.088, 0.221))
    assert (crowd.choice.scheduler.name, crowd.choice.planner.name, crowd.choice.scheduler.options["replan"]) == ("strong", "epibt-chain",
                                                                                              True)
    assert _own(crowd.choice) == {"active": 0.57, "active_by": "task", "portfolio": 2,
                                                         "pushes": 100}  # search chains capped at 100 pushes
    dense = entry.rules[2]  # RANDOM-03 (49 % of the free cells): 80 % at work, by the task to go
    assert dense.holds(Shape(400, 1024, 0.49, 0.088, 0.221))
    assert not dense.holds(Shape(200, 1024, 0.24, 0.088, 0.221)) and not dense.holds(Shape(1500, 1024, 0.9, 0.088, 0.221))
    assert _own(dense.choice) == {"active": 0.8, "active_by": "task", "portfolio": 2}
    assert (dense.choice.scheduler.name, dense.choice.planner.name, dense.choice.scheduler.options["replan"]) == ("strong", "epibt-chain",
                                                                                              True)
    sparse = entry.rules[3]  # RANDOM-01, -02
    assert sparse.holds(Shape(100, 1024, 0.12, 0.088, 0.221)) and sparse.holds(Shape(200, 1024, 0.24, 0.088, 0.221))
    big = [r for r in entry.rules if not r.conditions][0].choice
    assert (big.scheduler.name, big.planner.name) == ("lorr-greedy", "epibt")
    # GAME: EPIBT on goal fields that price the crowd, 30 % of the team at work each step, those of least task still
    # to go, the search weighing the robots by their priority squared
    assert _own(big) == {"flow": False, "congestion": 2, "active": 0.3, "active_by": "task",
                                               "weight_power": 2}
    assert big.planner.options.guidance == 8  # along lanes of weight 8
    assert big.scheduler.options == {"way": 5}  # every robot holds a task, the way x 5
    aisles, tables = entry.rules[4], entry.rules[5]
    # SORTATION (0.569) and WAREHOUSE (0.631) by their corridors, not CITY (0.001) nor GAME (0.003)
    assert aisles.holds(Shape(10000, 140 * 500, 0.18, 0.569, 0.569)) and aisles.holds(Shape(10000, 140 * 500, 0.26, 0.631, 0.641))
    assert not aisles.holds(Shape(3000, 256 ** 2, 0.06, 0.001, 0.054)) and not aisles.holds(Shape(6500, 481 * 530, 0.15, 0.003, 0.042))
    assert aisles.choice.scheduler.name == tables.choice.scheduler.name == "lorr-weighted"
    assert aisles.choice.scheduler.options == {"jam": 4}  # the jam term and one-way corridors
    assert aisles.choice.planner.name == "epibt"  # on goal fields, not along guide paths
    assert _own(aisles.choice) == {"flow": False, "corridors": 8}
    assert aisles.choice.planner.options.guidance == 0
    # the city (CITY-01 and CITY-02): EPIBT on goal fields that price the crowd
    assert (tables.choice.scheduler.name, tables.choice.planner.name) == ("lorr-weighted", "epibt")
    assert _own(tables.choice) == {"flow": False, "congestion": 2}
    assert tables.holds(Shape(3000, 256 ** 2, 0.06, 0.001, 0.054)) and tables.holds(Shape(1500, 256 ** 2, 0.03, 0.001, 0.054))
    # the weighted scheduler where its tables fit: the city's 65,536 cells, not GAME's 254,930
    assert not tables.holds(Shape(6500, 481 * 530, 0.15, 0.003, 0.042))


def _generated(tmp_path, spec: str, robots: int):
    from mrmt_env.lorr.generate import generate_instance

    path = tmp_path / f"X-{robots}-{len(list(tmp_path.glob('*.json')))}.json"
    return read_instance(generate_instance(spec, robots, path, seed=0, tasks=50).instance)


def test_the_corridor_share_counts_free_cells_between_two_opposite_free_neighbours():
    from mrmt_env.lorr.shape import corridor_share

    grid = np.zeros((5, 5), dtype=bool)  # two shelf rows of three cells: aisles one cell wide around them
    grid[1, 1:4] = grid[3, 1:4] = True
    # rows 0, 2, 4: the three cells above, between, below the shelves; rows 1, 3: the two ends beside them
    assert corridor_share(grid) == 13 / 19
    assert corridor_share(np.zeros((1, 6), dtype=bool)) == 4 / 6  # the ends have one free neighbour
    assert corridor_share(np.zeros((4, 4), dtype=bool)) == 0.0  # an open floor
    assert corridor_share(np.ones((3, 3), dtype=bool)) == 0.0  # no free cell
    with pytest.raises(ValueError, match="two-dimensional"):
        corridor_share(np.zeros(5, dtype=bool))


def test_the_narrow_share_counts_free_cells_of_at_most_two_free_neighbours():
    from mrmt_env.lorr.shape import narrow_share, shape_of

    grid = np.zeros((5, 5), dtype=bool)  # two shelf rows of three cells, as in the corridors' test
    grid[1, 1:4] = grid[3, 1:4] = True
    # 19 free cells: rows 0 and 4 (corners and the cells beside a shelf: 2 free neighbours), the four cells beside the
    # shelves' ends (2) and the three between the shelves (2) are narrow; the middle row's two ends have 3
    assert narrow_share(grid) == 17 / 19
    assert narrow_share(np.zeros((4, 4), dtype=bool)) == 4 / 16  # an open floor: its corners only
    assert narrow_share(np.ones((2, 2), dtype=bool)) == 0.0
    inst = read_instance(EXAMPLE)
    shape = shape_of(inst)
    assert (shape.robots, shape.cells, shape.narrow) == (inst.team_size, inst.grid.size, narrow_share(inst.grid))


def test_the_entry_reads_the_corridors_off_the_grid_whatever_the_map_is_called(tmp_path):
    from mrmt_env.lorr.shape import corridor_share

    entry = load_entry("default")
    # 1,100 robots (beyond the small-team rules) on a warehouse of one-cell aisles: the aisles' rule; on a uniform
    # map the city's; the maps are called X-*.map, so nothing but the grid can tell them apart
    aisles = _generated(tmp_path, "family:warehouse:64x64:aisle_width=1", 1100)
    flat = _generated(tmp_path, "family:uniform:64x64", 1100)
    assert aisles.map_name.startswith("X-") and flat.map_name.startswith("X-")
    assert corridor_share(aisles.grid) > 0.4 > 0.1 > corridor_share(flat.grid)
    assert entry.choose(aisles).rule == 5 and entry.choose(flat).rule == 6
    assert entry.rules[4].conditions == {"min_corridors": 0.4}


@pytest.mark.parametrize("text, needle", [
    ('[[rule]]\nmin_narrow = 0.9\nmax_narrow = 0.8\nscheduler = "strong"\nplanner = "pibt"\n[[rule]]\nscheduler = "lorr-greedy"\nplanner = "pibt"\n',
     "min_narrow = 0.9 exceeds max_narrow = 0.8"),
    ('[[rule]]\nmaps = ["warehouse*"]\nscheduler = "strong"\nplanner = "pibt"\n[[rule]]\nscheduler = "lorr-greedy"\nplanner = "pibt"\n',
     "unknown key 'maps'"),
    ('[[rule]]\nmin_corridors = 1.5\nscheduler = "strong"\nplanner = "pibt"\n[[rule]]\nscheduler = "lorr-greedy"\nplanner = "pibt"\n',
     r"min_corridors = 1.5 must be a share of the free cells, in \[0, 1\]"),
    ('[[rule]]\nmax_corridors = "wide"\nscheduler = "strong"\nplanner = "pibt"\n[[rule]]\nscheduler = "lorr-greedy"\nplanner = "pibt"\n',
     "max_corridors = 'wide' must be a number >= 0"),
    ('[[rule]]\nmin_corridors = 0.6\nmax_corridors = 0.3\nscheduler = "strong"\nplanner = "pibt"\n[[rule]]\nscheduler = "lorr-greedy"\nplanner = "pibt"\n',
     "min_corridors = 0.6 exceeds max_corridors = 0.3"),
    ('[[rule]]\nscheduler = "strong"\nplanner = "pibt"\nmax_robots = 5\n', "last rule must have no condition"),
    ('[[rule]]\nscheduler = "strong"\nplanner = "pibt"\nspeed = 3\n', "unknown key 'speed'"),
    ('[[rule]]\nplanner = "pibt"\n', "scheduler must name a scheduler"),
    ('[[rule]]\nscheduler = "strong"\nplanner = "pibt"\nreplan = "yes"\n', "replan is a scheduler option: write "
     'scheduler_options = { replan = "yes" }'),
    ('[[rule]]\nscheduler = "strong"\nplanner = "pibt"\nscheduler_options = { replan = "yes" }\n',
     "replan = 'yes' must be true or false"),
    ('[[rule]]\nmax_robots = -3\nscheduler = "strong"\nplanner = "pibt"\n[[rule]]\nscheduler = "s"\nplanner = "p"\n',
     "max_robots = -3 must be a whole number >= 0"),
    ('rule = 3\n', "non-empty list of rules"),
    ('[[rule]]\nmax_cells = 1.5\nscheduler = "strong"\nplanner = "pibt"\n[[rule]]\nscheduler = "s"\nplanner = "p"\n',
     "max_cells = 1.5 must be a whole number >= 0"),
    ('[[rule\n', "not TOML"),
])
def test_bad_entries_name_the_file_rule_and_key(tmp_path, text, needle):
    path = tmp_path / "mine.toml"
    path.write_text(text)
    with pytest.raises(EntryError, match=needle):
        load_entry(path)
    with pytest.raises(EntryError, match="no entry named 'nope'; shipped: default"):
        load_entry("nope")


@pytest.mark.parametrize("rule, needle", [
    ('scheduler = "telepathy"\nplanner = "pibt"', "rule 1: unknown scheduler 'telepathy'"),
    ('scheduler = "strong"\nplanner = "teleport"', "rule 1: unknown planner 'teleport'"),
    ('scheduler = "strong"\nplanner = "epibt"\nplanner_options = { warp = 9 }', "epibt takes no option 'warp'"),
    ('scheduler = "strong"\nplanner = "epibt"\nplanner_options = { op_len = 9 }', "op_len = 9 must be an integer in [1, 5] or 'auto'"),
])
def test_an_entry_whose_names_or_options_do_not_build_is_refused_in_one_line(tmp_path, rule, needle):
    path = tmp_path / "mine.toml"
    path.write_text(f"[[rule]]\n{rule}\n")
    proc = _mrmt("lorr", "run", str(EXAMPLE), "--entry", str(path), "--steps", "5", "--no-progress")
    assert proc.returncode == 2 and needle in proc.stderr and len(proc.stderr.strip().splitlines()) == 1


def test_an_entry_run_is_under_the_rules_clock_unless_told_and_refuses_its_own_flags(tmp_path):
    path = tmp_path / "greedy.json"
    path.write_text(json.dumps({"name": "greedy", "rule": [{"scheduler": "lorr-greedy", "planner": "pibt"}]}))
    proc = _mrmt("lorr", "run", str(EXAMPLE), "--entry", str(path), "--steps", "15", "--no-progress", "--json")
    assert proc.returncode == 0, proc.stderr
    row = json.loads(proc.stdout.splitlines()[0])
    assert row["clock"] == "1 s per step" and (row["scheduler"], row["executor"]) == ("lorr-greedy", "pibt")
    proc = _mrmt("lorr", "run", str(EXAMPLE), "--entry", str(path), "--steps", "15", "--step-limit", "none",
                 "--no-progress", "--json")
    assert json.loads(proc.stdout.splitlines()[0])["clock"] == "work-bounded"
    proc = _mrmt("lorr", "run", str(EXAMPLE), "--entry", str(path), "--planner", "epibt", "--no-progress")
    assert proc.returncode == 2 and "--entry decides the scheduler, the planner and their options: drop --planner" \
        in proc.stderr


# ---------------------------------------------------------------- the round
def _round_folder(tmp_path):
    """A round in the 2024 layout: two copies of the shipped instance, their steps in simulation_time.json."""
    domain = tmp_path / "round" / "random.domain"
    domain.mkdir(parents=True)
    for f in EXAMPLE.parent.iterdir():
        if f.name != "simulation_time.json":
            shutil.copy(f, domain / f.name)
    shutil.copy(domain / "EXAMPLE-01.json", domain / "EXAMPLE-02.json")
    (tmp_path / "round" / "simulation_time.json").write_text('{"EXAMPLE-01": 40, "EXAMPLE-02": 60}')
    best = tmp_path / "best.json"
    best.write_text(json.dumps({"test": {"EXAMPLE-01": [8, 40, 20], "EXAMPLE-02": [8, 60, 100]}}))
    entry = tmp_path / "greedy.toml"
    entry.write_text('name = "greedy"\n[[rule]]\nscheduler = "lorr-greedy"\nplanner = "pibt"\n')
    return tmp_path / "round", best, entry


def test_a_round_runs_every_instance_scores_the_sum_of_shares_and_resumes(tmp_path):
    folder, best, entry = _round_folder(tmp_path)
    out = tmp_path / "out"
    args = ["lorr", "round", str(folder), "--entry", str(entry), "--out", str(out), "--best-known", str(best),
            "--no-progress"]
    proc = _mrmt(*args, "--steps", "30")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    rows = {r["instance"]: r for r in summary["rows"]}
    assert set(rows) == {"EXAMPLE-01", "EXAMPLE-02"} and summary["clock"] == "1 s per step"
    for name, full, best_tasks in (("EXAMPLE-01", 40, 20), ("EXAMPLE-02", 60, 100)):
        r = rows[name]
        data = json.loads((out / name / "output.json").read_text())
        assert r["prefix"] and r["steps"] == 30 and r["full_steps"] == full
        assert r["best_known_pro_rata"] == pytest.approx(best_tasks * 30 / full)
        assert r["share_of_best"] == pytest.approx(data["numTaskFinished"] / (best_tasks * 30 / full))
        assert check_output(read_instance(folder / "random.domain" / f"{name}.json"), data).tasks_finished \
            == r["tasks_finished"] == data["numTaskFinished"]
        assert r["timeouts"] == data["numEntryTimeouts"] and r["peak_rss_mb"] > 50
    assert summary["score"] == pytest.approx(sum(r["share_of_best"] for r in summary["rows"]))
    assert "score" in (out / "summary.md").read_text() and "(pro rata)" in proc.stdout
    # --resume keeps both (same entry, steps, clock, seed): the files are not rewritten
    stamp = (out / "EXAMPLE-01" / "output.json").stat().st_mtime_ns
    again = _mrmt(*args, "--steps", "30", "--resume")
    assert again.returncode == 0, again.stderr
    assert (out / "EXAMPLE-01" / "output.json").stat().st_mtime_ns == stamp
    assert json.loads((out / "summary.json").read_text())["score"] == pytest.approx(summary["score"])
    # the summary names the commit every row ran at and the machine; a row of another commit is run again
    from agents.lorr.round import code_version, machine_name

    assert summary["code"] == code_version() == rows["EXAMPLE-01"]["code"] != "mixed"
    assert summary["machine"] == machine_name() and f"at commit {summary['code']}" in (out / "summary.md").read_text()
    row = json.loads((out / "EXAMPLE-01" / "run.json").read_text())
    (out / "EXAMPLE-01" / "run.json").write_text(json.dumps({**row, "code": "another"}))
    stamp2 = (out / "EXAMPLE-02" / "output.json").stat().st_mtime_ns
    third = _mrmt(*args, "--steps", "30", "--resume")
    assert third.returncode == 0, third.stderr
    assert (out / "EXAMPLE-01" / "output.json").stat().st_mtime_ns != stamp
    assert (out / "EXAMPLE-02" / "output.json").stat().st_mtime_ns == stamp2
    assert json.loads((out / "EXAMPLE-01" / "run.json").read_text())["code"] == code_version()
    # a row whose output file is not kept stays; one whose output file changed is run again
    (out / "EXAMPLE-02" / "output.json").unlink()
    (out / "EXAMPLE-01" / "output.json").write_text("{}")
    stamp2 = (out / "EXAMPLE-02" / "run.json").stat().st_mtime_ns
    fourth = _mrmt(*args, "--steps", "30", "--resume")
    assert fourth.returncode == 0, fourth.stderr
    assert (out / "EXAMPLE-02" / "run.json").stat().st_mtime_ns == stamp2 and not (out / "EXAMPLE-02" / "output.json").exists()
    import hashlib

    rerun = json.loads((out / "EXAMPLE-01" / "run.json").read_text())  # run again: its record names its new file
    assert rerun["output_sha1"] == hashlib.sha1((out / "EXAMPLE-01" / "output.json").read_bytes()).hexdigest()


def test_round_folders_and_best_known_tables(tmp_path):
    folder, best, _ = _round_folder(tmp_path)
    assert [p.stem for p in round_instances(folder)] == ["EXAMPLE-01", "EXAMPLE-02"]
    table = best_known_table()
    assert table["RANDOM-04"] == (700, 1000, 2585) and table["MR23-I-04"].tasks == 1741
    assert len(table) == 30  # 2023 and 2024, main (10 each) and test (5 each) rounds
    (tmp_path / "bad.json").write_text('{"r": {"X": [1, 2]}}')
    with pytest.raises(ValueError, match="r/X must be \\[agents, steps, tasks\\]"):
        best_known_table(tmp_path / "bad.json")
    proc = _mrmt("lorr", "round", str(tmp_path / "nowhere"), "--out", str(tmp_path / "o"))
    assert proc.returncode == 2 and "nowhere: no such round folder" in proc.stderr
    # an instance with no simulation time anywhere needs --steps, said before anything runs
    (folder / "simulation_time.json").unlink()
    (tmp_path / "one.json").write_text(json.dumps({"test": {"EXAMPLE-01": [8, 40, 20]}}))
    proc = _mrmt("lorr", "round", str(folder), "--out", str(tmp_path / "o"), "--best-known", str(tmp_path / "one.json"))
    assert proc.returncode == 2 and "EXAMPLE-02.json: no simulation time" in proc.stderr
    assert "give --steps" in proc.stderr
    assert not (tmp_path / "o").exists()


def test_a_round_on_ray_gives_the_local_round(tmp_path):
    """Work-bounded (``--step-limit none``): the same tasks, errands and output files on Ray as in local processes."""
    pytest.importorskip("ray")
    folder, best, entry = _round_folder(tmp_path)
    base = ["lorr", "round", str(folder), "--entry", str(entry), "--best-known", str(best), "--steps", "25",
            "--step-limit", "none", "--no-progress"]
    local = _mrmt(*base, "--out", str(tmp_path / "local"))
    ray = _mrmt(*base, "--out", str(tmp_path / "ray"), "--backend", "ray", "--jobs", "2")
    assert local.returncode == 0 and ray.returncode == 0, local.stderr + ray.stderr
    for name in ("EXAMPLE-01", "EXAMPLE-02"):
        a, b = (json.loads((tmp_path / d / name / "output.json").read_text()) for d in ("local", "ray"))
        assert a["actualPaths"] == b["actualPaths"] and a["events"] == b["events"]
        assert json.loads((tmp_path / "ray" / name / "run.json").read_text())["clock"] == "work-bounded"


def test_the_greedy_scheduler_under_a_clock_stops_where_the_start_kits_would():
    """Without a deadline the greedy is bounded by its work budget (every free robot here); with one already
    passed it still measures the first 64 task lines and assigns the first 16 robots, then stops."""
    from pathlib import Path

    from mrmt_env.lorr.greedy import GreedyScheduler
    from mrmt_env.lorr.sim import LoRRSimulator

    shared = Path(__file__).resolve().parents[2] / "shared" / "lorr" / "2024-main" / "random.domain" / "RANDOM-01.json"
    if not shared.is_file():
        pytest.skip("the LoRR instances (shared/lorr) are not beside the checkout")
    inst = read_instance(shared)
    free = GreedyScheduler().schedule(LoRRSimulator(inst))
    assert (free >= 0).sum() == 100
    late = GreedyScheduler().schedule(LoRRSimulator(inst), deadline=time.perf_counter() - 1.0)
    assert 0 < (late >= 0).sum() <= 16 and set(np.flatnonzero(late >= 0).tolist()) <= set(range(16))
    later = GreedyScheduler()
    sim = LoRRSimulator(inst)
    first = later.schedule(sim, deadline=time.perf_counter() + 60.0)  # time enough: the same as work-bounded
    assert np.array_equal(first, free)


def test_a_bad_scheduler_option_is_named_not_called_an_unknown_scheduler():
    from agents.lorr.schedulers import make_scheduler

    with pytest.raises(ValueError, match=r"^group_size = 0 must be an integer in \[1, 1048576\]$"):
        make_scheduler("strong", group_size=0)
    with pytest.raises(ValueError, match="^unknown scheduler 'warp'; known: lorr-greedy"):
        make_scheduler("warp")
    with pytest.raises(ValueError, match="unknown scheduler 'ssa\\+warp'.*unknown tour planner 'warp'"):
        make_scheduler("ssa+warp")
