"""World JSON / JSON Lines files and the MovingAI loaders (files written here)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mrmt_env import World, WorldError, generate_world
from mrmt_env.io import iter_world_lines, read_world, read_worlds, world_from_dict, world_to_dict, write_world, write_worlds
from mrmt_env.movingai import Scenario, read_movingai_map, read_movingai_scen, world_from_movingai


def test_dict_round_trip_and_format():
    w = generate_world(1)
    d = world_to_dict(w)
    assert set(d) == {"grid", "robots", "targets"}
    assert len(d["grid"]) == 10 and all(set(row) <= {".", "@"} for row in d["grid"])
    assert sum(row.count("@") for row in d["grid"]) == 20
    json.dumps(d)  # JSON-ready (plain lists and ints)
    assert world_from_dict(d) == w


def test_file_round_trip(tmp_path):
    w = generate_world(2, n_robots=2, n_targets=5)
    p = tmp_path / "w.json"
    write_world(w, p)
    assert read_world(p) == w
    assert read_worlds(p) == [w]


def test_jsonl_round_trip(tmp_path):
    worlds = [generate_world(s) for s in range(5)]
    p = tmp_path / "w.jsonl"
    write_worlds(worlds, p)
    assert len(p.read_text().splitlines()) == 5
    assert read_worlds(p) == worlds
    assert [n for n, _ in iter_world_lines(p)] == [1, 2, 3, 4, 5]


def test_movingai_letters_accepted():
    w = world_from_dict({"grid": [".GS", "@OT", "W.."], "robots": [[0, 0]], "targets": [[0, 2]]})
    assert w.grid.tolist() == [[False, False, False], [True, True, True], [True, False, False]]


@pytest.mark.parametrize(
    "d, match",
    [
        ([1, 2], "must be a JSON object"),
        ({"grid": ["..."], "robots": [[0, 0]]}, r"missing key\(s\) \['targets'\]"),
        ({"grid": ["..."], "robots": [[0, 0]], "targets": [], "x": 1}, r"unknown key\(s\) \['x'\]"),
        ({"grid": "...", "robots": [[0, 0]], "targets": []}, "grid must be a list of strings"),
        ({"grid": ["...", ".."], "robots": [[0, 0]], "targets": []}, "grid row 1 has 2 cells, row 0 has 3"),
        ({"grid": ["..x"], "robots": [[0, 0]], "targets": []}, r"row 0 col 2: unknown cell letter 'x'"),
        ({"grid": ["..."], "robots": [[0]], "targets": []}, r"'robots' entry 0 must be an integer \[row, col\] pair"),
        ({"grid": ["..."], "robots": [[0, 0]], "targets": [[0, 1.5]]}, r"'targets' entry 0"),
        ({"grid": ["..."], "robots": [[0, 0]], "targets": [[0, 5]]}, "out of bounds"),
        ({"grid": [".@."], "robots": [[0, 0]], "targets": [[0, 2]]}, "unreachable"),
        ({"grid": ["..."], "robots": [], "targets": []}, "at least one of robots"),
    ],
)
def test_malformed_dicts(d, match):
    with pytest.raises(WorldError, match=match):
        world_from_dict(d)


def test_bad_lines_are_reported_and_skippable(tmp_path):
    good = json.dumps(world_to_dict(generate_world(0)))
    p = tmp_path / "mixed.jsonl"
    p.write_text(good + "\n\n{not json\n" + json.dumps({"grid": ["."], "robots": [[0, 0]], "targets": [[0, 1]]}) + "\n" + good + "\n")
    items = list(iter_world_lines(p))
    assert [n for n, _ in items] == [1, 3, 4, 5]
    assert isinstance(items[0][1], World) and isinstance(items[3][1], World)
    assert isinstance(items[1][1], WorldError) and "line 3 column 2: not valid JSON" in str(items[1][1])
    assert isinstance(items[2][1], WorldError) and "line 4" in str(items[2][1]) and "out of bounds" in str(items[2][1])
    with pytest.raises(WorldError, match="line 3"):
        read_worlds(p)


def test_read_world_errors_name_the_file(tmp_path):
    p = tmp_path / "bad.json"
    p.write_text("{")
    with pytest.raises(WorldError, match="bad.json line 1 column 2: not valid JSON"):
        read_world(p)
    p.write_text("[]")
    with pytest.raises(WorldError, match="JSON array is not a world file"):
        read_worlds(p)


MAP = """type octile
height 4
width 5
map
..@..
.@@.T
.....
G..WS
"""

SCEN = """version 1
0\tbench.map\t5\t4\t0\t0\t4\t2\t5.41421
1\tbench.map\t5\t4\t3\t0\t0\t3\t4.5
2\tbench.map\t5\t4\t4\t3\t1\t0\t6
"""


def test_movingai_map(tmp_path):
    p = tmp_path / "bench.map"
    p.write_text(MAP)
    g = read_movingai_map(p)
    assert g.shape == (4, 5) and g.dtype == bool
    assert g.tolist() == [
        [False, False, True, False, False],
        [False, True, True, False, True],
        [False, False, False, False, False],
        [False, False, False, True, False],
    ]


@pytest.mark.parametrize(
    "text, match",
    [
        ("type octile\nheight 4\nwidth 5\n", "no 'map' line"),
        ("type octile\nheight 4\nwidth 5\n..@..\n", "line 4: bad header line '..@..'"),
        ("type octile\nwidth 5\nmap\n.....\n", "header lacks 'height'"),
        ("type octile\nheight 2\nwidth 5\nmap\n.....\n", "height 2 but the map has 1 rows"),
        ("type octile\nheight 1\nwidth 5\nmap\n....\n", "map row 0 has 4 cells, header says width 5"),
        ("type octile\nheight 1\nwidth 5\nmap\n...?.\n", "unknown cell letter '\\?'"),
    ],
)
def test_movingai_map_errors(tmp_path, text, match):
    p = tmp_path / "bad.map"
    p.write_text(text)
    with pytest.raises(WorldError, match=match):
        read_movingai_map(p)


def test_movingai_scen_and_bfs_length(tmp_path):
    (tmp_path / "bench.map").write_text(MAP)
    (tmp_path / "bench.map.scen").write_text(SCEN)
    grid = read_movingai_map(tmp_path / "bench.map")
    scen = read_movingai_scen(tmp_path / "bench.map.scen")
    assert len(scen) == 3
    s0 = scen[0]
    assert isinstance(s0, Scenario)
    assert (s0.bucket, s0.map, s0.width, s0.height) == (0, "bench.map", 5, 4)
    assert s0.start == (0, 0) and s0.goal == (2, 4)  # x = column, y = row
    assert s0.optimal_length_8conn == pytest.approx(5.41421)
    assert s0.bfs_length(grid) == 6  # 4-neighbour: down 2, right 4
    assert scen[1].start == (0, 3) and scen[1].goal == (3, 0)
    assert scen[1].bfs_length(grid) == 6  # via (1,3) (2,3) (2,2) (2,1) (2,0) (3,0)
    with pytest.raises(WorldError, match="scenario is for a 4x5 map"):
        s0.bfs_length(np.zeros((3, 3), bool))
    blocked = grid.copy()
    blocked[2, :4] = True  # cuts row 0-1 off from the goal
    with pytest.raises(WorldError, match="unreachable"):
        s0.bfs_length(blocked)


def test_scen_errors(tmp_path):
    p = tmp_path / "bad.scen"
    p.write_text("version 1\n0 m 5 4 0 0 4\n")
    with pytest.raises(WorldError, match="line 2: expected 9 columns"):
        read_movingai_scen(p)
    p.write_text("0 m 5 4 0 0 4 x 3\n")
    with pytest.raises(WorldError, match="line 1: goal_y must be an integer, got 'x'"):
        read_movingai_scen(p)


def test_world_from_movingai(tmp_path):
    (tmp_path / "bench.map").write_text(MAP)
    (tmp_path / "bench.map.scen").write_text(SCEN)
    m, s = tmp_path / "bench.map", tmp_path / "bench.map.scen"
    w = world_from_movingai(m, s, n_robots=2)
    assert w.robots.tolist() == [[0, 0], [0, 3]]
    assert w.targets.tolist() == [[2, 4], [3, 0], [0, 1]]
    w2 = world_from_movingai(m, s, n_robots=1, n_targets=2)
    assert w2.targets.tolist() == [[2, 4], [3, 0]]
    w3 = world_from_movingai(m, robots=[[2, 2]], targets=[[0, 0]])
    assert w3.robots.tolist() == [[2, 2]] and w3.targets.tolist() == [[0, 0]]
    a = world_from_movingai(m, n_robots=2, n_targets=5, seed=7)
    assert a == world_from_movingai(m, n_robots=2, n_targets=5, seed=7)
    assert a.n_robots == 2 and a.n_targets == 5
    with pytest.raises(ValueError, match="has only 3 scenarios"):
        world_from_movingai(m, s, n_robots=4)
    with pytest.raises(ValueError, match="need 20 distinct cells"):
        world_from_movingai(m, n_robots=2, n_targets=18)


def test_numpy_integer_cells_accepted():
    d = {"grid": ["..."], "robots": [[np.int64(0), np.int32(0)]], "targets": [[0, np.int64(2)]]}
    assert world_from_dict(d).targets.tolist() == [[0, 2]]
    with pytest.raises(WorldError, match="'robots' entry 0"):
        world_from_dict({"grid": ["..."], "robots": [[True, 0]], "targets": []})


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), h=st.integers(2, 9), w=st.integers(2, 9), placement=st.sampled_from(["uniform", "centre"]))
def test_json_round_trip_property(seed, h, w, placement):
    world = generate_world(seed, height=h, width=w, n_robots=1, n_targets=min(3, h * w // 3), placement=placement)
    assert world_from_dict(json.loads(json.dumps(world_to_dict(world)))) == world


# ----------------------------------------------------------- shipped examples, limits
def test_example_worlds_ship_with_the_package_and_load():
    tomllib = pytest.importorskip("tomllib")  # Python >= 3.11
    from pathlib import Path

    from mrmt_env.io import example_world_path

    one = read_world(example_world_path())
    assert read_worlds(example_world_path()) == [one]
    many = read_worlds(example_world_path(lines=True))
    assert len(many) == 5 and many[0] == one
    for w in many:  # the paper's set-up
        assert w.shape == (10, 10) and int(w.grid.sum()) == 20 and (w.n_robots, w.n_targets) == (3, 10)
    root = Path(__file__).resolve().parents[1]
    patterns = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["mrmt_env"]
    shipped = {p.name for pattern in patterns for p in (root / "mrmt_env").glob(pattern)}
    assert {example_world_path().name, example_world_path(lines=True).name} <= shipped


def test_example_world_drives_an_env_and_the_cli(capsys):
    import gymnasium as gym

    from agents.cli import main
    from mrmt_env.io import example_world_path

    env = gym.make("mrmt_env/MRMT-v0", world=str(example_world_path()))
    obs, info = env.reset(seed=0)
    assert obs.shape == (5, 10, 10) and info["n_targets"] == 10
    assert main(["plan", str(example_world_path(lines=True)), "--pipeline", "fast", "--no-progress"]) == 0
    assert [json.loads(x)["success"] for x in capsys.readouterr().out.splitlines()] == [True] * 5


@pytest.mark.parametrize("cell, shown", [(10**30, "1000000000000000000000000000000"), (-(2**63) - 1, "-9223372036854775809"),
                                         (2**53 + 1, "9007199254740993")])
def test_huge_cell_is_named_exactly_not_overflowed(cell, shown):
    d = {"grid": ["..."], "robots": [[0, 0]], "targets": [[0, cell]]}
    with pytest.raises(WorldError, match=rf"target 0 cell \[0, {shown}\] is out of bounds for a 1x3 grid"):
        world_from_dict(d)
    with pytest.raises(WorldError, match=rf"target 0 cell \[0, {shown}\] is out of bounds"):
        World(np.zeros((1, 3), bool), [[0, 0]], [[0, cell]])


def test_file_size_limits_are_named(tmp_path, monkeypatch):
    import mrmt_env.io as io

    p = tmp_path / "w.json"
    write_world(generate_world(0), p)
    monkeypatch.setattr(io, "MAX_FILE_BYTES", 100)
    with pytest.raises(WorldError, match=r"w.json: \d+ bytes; a world file may hold at most 100 bytes"):
        read_worlds(p)
    monkeypatch.setattr(io, "MAX_FILE_BYTES", 2**20)
    monkeypatch.setattr(io, "MAX_GRID_CELLS", 99)
    with pytest.raises(WorldError, match=r"grid is 10x10 = 100 cells; a grid read from a file may hold at most 99"):
        read_worlds(p)
    monkeypatch.setattr(io, "MAX_GRID_CELLS", 2**22)
    monkeypatch.setattr(io, "MAX_FIELD_CELLS", 1299)
    with pytest.raises(WorldError, match=r"3 robots \+ 10 targets on a 10x10 grid need 1300 distance-field cells"):
        read_worlds(p)


@pytest.mark.parametrize("text, match", [
    ("[" * 100_000 + "]" * 100_000, "nested too deeply"),
    ('{"grid": ["."], "robots": [[0, ' + "9" * 5000 + ']], "targets": []}', "Exceeds the limit"),
    ('{"grid": ["."], "robots": [[0, 0]], "targets": [[0, 0.5]]}', r"'targets' entry 0 must be an integer"),
    ("42", "a world must be a JSON object, got int"),
])
def test_odd_json_is_one_world_error(tmp_path, text, match):
    p = tmp_path / "odd.json"
    p.write_text(text)
    with pytest.raises(WorldError, match=match):
        read_worlds(p)


def test_non_utf8_and_trailing_map_text_are_named(tmp_path):
    p = tmp_path / "latin.json"
    p.write_bytes(b'{"grid": ["\xe9"]}')
    with pytest.raises(WorldError, match=r"byte 11 \(b'\\xe9'\) is not UTF-8 text"):
        read_worlds(p)
    m = tmp_path / "extra.map"
    m.write_text("type octile\nheight 1\nwidth 2\nmap\n..\n@@\n")
    with pytest.raises(WorldError, match="line 6: text after the 1 map rows the header announces"):
        read_movingai_map(m)
    s = tmp_path / "nan.scen"
    s.write_text("0 m 5 4 0 0 4 3 nan\n")
    with pytest.raises(WorldError, match="optimal_length must be a finite number >= 0, got 'nan'"):
        read_movingai_scen(s)
