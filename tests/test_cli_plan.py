"""``mrmt plan``: round trip on small files, bad lines, exit codes."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from agents.cli import main
from mrmt_env import generate_world
from mrmt_env.io import read_worlds, world_to_dict, write_world, write_worlds
from planners.plan import Plan, RobotRoute, validate_plan


def _as_plan(d):
    return Plan(tuple(RobotRoute(r["targets"], r["path"]) for r in d["robots"]), success=d["success"])


@pytest.fixture
def worlds():
    return [generate_world(s, n_robots=1 + s % 3, n_targets=2 + s) for s in range(4)]


def test_round_trip_jsonl(tmp_path, worlds, capsys):
    src = tmp_path / "w.jsonl"
    write_worlds(worlds, src)
    assert main(["plan", str(src), "--pipeline", "strong", "--no-progress"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == len(worlds)
    for world, line in zip(read_worlds(src), lines):
        d = json.loads(line)
        assert set(d) == {"robots", "route_cost", "makespan", "imbalance", "success", "compute"}
        assert d["success"] is True
        plan = _as_plan(d)
        validate_plan(world, plan)
        assert (plan.route_cost, plan.makespan, plan.imbalance) == (d["route_cost"], d["makespan"], d["imbalance"])
        assert d["compute"]["cpu_s"] > 0 and d["compute"]["chip_calls"] == 0
        assert d["compute"]["host_energy_j"] == pytest.approx(15 * d["compute"]["cpu_s"])


def test_layer_flags_single_world_file_and_out(tmp_path, worlds):
    src = tmp_path / "one.json"
    write_world(worlds[2], src)
    out = tmp_path / "plans.jsonl"
    rc = main(["plan", str(src), "--sharing", "exact", "--tour", "brute", "--path", "bfs", "--out", str(out)])
    assert rc == 0
    (line,) = out.read_text().splitlines()
    validate_plan(worlds[2], _as_plan(json.loads(line)))


def test_same_seed_same_output(tmp_path, worlds, capsys):
    src = tmp_path / "w.jsonl"
    write_worlds(worlds, src)
    outs = []
    for _ in range(2):
        main(["plan", str(src), "--pipeline", "fast", "--seed", "3"])
        outs.append([json.loads(x)["robots"] for x in capsys.readouterr().out.splitlines()])
    assert outs[0] == outs[1]


def _bad_file(tmp_path, worlds):
    good = [json.dumps(world_to_dict(w)) for w in worlds[:3]]
    bad_world = dict(world_to_dict(worlds[0]), robots=[[0, 99]])
    src = tmp_path / "bad.jsonl"
    src.write_text("\n".join([good[0], "{not json", good[1], json.dumps(bad_world), good[2]]) + "\n")
    return src


def test_bad_lines_are_all_named_and_nothing_is_planned(tmp_path, worlds, capsys):
    src = _bad_file(tmp_path, worlds)
    assert main(["plan", str(src), "--pipeline", "fast"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""  # no partial output: the good lines are not silently cut short
    err = captured.err.strip().splitlines()
    assert len(err) == 3
    assert err[0].startswith(f"mrmt plan: error: {src} line 2 column 2: not valid JSON")
    assert f"{src} line 4: robot 0 cell [0, 99] is out of bounds" in err[1]
    assert "2 of 5 worlds" in err[2] and "--keep-going" in err[2]


def test_pretty_printed_world_error_names_its_line_and_column(tmp_path, worlds, capsys):
    src = tmp_path / "one.json"
    write_world(worlds[0], src)
    lines = src.read_text().splitlines()
    lines[3] = lines[3].rstrip(",")  # no comma after grid row 1 (file line 4): the parser stops on line 5
    src.write_text("\n".join(lines) + "\n")
    assert main(["plan", str(src), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith(f"mrmt plan: error: {src} line 5 column 5: not valid JSON (Expecting ',' delimiter)")


def test_keep_going_emits_error_objects_in_place(tmp_path, worlds, capsys):
    src = _bad_file(tmp_path, worlds)
    assert main(["plan", str(src), "--pipeline", "fast", "--keep-going"]) == 2
    captured = capsys.readouterr()
    records = [json.loads(x) for x in captured.out.splitlines()]
    assert len(records) == 5
    assert records[1]["line"] == 2 and "not valid JSON" in records[1]["error"]
    assert records[3]["line"] == 4 and "robot 0 cell [0, 99] is out of bounds" in records[3]["error"]
    for i, w in zip((0, 2, 4), worlds[:3]):
        validate_plan(w, _as_plan(records[i]))
    assert len([x for x in captured.err.splitlines() if "error" in x]) == 2


def test_planning_refusal_is_reported_with_line(tmp_path, capsys):
    src = tmp_path / "big.jsonl"
    write_worlds([generate_world(1, n_robots=1, n_targets=5), generate_world(0, n_robots=1, n_targets=14),
                  generate_world(2, n_robots=1, n_targets=5)], src)
    argv = ["plan", str(src), "--sharing", "psa", "--tour", "brute", "--path", "bfs"]
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert len(captured.out.splitlines()) == 1
    (err,) = captured.err.strip().splitlines()
    assert f"{src} line 2: planning failed: brute tour: 14 targets exceeds the limit of 13" in err
    assert "the 1 world(s) after line 2 were not planned; --keep-going" in err
    assert main(argv + ["--keep-going"]) == 2
    records = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert [("error" in r) for r in records] == [False, True, False] and records[1]["line"] == 2


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--tour", "4opt"], "unknown tour planner '4opt'; valid tour planners: nn, 2opt, 3opt, brute, ising"),
        (["--pipeline", "quick"], "unknown pipeline preset 'quick'"),
        (["--option", "tour.movez=7"], "takes no option 'movez'"),
        (["--option", "moves=7"], "the key must look like LAYER.KEY"),
    ],
)
def test_bad_planner_arguments(tmp_path, worlds, capsys, argv, message):
    src = tmp_path / "w.jsonl"
    write_worlds(worlds[:1], src)
    assert main(["plan", str(src), *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_missing_and_empty_files(tmp_path, capsys):
    assert main(["plan", str(tmp_path / "nope.jsonl")]) == 2
    assert "nope.jsonl: cannot read" in capsys.readouterr().err
    (tmp_path / "empty.jsonl").write_text("\n\n")
    assert main(["plan", str(tmp_path / "empty.jsonl")]) == 2
    assert "no worlds" in capsys.readouterr().err


def test_option_reaches_the_layer(tmp_path, worlds, capsys):
    from agents.commands.plan import build_pipeline

    class Args:
        pipeline, sharing, tour, path = "strong", None, None, None
        option = ["tour.moves=7", "sharing.bid=tour"]

    pipe = build_pipeline(Args)
    assert pipe.tour.moves == "7" and pipe.sharing.bid == "tour"


def test_console_script_subprocess(tmp_path, worlds):
    src = tmp_path / "w.jsonl"
    write_worlds(worlds[:2], src)
    script = Path(sys.executable).parent / "mrmt"
    cmd = [str(script)] if script.exists() else [sys.executable, "-m", "agents.cli"]
    proc = subprocess.run([*cmd, "plan", str(src), "--pipeline", "fast"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert len(lines) == 2
    validate_plan(worlds[1], _as_plan(json.loads(lines[1])))


def test_a_reader_that_goes_away_stops_the_command_quietly(tmp_path, worlds):
    """``mrmt plan ... | head``: the pipe closes before the first line; the command stops with 141
    (128 + SIGPIPE, as a shell reports it) and no traceback."""
    src = tmp_path / "w.jsonl"
    write_worlds(worlds[:2], src)
    script = Path(sys.executable).parent / "mrmt"
    cmd = [str(script)] if script.exists() else [sys.executable, "-m", "agents.cli"]
    proc = subprocess.Popen([*cmd, "plan", str(src), "--pipeline", "fast", "--no-progress"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    proc.stdout.close()  # before the command plans anything: its first write meets a closed pipe
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141
    assert "Traceback" not in err and "BrokenPipeError" not in err, err


def test_a_failed_plan_is_written_and_exits_1(tmp_path, capsys):
    src = tmp_path / "w.json"
    write_world(generate_world(0, n_robots=3, n_targets=10), src)
    # the Ising path layer with a budget of 4 chip calls per leg and no fallback gives up on long legs:
    # a failed plan (a result), not an input error
    assert main(["plan", str(src), "--sharing", "ssa", "--tour", "3opt", "--path", "ising", "--option",
                 "path.max_chip_calls=4", "--option", "path.fallback=never", "--no-progress"]) == 1
    captured = capsys.readouterr()
    (line,) = captured.out.splitlines()
    d = json.loads(line)
    assert d["success"] is False and "budget spent" in d["failure"] and "max_chip_calls=4" in d["failure"]
    assert captured.err.strip().splitlines() == ['mrmt plan: 1 of 1 plans failed ("success": false; see their "failure")']


def test_chip_option_plans_on_another_chip(tmp_path, worlds, capsys):
    src = tmp_path / "w.json"
    write_world(worlds[3], src)
    spec_file = tmp_path / "chip.json"
    spec_file.write_text(json.dumps({"n_spins": 64, "j_range": [-15, 15]}))
    assert main(["plan", str(src), "--pipeline", "ising", "--chip", str(spec_file), "--chip", "cores_per_chip=4",
                 "--no-progress"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["success"] is True
    # 16 cores: a submission of up to 16 programs is one parallel batch
    assert d["compute"]["chip_batches"] <= d["compute"]["chip_calls"]
    validate_plan(worlds[3], _as_plan(d))


@pytest.mark.parametrize("chip, message", [
    (["warp=9"], "unknown chip field 'warp'; valid fields: n_spins, h_range"),
    (["n_spins=4.5"], "n_spins = '4.5' must be an integer"),
    (["j_range=0"], "a single value m means (-m, m) and must be >= 1"),
    (["missing.json"], "neither KEY=VALUE nor a readable JSON file"),
    (["n_spins=64", "n-spins=32"], "--chip n_spins given twice ('64' and '32'); give it once"),
    (["=3"], "--chip '=3' must look like KEY=VALUE"),
])
def test_bad_chip_option_is_one_line_and_exit_2(tmp_path, worlds, capsys, chip, message):
    src = tmp_path / "w.json"
    write_world(worlds[0], src)
    args = ["plan", str(src), "--pipeline", "ising", "--no-progress"]
    for c in chip:
        args += ["--chip", c]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]


def test_chip_option_needs_a_chip_layer(tmp_path, worlds, capsys):
    src = tmp_path / "w.json"
    write_world(worlds[0], src)
    assert main(["plan", str(src), "--pipeline", "strong", "--chip", "n_spins=64", "--no-progress"]) == 2
    assert "no layer of this pipeline runs on a chip" in capsys.readouterr().err


def test_chip_spec_file_is_data_with_a_size_limit(tmp_path):
    from ising_backend import ChipSpec

    big = tmp_path / "big.json"
    big.write_text("{" + " " * 70000 + "}")
    with pytest.raises(ValueError, match="at most 65536 bytes"):
        ChipSpec.from_options([str(big)])
    not_obj = tmp_path / "list.json"
    not_obj.write_text("[1, 2]")
    with pytest.raises(ValueError, match="one JSON object of fields, got list"):
        ChipSpec.from_options([str(not_obj)])
    broken = tmp_path / "broken.json"
    broken.write_text('{\n  "n_spins": 64,\n  "sweeps": \n}')
    with pytest.raises(ValueError, match="line 4"):
        ChipSpec.from_options([str(broken)])
    spec = ChipSpec.from_options([("beta_range", "0.1,3"), ("h_range", "-3,5"), ("readout_flip_prob", "0.01")])
    assert spec.beta_range == (0.1, 3.0) and spec.h_range == (-3, 5) and spec.readout_flip_prob == 0.01


def test_first_plan_reports_the_warm_up_apart(tmp_path, worlds, capsys):
    src = tmp_path / "w.jsonl"
    write_worlds(worlds, src)
    assert main(["plan", str(src), "--pipeline", "fast", "--no-progress"]) == 0
    computes = [json.loads(line)["compute"] for line in capsys.readouterr().out.splitlines()]
    assert computes[0]["warmup_s"] > 0 and all(c["warmup_s"] == 0 for c in computes[1:])
    for c in computes:  # the warm-up is in no time or energy figure of the plan
        assert c["host_energy_j"] == pytest.approx(15 * c["host_cpu_s"])
        assert c["latency_s"] == pytest.approx(c["host_cpu_s"])
