"""Fuzzing the world readers (JSON, JSON Lines, MovingAI) and ``mrmt plan`` on what they read.

Every bad world is one ``WorldError`` line naming its line; a good world is never dropped, and
good lines keep their order; ``mrmt plan`` exits 0 / 1 / 2 without a traceback.
"""

from __future__ import annotations

import contextlib
import io
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest
from fuzzing import fuzz_settings, no_hang, one_line
from hypothesis import given
from hypothesis import strategies as st

from agents.cli import main
from mrmt_env import World, WorldError, generate_world
from mrmt_env.io import iter_worlds_text, read_worlds, world_from_dict, world_to_dict
from mrmt_env.movingai import read_movingai_map, read_movingai_scen

json_values = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(-(2**70), 2**70), st.floats(allow_nan=True),
              st.text(max_size=6)),
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=6), inner, max_size=4)),
    max_leaves=12,
)


@st.composite
def small_worlds(draw):
    return generate_world(draw(st.integers(0, 10**6)), height=draw(st.integers(3, 6)), width=draw(st.integers(2, 6)),
                          obstacle_density=0.1, n_robots=draw(st.integers(1, 2)), n_targets=draw(st.integers(0, 3)))


@st.composite
def mutated_dicts(draw):
    """A good world dict with one part replaced by anything."""
    d = world_to_dict(draw(small_worlds()))
    key = draw(st.sampled_from(["grid", "robots", "targets", "extra", "drop"]))
    if key == "drop":
        del d[draw(st.sampled_from(sorted(d)))]
    elif key == "extra":
        d[draw(st.text(max_size=4))] = draw(json_values)
    elif draw(st.booleans()):
        d[key] = draw(json_values)
    else:  # one entry of the list replaced
        items = list(d[key])
        if items:
            items[draw(st.integers(0, len(items) - 1))] = draw(st.one_of(
                json_values, st.lists(st.integers(-(2**70), 2**70), min_size=2, max_size=2),
                st.text(alphabet=".@GSOTWx?", max_size=8)))
        d[key] = items
    return d


@fuzz_settings(150)
@given(value=st.one_of(json_values, mutated_dicts()))
def test_world_from_any_json_value(value):
    try:
        world = world_from_dict(value)
    except WorldError as exc:
        one_line(exc)
    else:
        assert isinstance(world, World) and world_from_dict(world_to_dict(world)) == world


def _bad_line(draw) -> str:
    kind = draw(st.sampled_from(["text", "json", "dict", "cut"]))
    if kind == "text":
        return draw(st.text(st.characters(blacklist_characters="\n\r", blacklist_categories=("Cs",)), min_size=1,
                            max_size=30).filter(str.strip))
    if kind == "json":
        return json.dumps(draw(json_values))
    if kind == "dict":
        return json.dumps(draw(mutated_dicts()))
    line = json.dumps(world_to_dict(draw(small_worlds())))
    return line[: draw(st.integers(1, len(line) - 1))]


@st.composite
def world_files(draw):
    """JSON Lines text: ``entries`` of ('good', World) or ('bad', line), blank lines between."""
    entries = []
    for _ in range(draw(st.integers(1, 6))):
        if draw(st.booleans()):
            entries.append(("good", draw(small_worlds())))
        else:
            entries.append(("bad", _bad_line(draw)))
    lines = []
    for kind, item in entries:
        lines.extend([""] * draw(st.integers(0, 1)))
        lines.append(json.dumps(world_to_dict(item)) if kind == "good" else item)
    return entries, "\n".join(lines) + draw(st.sampled_from(["", "\n", "\r\n"]))


def _parses_whole(text: str) -> bool:
    try:
        json.loads(text)
    except (ValueError, RecursionError):
        return False
    return True


def _reference(line: str):
    """A line's world, or None: plain json + world_from_dict, independent of the file reader."""
    try:
        return world_from_dict(json.loads(line))
    except (ValueError, RecursionError):
        return None


@fuzz_settings(150)
@given(case=world_files())
def test_json_lines_keep_every_good_line_in_order(case):
    entries, text = case
    items = list(iter_worlds_text(text.replace("\r\n", "\n"), "w.jsonl"))
    for _, item in items:
        if isinstance(item, WorldError):
            one_line(item)
    lines = [item for _, item in entries]
    expected = [w if kind == "good" else _reference(w) for kind, w in entries]
    if _parses_whole(text):  # the whole text is one JSON value: one world (or one error)
        assert len(items) == 1
        return
    if not any(e is not None for e in expected):
        assert all(isinstance(item, WorldError) for _, item in items)
        return
    assert len(items) == len(lines)
    numbers = [n for n, _ in items]
    assert numbers == sorted(numbers) and len(set(numbers)) == len(numbers)
    for want, (n, item) in zip(expected, items):
        if want is None:
            assert isinstance(item, WorldError) and f"line {n}" in str(item)
        else:
            assert item == want


@fuzz_settings(100)
@given(data=st.binary(max_size=200))
def test_arbitrary_bytes_are_refused_in_one_line(data):
    with tempfile.TemporaryDirectory() as tmp:
        for name, reader in (("w.jsonl", read_worlds), ("m.map", read_movingai_map), ("s.scen", read_movingai_scen)):
            p = Path(tmp) / name
            p.write_bytes(data)
            try:
                reader(p)
            except WorldError as exc:
                one_line(exc)


@st.composite
def map_texts(draw):
    h, w = draw(st.integers(0, 5)), draw(st.integers(0, 5))
    rows = [draw(st.text(alphabet=".@GSOTW", min_size=w, max_size=w)) for _ in range(h)]
    header = [f"type {draw(st.sampled_from(['octile', 'x']))}",
              f"height {draw(st.sampled_from([h, h + 1, max(h - 1, 0), -1, 'x', 10**30]))}",
              f"width {draw(st.sampled_from([w, w + 1, 'y', 2**70]))}", "map"]
    if draw(st.booleans()):  # damage one row or header line
        k = draw(st.integers(0, len(header) + len(rows) - 1))
        lines = header + rows
        lines[k] = draw(st.text(st.characters(blacklist_characters="\n\r", blacklist_categories=("Cs",)),
                                max_size=8))
        header, rows = lines[:4], lines[4:]
    return "\n".join(header + rows) + "\n" * draw(st.integers(0, 2)), (h, w, rows)


@fuzz_settings(150)
@given(case=map_texts())
def test_movingai_map_reads_or_names_the_problem(case):
    text, (h, w, rows) = case
    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "x.map"
        p.write_text(text)
        try:
            grid = read_movingai_map(p)
        except WorldError as exc:
            one_line(exc)
        else:
            assert grid.shape == (h, w) and h >= 1 and w >= 1
            assert grid.tolist() == [[ch in "@OTW" for ch in row] for row in rows]


scen_field = st.one_of(st.integers(-3, 20), st.integers(-(2**70), 2**70), st.floats(allow_nan=True),
                       st.text(alphabet="0123456789abc.-", min_size=1, max_size=5))


@fuzz_settings(150)
@given(rows=st.lists(st.lists(scen_field, min_size=7, max_size=10), max_size=5), version=st.booleans())
def test_movingai_scen_reads_or_names_the_problem(rows, version):
    text = ("version 1\n" if version else "") + "".join(
        "\t".join([str(r[0]), "m.map", *map(str, r[1:])]) + "\n" for r in rows)
    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "x.scen"
        p.write_text(text)
        try:
            scen = read_movingai_scen(p)
        except WorldError as exc:
            one_line(exc)
        else:
            assert len(scen) == len(rows)
            for s in scen:
                assert s.width >= 1 and s.height >= 1 and np.isfinite(s.optimal_length_8conn)


# ------------------------------------------------------------------ mrmt plan
def _plan(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(argv)
    return rc, out.getvalue(), err.getvalue()


@fuzz_settings(40)
@given(case=world_files(), keep_going=st.booleans(), seed=st.integers(-3, 2**64),
       pipeline=st.sampled_from(["fast", "strong"]))
def test_mrmt_plan_on_anything(case, keep_going, seed, pipeline):
    entries, text = case
    with tempfile.TemporaryDirectory() as tmp, no_hang(120):
        src = Path(tmp) / "w.jsonl"
        src.write_text(text)
        argv = ["plan", str(src), "--pipeline", pipeline, "--seed", str(seed), "--no-progress"]
        rc, out, err = _plan(argv + (["--keep-going"] if keep_going else []))
    assert "Traceback" not in err
    errors = [line for line in err.splitlines() if line.startswith("mrmt plan: error: ")]
    assert len(errors) == len(err.splitlines())  # nothing else on stderr
    if seed < 0:
        assert rc == 2 and out == "" and len(errors) == 1 and f"got {seed}" in errors[0]
        return
    items = list(iter_worlds_text(text.replace("\r\n", "\n"), str(src)))
    bad = [n for n, item in items if isinstance(item, Exception)]
    records = [json.loads(line) for line in out.splitlines()]
    if not bad:
        assert rc == 0 and len(records) == len(items) and not errors
        assert all(r["success"] for r in records)
    elif keep_going:
        assert rc == 2 and len(records) == len(items) and len(errors) == len(bad)
        assert [r["line"] for r in records if "error" in r] == bad
        assert [("error" in r) for r in records] == [isinstance(item, Exception) for _, item in items]
    else:
        assert rc == 2 and records == []
        assert len(errors) == len(bad) + (len(items) > 1)
        if len(items) > 1:
            assert "--keep-going" in errors[-1]


def _run(args, tmp_path):
    script = Path(sys.executable).parent / "mrmt"
    cmd = [str(script)] if script.exists() else [sys.executable, "-m", "agents.cli"]
    return subprocess.run([*cmd, *args], capture_output=True, text=True, timeout=120, cwd=tmp_path)


@pytest.mark.parametrize("content, message", [
    (b'{"grid": [".."], "robots": [[0, 0]], "targets": [[0, ' + str(10**30).encode() + b"]]}",
     "target 0 cell [0, 1000000000000000000000000000000] is out of bounds for a 1x2 grid"),
    (b'{\n  "grid": [\n    ".."\n  ],\n  "robots": [[0, 0]]\n  "targets": []\n}\n',
     "line 6 column 3: not valid JSON (Expecting ',' delimiter)"),
    (b"\xff\xfe{}", "byte 0 (b'\\xff') is not UTF-8 text"),
    (b"[" * 50000, "nested too deeply"),
])
def test_plan_subprocess_bad_files_one_line_no_traceback(tmp_path, content, message):
    (tmp_path / "w.json").write_bytes(content)
    proc = _run(["plan", "w.json", "--no-progress"], tmp_path)
    assert proc.returncode == 2 and proc.stdout == ""
    (line,) = proc.stderr.splitlines()
    assert message in line


def test_plan_subprocess_bad_seed(tmp_path):
    (tmp_path / "w.json").write_text(json.dumps(world_to_dict(generate_world(0))))
    proc = _run(["plan", "w.json", "--seed", "-1"], tmp_path)
    assert proc.returncode == 2 and proc.stderr.strip() == "mrmt plan: error: --seed must be >= 0 (a numpy seed), got -1"
