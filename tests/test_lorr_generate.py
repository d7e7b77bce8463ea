"""``mrmt lorr generate`` and :mod:`mrmt_env.lorr.generate`; ``lorr run`` / ``round`` steps and shares alike."""

import ast
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from agents.cli import main
from mrmt_env.lorr.generate import GenerateError, default_tasks, generate_instance
from mrmt_env.lorr.instance import example_instance_path, read_instance, read_lorr_map
from mrmt_env.maps import build_layout

# 4 x 5: a wall column splits 12 free cells (left) from 4 (right); T is blocked for both readers
TINY = "type octile\nheight 4\nwidth 5\nmap\n...@.\n...T.\n...@.\n...@.\n"
LEFT = {r * 5 + c for r in range(4) for c in range(3)}


def _tiny(tmp_path) -> Path:
    path = tmp_path / "tiny.map"
    path.write_text(TINY)
    return path


def _bytes(files) -> list[bytes]:
    return [Path(f).read_bytes() for f in files]


def _mrmt(*args, timeout=300):
    return subprocess.run([sys.executable, "-m", "agents.cli", *args], capture_output=True, text=True, timeout=timeout)


def test_a_tiny_map_gives_an_instance_that_reads_back(tmp_path):
    files = generate_instance(_tiny(tmp_path), 5, tmp_path / "out" / "TINY-01.json", seed=3, tasks=40)
    out = tmp_path / "out"
    assert files == (out / "TINY-01.json", out / "maps" / "TINY-01.map", out / "agents" / "TINY-01.agents",
                     out / "tasks" / "TINY-01.tasks")
    assert json.loads(files.instance.read_text()) == {
        "mapFile": "maps/TINY-01.map", "agentFile": "agents/TINY-01.agents", "teamSize": 5,
        "taskFile": "tasks/TINY-01.tasks", "numTasksReveal": 1.5, "version": "2024 LoRR"}
    inst = read_instance(files.instance)
    assert (inst.name, inst.team_size, inst.n_tasks, inst.reveal, inst.steps) == ("TINY-01", 5, 40, 1.5, None)
    assert np.array_equal(inst.grid, read_lorr_map(_tiny(tmp_path)))
    assert files.map.read_text() == TINY.replace("T", "@")
    assert len(set(inst.starts.tolist())) == 5 and set(inst.starts.tolist()) <= LEFT
    assert set(inst.errands.tolist()) <= LEFT
    assert set(np.diff(inst.offsets).tolist()) <= {2, 3, 4, 5} and inst.errands.size == inst.offsets[-1]
    lines = files.agents.read_text().splitlines()
    assert lines[:2] == ["# version for LoRR 2024", "5"] and [int(x) for x in lines[2:]] == inst.starts.tolist()
    task_lines = files.tasks.read_text().splitlines()
    assert task_lines[:2] == ["# version for LoRR 2024", "40"] and len(task_lines) == 42
    assert [int(x) for x in task_lines[2].split(",")] == inst.task_errands(0).tolist()


def test_the_same_seed_writes_the_same_bytes_and_another_seed_other_starts(tmp_path):
    a = generate_instance(_tiny(tmp_path), 4, tmp_path / "a" / "X.json", seed=7, tasks=30, errands=(1, 3))
    b = generate_instance(_tiny(tmp_path), 4, tmp_path / "b" / "X.json", seed=7, tasks=30, errands=(1, 3))
    c = generate_instance(_tiny(tmp_path), 4, tmp_path / "c" / "X.json", seed=8, tasks=30, errands=(1, 3))
    assert _bytes(a) == _bytes(b)
    assert _bytes(a)[2:] != _bytes(c)[2:]
    assert set(np.diff(read_instance(a.instance).offsets).tolist()) <= {1, 2, 3}


def test_a_package_family_map_is_written_out_and_reads_back(tmp_path):
    files = generate_instance("family:warehouse:32x32", 30, tmp_path / "WH.json", seed=0, tasks=200)
    inst = read_instance(files.instance)
    want = build_layout("warehouse", np.random.default_rng(0), 32, 32).grid
    assert np.array_equal(inst.grid, want) and (inst.team_size, inst.n_tasks) == (30, 200)
    assert not inst.grid.flat[inst.starts].any() and not inst.grid.flat[inst.errands].any()
    rooms = [generate_instance("family:rooms:24x24:room_size=5", 10, tmp_path / d / "R.json", seed=2, tasks=50)
             for d in ("x", "y")]
    assert _bytes(rooms[0]) == _bytes(rooms[1])
    dense = read_instance(generate_instance("family:uniform:20x30:obstacle_density=0.3", 8, tmp_path / "U.json",
                                            seed=1, tasks=20).instance)
    assert dense.grid.shape == (20, 30) and int(dense.grid.sum()) == 180


def test_the_default_task_count_is_the_archives_or_twenty_a_robot(tmp_path):
    assert (default_tasks(1), default_tasks(5000), default_tasks(10000)) == (100_000, 100_000, 200_000)
    inst = read_instance(generate_instance(_tiny(tmp_path), 2, tmp_path / "D.json", seed=0).instance)
    assert inst.n_tasks == 100_000 and inst.reveal == 1.5


@pytest.mark.parametrize("kwargs, message", [
    ({"agents": 13}, "agents 13: the map's largest connected component has 12 free cells (at most one robot a cell)"),
    ({"agents": 0}, "agents must be an integer >= 1, got 0"),
    ({"tasks": 0}, "tasks must be an integer in [1, 10000000], got 0"),
    ({"reveal": 0.0}, "reveal (numTasksReveal) must be a number > 0, got 0.0"),
    ({"reveal": 0.1}, "reveal 0.1 x agents 2 keeps no task open (the start kit truncates the product; it must be at "
                      "least 1)"),
    ({"seed": -1}, "seed must be an integer >= 0, got -1"),
    ({"errands": (3, 2)}, "errands max must be an integer in [3, 1000], got 2"),
])
def test_bad_numbers_are_refused_naming_the_value_and_the_limit(tmp_path, kwargs, message):
    args = {"agents": 2, "tasks": 5, **kwargs}
    with pytest.raises(GenerateError) as err:
        generate_instance(_tiny(tmp_path), args.pop("agents"), tmp_path / "E.json", **args)
    assert str(err.value) == message
    assert not (tmp_path / "E.json").exists()


@pytest.mark.parametrize("argv, message", [
    (["MAP", "--agents", "13"], "--agents 13: the map's largest connected component has 12 free cells (at most one "
                                "robot a cell)"),
    (["MAP", "--agents", "0"], "--agents must be an integer >= 1, got 0"),
    (["MAP", "--agents", "2", "--tasks", "-4"], "--tasks must be an integer in [1, 10000000], got -4"),
    (["MAP", "--agents", "2", "--reveal", "-1"], "--reveal (numTasksReveal) must be a number > 0, got -1.0"),
    (["MAP", "--agents", "2", "--errands", "2-x"], "--errands '2-x': must be MIN-MAX (or one number), whole numbers "
                                                   ">= 1"),
    (["NOMAP", "--agents", "2"], "map 'NOMAP': no such map file (or give family:NAME:HxW[:KEY=VALUE,...] (NAME one "
                                 "of uniform, warehouse, rooms, maze))"),
    (["BADMAP", "--agents", "2"], "BADMAP: header says height 4 but the map has 2 rows"),
    (["family:castle:8x8", "--agents", "2"], "map 'family:castle:8x8': unknown family 'castle'; known: uniform, "
                                             "warehouse, rooms, maze"),
    (["family:rooms:8by8", "--agents", "2"], "map 'family:rooms:8by8': size '8by8' must be HxW, two integers >= 1 "
                                             "(e.g. 64x64)"),
])
def test_the_command_refuses_bad_input_with_one_line_and_exit_2(tmp_path, capsys, argv, message):
    bad = tmp_path / "bad.map"
    bad.write_text("type octile\nheight 4\nwidth 5\nmap\n.....\n.....\n")
    paths = {"MAP": str(_tiny(tmp_path)), "NOMAP": str(tmp_path / "none.map"), "BADMAP": str(bad)}
    argv = [paths.get(a, a) for a in argv]
    message = message.replace("NOMAP", paths["NOMAP"]).replace("BADMAP", paths["BADMAP"])
    assert main(["lorr", "generate", *argv, "--out", str(tmp_path / "E.json")]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err == f"mrmt lorr: error: {message}\n"


def test_lorr_run_runs_a_generated_instance_and_asks_for_steps_as_round_does(tmp_path):
    inst = tmp_path / "gen" / "G-01.json"
    assert main(["lorr", "generate", "family:warehouse:32x32", "--agents", "12", "--seed", "1", "--tasks", "300",
                 "--out", str(inst)]) == 0
    proc = _mrmt("lorr", "run", str(inst), "--steps", "20", "--no-progress", "--json")
    assert proc.returncode == 0, proc.stderr
    row = json.loads(proc.stdout)
    assert (row["instance"], row["robots"], row["steps"], row["errors"]) == ("G-01", 12, 20, 0)
    assert (row["full_steps"], row["prefix"], row["best_known"], row["share_of_best"]) == (None, True, None, None)
    want = f"mrmt lorr: error: {inst}: no simulation time (no simulation_time.json beside it, no best-known row): " \
           "give --steps\n"
    alone = _mrmt("lorr", "run", str(inst), "--no-progress")
    assert alone.returncode == 2 and alone.stderr == want
    rnd = _mrmt("lorr", "round", str(inst.parent), "--out", str(tmp_path / "r"), "--no-progress")
    assert rnd.returncode == 2 and rnd.stderr == want


def test_lorr_run_scores_a_prefix_pro_rata_and_prints_it_as_the_round_does(tmp_path):
    for f in example_instance_path().parent.iterdir():
        shutil.copy(f, tmp_path / f.name)
    (tmp_path / "simulation_time.json").write_text('{"EXAMPLE-01": 40}')
    (tmp_path / "best_known.json").write_text(json.dumps({"test": {"EXAMPLE-01": [8, 40, 20]}}))
    base = ["lorr", "run", str(tmp_path / "EXAMPLE-01.json"), "--steps", "20", "--no-progress"]
    row = json.loads(_mrmt(*base, "--json").stdout)
    assert (row["steps"], row["full_steps"], row["prefix"], row["best_known"]) == (20, 40, True, 20)
    assert row["best_known_pro_rata"] == 10.0 and row["share_of_best"] == row["tasks_finished"] / 10.0
    table = _mrmt(*base).stdout.splitlines()
    assert table[0] == "clock: work-bounded" and "timeouts" in table[1].split()
    cells = table[2].split()
    assert cells[5:8] == ["20", "of", "40"] and f"{row['share_of_best']:.1%}" in cells and "(pro" in cells


def test_the_lorr_commands_import_no_circle():
    folder = Path(__file__).resolve().parents[1] / "agents" / "commands"
    for name in ("lorr_args", "lorr_sweep", "lorr_info", "lorr_generate"):
        tree = ast.parse((folder / f"{name}.py").read_text())
        imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
        imported |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
        assert "agents.commands.lorr" not in imported, name
