"""The start kit's Python track: the package's scheduler and planner run inside the kit's step through
``agents.lorr.startkit`` (here against a stand-in of the kit's C++ side, ``tests/startkit_standin.py``) make
the same run as the package's own runner."""

from __future__ import annotations

import datetime
import importlib
import json
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from agents.lorr.entry import EntryError, load_entry
from mrmt_env.lorr.output import output_dict
from agents.lorr.run import run_lorr
from agents.lorr.startkit import TRACK_DIR, TRACK_DIR_2026, KitInstance, KitPlanner, KitPlanner2026, KitScheduler, \
    deadline_of
from mrmt_env.lorr.instance import example_instance_path, read_instance
from startkit_standin import SharedEnvironment, SharedEnvironment2026, run_standin

SHARED = Path(__file__).resolve().parents[2] / "shared" / "lorr"


def _entry(tmp_path, scheduler: str, planner: str, **decisions) -> Path:
    lines = ['name = "one"', "[[rule]]", f'scheduler = "{scheduler}"', f'planner = "{planner}"']
    for key, into in (("replan", "scheduler_options"), ("guidance", "planner_options")):  # their tables' own
        if key in decisions:
            decisions[into] = {key: decisions.pop(key), **decisions.get(into, {})}
    for key, value in decisions.items():
        if isinstance(value, dict):
            value = "{ " + ", ".join(f"{k} = {json.dumps(v)}" for k, v in value.items()) + " }"
        else:
            value = json.dumps(value)
        lines.append(f"{key} = {value}")
    path = tmp_path / "one.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


def _digest(sim) -> tuple:
    out = output_dict(sim)
    return sim.finished, out["actualPaths"], out["events"], out["numTaskFinished"]


@pytest.mark.parametrize("scheduler, planner, decisions", [
    ("lorr-greedy", "pibt", {}),
    ("lorr-weighted", "pibt", {"guidance": 0}),
    ("strong", "epibt", {"replan": True, "planner_options": {"portfolio": 2, "weight_power": 2}}),
    ("lorr-greedy", "epibt", {"planner_options": {"active": 0.5, "active_by": "task"}}),  # the kit's tasks' rest
])
def test_the_kit_runs_the_packages_roles_as_the_runner_does(tmp_path, scheduler, planner, decisions):
    """Through the kit's fields alone (its task pool in no order, its goal locations from the proposal), the
    adapter's roles make the runner's run: the same paths, task events and tasks finished."""
    inst = read_instance(example_instance_path())
    entry = _entry(tmp_path, scheduler, planner, **decisions)
    choice = load_entry(entry).choose(inst)
    sim = run_standin(inst, 40, KitScheduler, KitPlanner, entry=str(entry), seed=3)
    record, own, _ = run_lorr(inst, choice.scheduler, choice.planner, steps=40, seed=3)
    assert _digest(sim) == _digest(own)
    assert sim.finished == record["tasks_finished"] > 0 and not sim.tasks.schedule_errors


@pytest.mark.skipif(not (SHARED / "2024-main").is_dir(), reason="the LoRR instances (shared/lorr) are not beside the checkout")
def test_the_default_entry_inside_the_kit_on_a_round_instance():
    """RANDOM-01 (400 robots) under the default entry through the kit's fields: the runner's run."""
    inst = read_instance(SHARED / "2024-main" / "random.domain" / "RANDOM-01.json")
    choice = load_entry("default").choose(inst)
    sim = run_standin(inst, 15, KitScheduler, KitPlanner, entry="default")
    _record, own, _ = run_lorr(inst, choice.scheduler, choice.planner, steps=15)
    assert _digest(sim) == _digest(own)


def test_the_kit_instance_is_what_the_entry_reads():
    """The map (1 = blocked), team, map name and open-task target as the kit shows them choose what the
    package's own reading of the instance chooses."""
    from mrmt_env.lorr.sim import LoRRSimulator

    inst = read_instance(example_instance_path())
    env = SharedEnvironment(inst)
    env.sync(LoRRSimulator(inst))
    kit = KitInstance(env)
    assert np.array_equal(kit.grid, inst.grid) and kit.team_size == inst.team_size
    assert kit.map_name == inst.map_name and kit.open_target() == inst.open_target()
    assert load_entry("default").choose(kit) == load_entry("default").choose(inst)


def test_the_deadline_is_the_kits_time_limit_from_its_plan_start():
    env = SharedEnvironment(read_instance(example_instance_path()))
    env.plan_start_time = env.plan_current_time() - datetime.timedelta(milliseconds=200)
    left = deadline_of(env, 700) - time.perf_counter()
    assert 0.45 < left <= 0.5


def test_the_track_folder_holds_the_modules_the_kit_imports(monkeypatch):
    """The kit imports ``pyMAPFPlanner`` and ``pyTaskScheduler`` from its ``python_path`` and builds the classes
    of the same names with the env."""
    monkeypatch.syspath_prepend(str(TRACK_DIR))
    for module, cls in (("pyMAPFPlanner", KitPlanner), ("pyTaskScheduler", KitScheduler)):
        sys.modules.pop(module, None)
        assert getattr(importlib.import_module(module), module) is cls


def test_an_unknown_entry_is_named_at_initialize(monkeypatch):
    monkeypatch.setenv("MRMT_LORR_ENTRY", "no-such-entry")
    env = SharedEnvironment(read_instance(example_instance_path()))
    with pytest.raises(EntryError, match="no-such-entry"):
        KitPlanner(env).initialize(30_000)


def test_the_startkit_command_prints_the_kits_python_path(capsys):
    from agents.cli import main

    assert main(["lorr", "startkit"]) == 0
    first = capsys.readouterr().out.splitlines()[0]
    assert json.loads(first.split(": ", 1)[1]) == {"python_path": str(TRACK_DIR)}


@pytest.mark.parametrize("scheduler, planner, decisions", [
    ("lorr-greedy", "pibt", {}),
    ("strong", "epibt", {"replan": True, "planner_options": {"portfolio": 2, "weight_power": 2}}),
    ("lorr-greedy", "epibt", {"planner_options": {"active": 0.5, "active_by": "task"}}),
])
def test_the_2026_kit_runs_the_one_step_planner_as_the_runner_does(tmp_path, scheduler, planner, decisions):
    """The 2026 kit's form (roles built bare, the env set before ``initialize``, no plan start on its clock, a
    planning snapshot whose ``curr_timestep`` stays 0, a window of actions per robot): executed one action a
    tick, the adapter's roles make the runner's run."""
    inst = read_instance(example_instance_path())
    entry = _entry(tmp_path, scheduler, planner, **decisions)
    choice = load_entry(entry).choose(inst)
    sim = run_standin(inst, 40, KitScheduler, KitPlanner2026, kit=2026, entry=str(entry), seed=3)
    record, own, _ = run_lorr(inst, choice.scheduler, choice.planner, steps=40, seed=3)
    assert _digest(sim) == _digest(own) and sim.finished == record["tasks_finished"] > 0


def test_without_the_kits_plan_start_the_deadline_runs_from_the_call():
    env = SharedEnvironment2026(read_instance(example_instance_path()))
    before = time.perf_counter()
    deadline = deadline_of(env, 700)
    assert before + 0.7 <= deadline <= time.perf_counter() + 0.7


def test_the_2026_track_folder_holds_the_modules_the_kit_imports(monkeypatch):
    monkeypatch.syspath_prepend(str(TRACK_DIR_2026))
    for module, cls in (("pyMAPFPlanner", KitPlanner2026), ("pyTaskScheduler", KitScheduler)):
        sys.modules.pop(module, None)
        assert getattr(importlib.import_module(module), module) is cls
    sys.modules.pop("pyMAPFPlanner", None)
    sys.modules.pop("pyTaskScheduler", None)


def test_the_startkit_command_names_the_2026_files(capsys):
    from agents.cli import main

    assert main(["lorr", "startkit", "--kit", "2026"]) == 0
    out = capsys.readouterr().out
    assert f"cp {TRACK_DIR_2026}/pyMAPFPlanner.py python/user_planner/" in out and "--plannerPython true" in out
    with pytest.raises(SystemExit) as exit_:
        main(["lorr", "startkit", "--kit", "2025"])
    assert exit_.value.code == 2


@pytest.mark.parametrize("scheduler, planner", [("lorr-greedy", "pibt"), ("lorr-weighted", "epibt")])
def test_the_2026_window_covers_the_ticks_to_the_next_call_and_its_moves_are_valid(tmp_path, scheduler, planner):
    """Where the kit calls every 5 ticks the planner returns 6 actions a robot (the kit's executor's window), rolled
    out on the rules' moves: executed a tick at a time until the next call they collide nowhere, and robots finish
    errands inside a window."""
    inst = read_instance(example_instance_path())
    entry = _entry(tmp_path, scheduler, planner)
    sim = run_standin(inst, 60, KitScheduler, KitPlanner2026, kit=2026, window_ticks=5, entry=str(entry), seed=1)
    assert sim.t == 60 and len(sim.errors) == 0 and len(sim.tasks.schedule_errors) == 0
    ticks = [t for t, *_ in sim.tasks.events]
    assert sim.finished > 0 and any(t % 5 not in (0, 1) for t in ticks)


def test_the_2026_window_is_read_from_the_kit_or_set(monkeypatch):
    planner = KitPlanner2026()
    planner.env = SharedEnvironment2026(read_instance(example_instance_path()))
    assert planner.window() == 1  # the kit shows no rhythm: one action
    planner.env = SharedEnvironment2026(read_instance(example_instance_path()), window_ticks=10)
    assert planner.window() == 11  # the ticks to the next call and one more, as the kit's executor stages
    planner.env.max_counter = 3  # an action takes 3 ticks
    assert planner.window() == 1000 // 300 + 1
    monkeypatch.setenv("MRMT_LORR_WINDOW", "7")
    assert planner.window() == 7
    monkeypatch.setenv("MRMT_LORR_WINDOW", "0")
    with pytest.raises(ValueError, match="MRMT_LORR_WINDOW = '0' must be an integer in 1..100"):
        planner.window()
