"""League of Robot Runners: exact values pinned where a plausible mistake passed the other tests.

Each test fails under one such mistake: the entry's fill counted over every cell (not the free ones), a late
preprocessing never marked (seconds compared with milliseconds) or still scored by the round, the clock charging only
the planner's seconds (not the scheduler's), the open-task count computed in float64 (the start kit's product is a
float32), the 2023 round layout (instance files at the top of the folder) dropped, and a corrupted output's first
invalid step reported anywhere else.
"""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import numpy as np
import pytest

import agents.lorr.round as round_mod
import agents.lorr.run as run_mod
from agents.lorr.entry import Rule, load_entry
from agents.lorr.round import BestKnown, round_instances, round_task, run_round
from agents.lorr.run import run_lorr
from mrmt_env.lorr.clock import StepLimit
from mrmt_env.lorr.instance import example_instance_path, read_instance
from mrmt_env.lorr.output import check_output, output_dict
from mrmt_env.lorr.sim import LoRRSimulator
from planners.compute import ComputeReport

EXAMPLE = example_instance_path()
SHARED = Path(__file__).resolve().parents[2] / "shared" / "lorr"
RANDOM = SHARED / "2024-main" / "random.domain"
needs_random = pytest.mark.skipif(not RANDOM.is_dir(), reason="the LoRR instances (shared/lorr) are not beside the "
                                                              "checkout")


def _free_cells(map_path: Path) -> int:
    """Free cells of a MovingAI map counted from its text: every letter but ``@`` and ``T`` after the ``map`` line."""
    lines = map_path.read_text().splitlines()
    rows = lines[lines.index("map") + 1:]
    return sum(1 for row in rows for ch in row.strip() if ch not in "@T")


def _capture_fill(monkeypatch) -> list:
    """Every ``(robots, fill, cells, corridors)`` an entry's rules are asked about."""
    seen = []
    real = Rule.holds

    def holds(self, shape):
        seen.append((shape.robots, shape.fill, shape.cells, shape.corridors))
        return real(self, shape)

    monkeypatch.setattr(Rule, "holds", holds)
    return seen


# ---------------------------------------------------------------- the entry's fill: robots per free cell
@needs_random
def test_the_default_entry_gives_each_random_instance_its_rule(monkeypatch):
    """random-32-32-20 has 819 free cells of 1,024: robots per free cell 0.122, 0.244, 0.488, 0.855, 0.977 pick rules
    4, 4, 3 (min_fill 0.4), 2 (min_fill 0.8), 2 (rule 1 is the dense mazes').  Over all 1,024 cells RANDOM-04 (0.684) and
    RANDOM-05 (0.781) would both fall to rule 3."""
    entry = load_entry("default")
    seen = _capture_fill(monkeypatch)
    rules, fills, teams = {}, {}, {}
    for i in range(1, 6):
        inst = read_instance(RANDOM / f"RANDOM-0{i}.json")
        assert _free_cells(RANDOM / "maps" / inst.map_name) == 819
        seen.clear()
        rules[inst.name] = entry.choose(inst).rule
        fills[inst.name], teams[inst.name] = {s[1] for s in seen}, inst.team_size
    assert rules == {"RANDOM-01": 4, "RANDOM-02": 4, "RANDOM-03": 3, "RANDOM-04": 2, "RANDOM-05": 2}
    assert teams == {"RANDOM-01": 100, "RANDOM-02": 200, "RANDOM-03": 400, "RANDOM-04": 700, "RANDOM-05": 800}
    assert fills == {name: {team / 819} for name, team in teams.items()}


def test_the_fill_is_robots_per_free_cell_on_a_small_map(tmp_path, monkeypatch):
    """A 3 x 4 map with 2 blocked cells (10 free of 12) and 4 robots: fill 4 / 10 = 0.4 exactly (over every cell it
    would be 1 / 3); an entry whose first rule asks for exactly 0.4 chooses it."""
    (tmp_path / "s.map").write_text("type octile\nheight 3\nwidth 4\nmap\n..@.\n....\n.T..\n")
    (tmp_path / "s.agents").write_text("4\n0\n1\n4\n5\n")
    (tmp_path / "s.tasks").write_text("1\n6\n")
    (tmp_path / "SMALL.json").write_text(json.dumps({"mapFile": "s.map", "agentFile": "s.agents", "teamSize": 4,
                                                     "taskFile": "s.tasks", "numTasksReveal": 1}))
    (tmp_path / "e.toml").write_text('name = "exact"\n[[rule]]\nmin_fill = 0.4\nmax_fill = 0.4\nscheduler = "strong"\n'
                                     'planner = "pibt"\n[[rule]]\nscheduler = "lorr-greedy"\nplanner = "pibt"\n')
    inst = read_instance(tmp_path / "SMALL.json")
    assert _free_cells(tmp_path / "s.map") == 10
    seen = _capture_fill(monkeypatch)
    choice = load_entry(tmp_path / "e.toml").choose(inst)
    assert seen == [(4, 0.4, 12, 0.0)]
    assert (choice.rule, choice.scheduler.name) == (1, "strong")


# ---------------------------------------------------------------- preprocessing: its own limit
def _slow_preprocessing(monkeypatch, seconds: float, names=None) -> None:
    """Building the simulator (part of the timed preprocessing) takes ``seconds`` more on the instances ``names``
    (every one when ``None``)."""
    real = run_mod.LoRRSimulator

    def slow(inst, *args, **kwargs):
        if names is None or inst.name in names:
            time.sleep(seconds)
        return real(inst, *args, **kwargs)

    monkeypatch.setattr(run_mod, "LoRRSimulator", slow)


def test_a_late_preprocessing_is_marked_and_one_in_time_is_not(monkeypatch):
    """Preprocessing of at least 0.05 s: late against 0.01 s (and would not be with the limit read as milliseconds,
    10 s), in time against the rules' 30 s (and would not be with the seconds read as milliseconds, 50 ms > 30)."""
    _slow_preprocessing(monkeypatch, 0.05)
    late, _, _ = run_lorr(EXAMPLE, "lorr-greedy", "pibt", steps=5, seed=0, limit=StepLimit(60.0, 0.01))
    fine, _, _ = run_lorr(EXAMPLE, "lorr-greedy", "pibt", steps=5, seed=0, limit=StepLimit(60.0))
    assert late["preprocess_s"] >= 0.05 and fine["preprocess_s"] >= 0.05
    assert late["preprocess_timeout"] is True and fine["preprocess_timeout"] is False
    free, _, _ = run_lorr(EXAMPLE, "lorr-greedy", "pibt", steps=5, seed=0)
    assert free["preprocess_timeout"] is False  # work-bounded: no limit to be late for


def _two_instance_round(tmp_path) -> tuple[Path, object]:
    domain = tmp_path / "round" / "random.domain"
    domain.mkdir(parents=True)
    for f in EXAMPLE.parent.iterdir():
        if f.name != "simulation_time.json":
            shutil.copy(f, domain / f.name)
    shutil.copy(domain / "EXAMPLE-01.json", domain / "EXAMPLE-02.json")
    (tmp_path / "round" / "simulation_time.json").write_text('{"EXAMPLE-01": 40, "EXAMPLE-02": 40}')
    (tmp_path / "greedy.toml").write_text('name = "greedy"\n[[rule]]\nscheduler = "lorr-greedy"\nplanner = "pibt"\n')
    return tmp_path / "round", load_entry(tmp_path / "greedy.toml")


def test_a_round_scores_an_instance_with_late_preprocessing_zero(tmp_path, monkeypatch):
    """EXAMPLE-02's preprocessing takes 0.6 s more, past the limit of 0.5 s; EXAMPLE-01's is in time.  Both run 20 of
    their 40 steps against a best-known of 20 tasks (pro rata 10): EXAMPLE-02's share is shown but scored 0, and the
    round's score is EXAMPLE-01's share alone."""
    folder, entry = _two_instance_round(tmp_path)
    _slow_preprocessing(monkeypatch, 0.6, names={"EXAMPLE-02"})
    monkeypatch.setattr(round_mod, "_fresh_processes", lambda tasks, jobs, progress: [round_task(*t) for t in tasks])
    best = {"EXAMPLE-01": BestKnown(8, 40, 20), "EXAMPLE-02": BestKnown(8, 40, 20)}
    summary = run_round(folder, entry, tmp_path / "out", steps=20, limit=StepLimit(60.0, 0.5), best=best,
                        progress=False)
    on_time, late = summary.rows
    assert (on_time["instance"], late["instance"]) == ("EXAMPLE-01", "EXAMPLE-02")
    assert (on_time["preprocess_timeout"], late["preprocess_timeout"]) == (False, True)
    assert late["tasks_finished"] > 0  # a share that a round scoring late preprocessing would add
    assert late["share_of_best"] == late["tasks_finished"] / 10 and late["scored_share"] == 0.0
    assert on_time["scored_share"] == on_time["share_of_best"] == on_time["tasks_finished"] / 10
    assert (summary.score, summary.scored, summary.instances) == (on_time["tasks_finished"] / 10, 2, 2)
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["score"] == on_time["tasks_finished"] / 10
    assert "(preprocessing late: 0)" in [line for line in (tmp_path / "out" / "summary.md").read_text().splitlines()
                                         if line.startswith("| EXAMPLE-02")][0]


# ---------------------------------------------------------------- the clock: scheduler and planner together
class _SleepyScheduler:
    """A scheduler that spends ``seconds`` per decision under a clock (none work-bounded) and changes nothing."""

    name = "sleepy"
    accelerated = False

    def __init__(self, seconds: float) -> None:
        self.seconds = seconds
        self.last_compute = ComputeReport()

    def reset(self, sim) -> None:
        self.last_compute = ComputeReport()

    def schedule(self, sim, deadline=None):
        if deadline is not None:
            time.sleep(self.seconds)
        return sim.tasks.assigned.copy()


def test_the_schedulers_seconds_count_against_the_step_limit(monkeypatch):
    """A scheduler sleeping 0.21 s per decision beside a fast planner under 0.1 s per step: the run's timeouts are
    exactly the clock's rule (:meth:`StepLimit.timeouts`) over the measured decisions, the last cut at the end."""
    limit, steps = StepLimit(0.1), 20  # the scheduler is a user's own object, run as it is
    record, sim, step_s = run_lorr(EXAMPLE, _SleepyScheduler(0.21), "pibt", steps=steps, seed=0, limit=limit)
    assert len(step_s) == record["decisions"] and all(d >= 0.21 for d in step_s)  # each holds the sleep
    t = timeouts = 0
    for d in step_s:  # the start kit's loop: a decision's timeouts (none past the end), then its step
        late = min(limit.timeouts(float(d)), steps - t)
        timeouts, t = timeouts + late, t + late
        if t < steps:
            t += 1
    assert t == sim.t == steps
    assert record["timeouts"] == sim.timeouts == timeouts
    assert record["scheduler_p99_s"] >= 0.21


# ---------------------------------------------------------------- the open tasks: a float32 product, truncated
@pytest.mark.parametrize("reveal, kit, wide", [(0.7, 63, 62), (1.3, 116, 117)])
def test_open_tasks_are_the_float32_product_where_float64_truncates_elsewhere(tmp_path, reveal, kit, wide):
    """90 robots.  float32(0.7) = 0.699999988079071, x 90 = 62.9999989..., whose nearest float32 is 63.0: 63 open
    (float64: 0.7 x 90 = 62.99999999999999, 62).  float32(1.3) = 1.2999999523162842, x 90 = 116.9999957...,
    whose nearest float32 is 116.99999237060547: 116 open (float64: 1.3 x 90 = 117.0, 117)."""
    assert int(reveal * 90) == wide  # the float64 product truncates to the other side
    (tmp_path / "o.map").write_text("type octile\nheight 10\nwidth 10\nmap\n" + "..........\n" * 10)
    (tmp_path / "o.agents").write_text("90\n" + "".join(f"{a}\n" for a in range(90)))
    (tmp_path / "o.tasks").write_text("3\n95\n97\n99\n")
    (tmp_path / "OPEN.json").write_text(json.dumps({"mapFile": "o.map", "agentFile": "o.agents", "teamSize": 90,
                                                    "taskFile": "o.tasks", "numTasksReveal": reveal}))
    inst = read_instance(tmp_path / "OPEN.json")
    assert inst.open_target() == kit
    sim = LoRRSimulator(inst)
    assert sim.tasks.target == len(sim.tasks.open) == kit


# ---------------------------------------------------------------- round folders: both archive layouts
def _instance_file(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"mapFile": "m.map", "agentFile": "a", "teamSize": 1, "taskFile": "t"}))
    return path


def test_round_folders_in_the_2023_and_2024_layouts_and_mixed(tmp_path):
    top = tmp_path / "2023"  # instance files at the top of the folder
    expect_top = [_instance_file(top / f"{n}.json") for n in ("MR23-I-01", "MR23-I-04")]
    (top / "simulation_time.json").write_text('{"MR23-I-01": 500}')  # JSON, but no instance
    assert round_instances(top) == expect_top
    nested = tmp_path / "2024"  # <domain>/<NAME>.json
    b = _instance_file(nested / "random.domain" / "RANDOM-01.json")
    a = _instance_file(nested / "city.domain" / "CITY-01.json")
    (nested / "best_known.json").write_text('{"x": {}}')
    assert round_instances(nested) == [a, b]
    mixed = tmp_path / "mixed"  # files at the top beside sub-folders of them: all, by name
    m1 = _instance_file(mixed / "B-01.json")
    m2 = _instance_file(mixed / "dom" / "A-01.json")
    m3 = _instance_file(mixed / "dom" / "C-01.json")
    _instance_file(mixed / "dom" / "deeper" / "D-01.json")  # two folders down: not a round's layout
    assert round_instances(mixed) == [m2, m1, m3]


# ---------------------------------------------------------------- the check: the first invalid step
def _facing_wall(grid: np.ndarray, cell: int, orient: int) -> bool:
    h, w = grid.shape
    r, c = divmod(cell, w)
    dr, dc = ((0, 1), (1, 0), (0, -1), (-1, 0))[orient]  # east, south, west, north
    r, c = r + dr, c + dc
    return not (0 <= r < h and 0 <= c < w) or bool(grid[r, c])


def test_a_corrupted_output_reports_its_first_invalid_step(tmp_path):
    """A clean run's file re-checks with no error; one robot's action at a known step turned into F into a wall or off
    the map makes that step (counted from 1) the first error the check reports."""
    _, sim, step_s = run_lorr(EXAMPLE, "lorr-greedy", "pibt", steps=60, seed=0)
    data = json.loads(json.dumps(output_dict(sim, step_s)))
    inst = read_instance(EXAMPLE)
    clean = check_output(inst, data)
    assert (clean.errors, clean.first_error_step) == (0, None)
    # replay the clean file to step 12 onwards and find a robot facing a wall or the map's edge
    paths = [p.split(",") for p in data["plannerPaths"]]
    replay = LoRRSimulator(inst, record=False)
    for t in range(60):
        faced = [k for k in range(inst.team_size)
                 if _facing_wall(inst.grid, int(replay.pos[k]), int(replay.orient[k])) and paths[k][t] != "F"]
        if t >= 12 and faced:
            break
        replay.step(np.array(["FRCW".index(p[t]) for p in paths]))
    else:
        pytest.fail("no robot faces a wall in the run")
    paths[faced[0]][t] = "F"
    bad = dict(data, plannerPaths=[",".join(p) for p in paths])
    result = check_output(inst, bad)
    assert result.first_error_step == t + 1 and result.errors >= 1
    assert result.to_json()["firstErrorStep"] == t + 1
