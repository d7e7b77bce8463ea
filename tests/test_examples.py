"""Every example runs as a script (small sizes via argv)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"


def run_example(name: str, *args: str) -> str:
    env = dict(os.environ, PYTHONPATH=str(ROOT), MPLBACKEND="Agg")
    proc = subprocess.run(
        [sys.executable, str(EXAMPLES / name), *args],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=300,
    )
    assert proc.returncode == 0, f"{name} failed ({proc.returncode}):\n{proc.stdout[-2000:]}\n{proc.stderr[-4000:]}"
    return proc.stdout


def test_every_example_is_tested():
    tested = {"quickstart.py", "planner_vs_ppo.py", "custom_chip.py", "movingai_map.py", "watch_episode.py",
              "map_families.py", "socket_chip.py", "lifelong_warehouse.py", "lorr_instance.py",
              "lorr_own_planner.py"}
    assert {p.name for p in EXAMPLES.glob("*.py")} == tested


def test_lorr_own_planner():
    out = run_example("lorr_own_planner.py")
    assert "EXAMPLE-01, 100 steps: forward" in out and "(0 errors)" in out


def test_quickstart_ising():
    out = run_example("quickstart.py", "--seed", "1")
    assert "pipeline ising: success=True" in out
    assert "chip calls" in out and "accelerator energy" in out


def test_socket_chip():
    out = run_example("socket_chip.py")
    assert "plan valid: True" in out and "chip calls" in out


def test_movingai_map():
    out = run_example("movingai_map.py", "--robots", "2", "--targets", "5")
    assert "12x16 map, 2 robots, 5 targets" in out and "success=True" in out


def test_map_families(tmp_path):
    out = run_example("map_families.py", "--size", "24", "--robots", "3", "--targets", "10", "--worlds", "1",
                      "--export", str(tmp_path), "--png", str(tmp_path / "maps.png"))
    for family in ("uniform", "warehouse", "rooms", "maze"):
        assert any(line.startswith(family) and line.endswith("1/1") for line in out.splitlines()), out
    data = ROOT / "examples" / "data"
    for name in ("warehouse_32x32", "rooms_24x24", "maze_31x31"):  # the shipped maps are what --export writes
        for ext in (".map", ".scen"):
            assert (tmp_path / (name + ext)).read_text() == (data / (name + ext)).read_text()
    assert (tmp_path / "maps.png").stat().st_size > 0


def test_custom_chip():
    out = run_example("custom_chip.py", "--worlds", "1", "--jobs", "1")
    assert "ising, default chip" in out and "ising, custom chip" in out
    assert "100 spins" in out


def test_planner_vs_ppo():
    pytest.importorskip("stable_baselines3")
    out = run_example("planner_vs_ppo.py", "--timesteps", "128", "--worlds", "2", "--jobs", "1")
    assert "strong" in out and "ising" in out and "ppo_small.zip" in out


def test_watch_episode(tmp_path):
    pytest.importorskip("sb3_contrib")
    pytest.importorskip("imageio")
    out = run_example("watch_episode.py", "--timesteps", "256", "--out", str(tmp_path))
    assert "strong: route cost" in out and "learned: route cost" in out
    assert (tmp_path / "strong.gif").stat().st_size > 0 and (tmp_path / "learned.gif").stat().st_size > 0


def test_watch_episode_writes_nothing_into_the_working_tree_by_default():
    pytest.importorskip("sb3_contrib")
    pytest.importorskip("imageio")
    import shutil
    import tempfile

    out = run_example("watch_episode.py", "--timesteps", "64")
    gifs = [Path(line.rsplit("-> ", 1)[1]) for line in out.splitlines() if "-> " in line]
    assert len(gifs) == 2 and all(g.stat().st_size > 0 for g in gifs)
    assert all(g.resolve().is_relative_to(Path(tempfile.gettempdir()).resolve()) for g in gifs), gifs
    shutil.rmtree(gifs[0].parent)


def test_lifelong_warehouse():
    out = run_example("lifelong_warehouse.py", "--robots", "6", "--steps", "20", "--size", "16")
    assert out.count("conflicts 0, blocked 0") == 3 and " ising: " in out


def test_lorr_instance(tmp_path):
    import json

    out = run_example("lorr_instance.py", "--steps", "80", "--out", str(tmp_path / "output.json"))
    assert "EXAMPLE-01:" in out and "0 invalid joint actions" in out
    finished = int(out.split("EXAMPLE-01: ")[1].split(" tasks")[0])
    data = json.loads((tmp_path / "output.json").read_text())
    assert data["numTaskFinished"] == finished > 0 and len(data["actualPaths"][0].split(",")) == 80
