"""Cold start: ``mrmt warmup`` and the one-line notice before a first compile (agents/warmup.py)."""

import json

import pytest

from agents.cli import main
from agents.warmup import cold_parts, parts_for, stamp_path


@pytest.fixture(autouse=True)
def fresh_stamp(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))


def test_parts_split_the_ising_layers_and_put_the_longest_first():
    parts = parts_for(["fast", "ising", "ssa+3opt+ising", "ising-paper+2opt+astar", "ppo:model.zip"])
    assert parts[0] == "ising:sharing"
    assert set(parts) == {"ising:sharing", "ising:tour+path", "ising-fleet", "fast", "psa+3opt+ising"}
    # ising: the fleet search above 20 targets too; the paper's sharing runs the same kernels as ising's
    assert parts_for(["ssa+ising+ising"]) == ["ising:tour+path"]  # the preset's part: compiled once
    assert sorted(parts_for(["ising-paper"])) == ["ising-paper:tour+path", "ising:sharing"]
    assert parts_for(["ppo:model.zip"]) == []
    # worlds known to stay at or below the fleet crossover never run the fleet search: no part for it
    from planners.pipeline import FLEET_ABOVE

    assert "ising-fleet" not in parts_for(["ising"], max_targets=FLEET_ABOVE)
    assert "ising-fleet" in parts_for(["ising"], max_targets=FLEET_ABOVE + 1)
    assert "ising-fleet" in parts_for(["ising-fleet"], max_targets=10)  # asked for by name: always


def test_warmup_says_once_what_it_compiles_then_is_warm(capsys):
    assert cold_parts(["fast"]) == ["fast"]
    assert main(["warmup", "--pipelines", "fast", "--jobs", "1", "--no-progress"]) == 0
    out, err = capsys.readouterr()
    (line,) = err.strip().splitlines()  # one line: what, why, how long, that it is once per install
    assert line.startswith("mrmt: compiling the numba kernels of fast")
    assert "first run" in line and " s on 1 core" in line
    assert "compiled 1 part(s)" in out
    assert "fast" in next(iter(json.loads(stamp_path().read_text()).values()))
    assert cold_parts(["fast"]) == []
    assert main(["warmup", "--pipelines", "fast", "--jobs", "1", "--no-progress"]) == 0
    out, err = capsys.readouterr()
    assert err == "" and out.startswith("already warm: fast")


def test_plan_prints_the_notice_only_when_cold(tmp_path, capsys):
    from mrmt_env import generate_world
    from mrmt_env.io import write_worlds

    src = tmp_path / "w.jsonl"
    write_worlds([generate_world(1)], src)
    assert main(["plan", str(src), "--pipeline", "fast", "--no-progress"]) == 0
    assert capsys.readouterr().err == ""  # a few seconds of compiling: not announced
    assert main(["plan", str(src), "--pipeline", "ising", "--no-progress"]) == 0
    err = capsys.readouterr().err
    assert err.startswith("mrmt: compiling the numba kernels of ising:sharing, ising-fleet, ising:tour+path (first run")  # longest first
    assert len(err.strip().splitlines()) == 1
    assert main(["plan", str(src), "--pipeline", "ising", "--no-progress"]) == 0
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("argv, message", [
    (["warmup", "--jobs", "0"], "--jobs must be >= 1"),
    (["warmup", "--pipelines", "nope"], "unknown controller 'nope'"),
    (["warmup", "--lorr", "epibt,nope"], "--lorr: unknown executor 'nope'; expected `all` or some of pibt"),
])
def test_bad_input_is_one_line(argv, message, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


def test_other_installs_keep_their_stamps():
    stamp_path().parent.mkdir(parents=True)
    stamp_path().write_text(json.dumps({"another-install": ["ising:sharing"]}))
    assert main(["warmup", "--pipelines", "fast", "--jobs", "1", "--no-progress"]) == 0
    data = json.loads(stamp_path().read_text())
    assert data["another-install"] == ["ising:sharing"] and ["fast"] in data.values()


def test_lorr_executors_are_warmed_as_parts_of_their_own():
    """``--lorr`` adds the named executors' parts (``all``: every registered one) to the presets'."""
    from agents.commands.warmup import _lorr_executors
    from planners.mapf import TURNING_PLANNERS

    assert main(["warmup", "--pipelines", "fast", "--lorr", "pibt", "--jobs", "1", "--no-progress"]) == 0
    assert {"fast", "lorr:pibt"} <= set(json.loads(stamp_path().read_text()).popitem()[1])
    assert _lorr_executors("all") == list(TURNING_PLANNERS) and _lorr_executors(" epibt, pibt ") == ["epibt", "pibt"]


def test_the_probe_times_a_fresh_compile_and_says_when_it_cannot(monkeypatch):
    from agents import warmup

    seconds = warmup.probe_seconds()
    assert seconds is not None and 0 < seconds < 120  # a fresh interpreter: numba imported, one kernel compiled
    monkeypatch.setattr(warmup.sys, "executable", "/nonexistent/python")
    assert warmup.probe_seconds() is None


@pytest.mark.parametrize("pace, busy, expected", [
    (2.0, 1.0, "roughly 40 s on 1 core(s) (this machine's pace: 2.0x, 0.0 cores busy with other work)"),
    (1.0, 2.0, "roughly 20 s on 1 core(s) (this machine's pace: 1.0x, 1.0 cores busy with other work)"),
    (None, 1.0, "roughly 20 s on 1 core(s) (the reference machine's pace)")])
def test_the_notice_scales_the_reference_seconds_by_the_machines_pace(pace, busy, expected, monkeypatch, capsys):
    from agents import warmup

    monkeypatch.setitem(warmup.PART_SECONDS, "fast", 20)  # long enough to be probed
    monkeypatch.setattr(warmup, "probe_seconds", lambda: None if pace is None else pace * warmup.PROBE_REF_S)
    readings = iter([(0, 0, 2), (int(50 * busy), 100, 2)])  # 2 cpus, `busy` of them busy during the probe
    monkeypatch.setattr(warmup, "cpu_times", lambda: next(readings))
    assert warmup.estimate_s(["fast"], 1) == 20
    assert main(["warmup", "--pipelines", "fast", "--jobs", "1", "--no-progress", "--force"]) == 0
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.endswith(expected)


@pytest.mark.parametrize("probe, others, jobs, cores, factor", [
    (1.0, 0.0, 2, 2, 1.0),    # the reference machine, idle: its seconds
    (1.0, 1.0, 2, 2, 1.5),    # a core busy elsewhere: the probe had a core of its own, the two workers share three ways
    (2.0, 3.0, 2, 2, 2.5),    # the probe slowed by half by the load beside it: as fast as the reference alone
    (1.0, 0.0, 1, 2, 1.0),
    (0.5, 0.0, 4, 2, 1.0),    # twice as fast, four workers on two cores
])
def test_the_pace_factor_counts_the_probe_alone_and_the_workers_share_of_the_cores(probe, others, jobs, cores, factor):
    from agents import warmup

    assert warmup.pace_factor(probe * warmup.PROBE_REF_S, others, jobs, cores) == pytest.approx(factor)


def test_busy_cores_are_read_from_the_machines_ticks():
    from agents.warmup import busy_cores, cpu_times

    assert busy_cores((100, 1000, 2), (150, 1100, 2)) == 1.0 and busy_cores((5, 9, 2), (5, 9, 2)) == 0.0
    now = cpu_times()
    if now is not None:  # Linux
        busy, total, cpus = now
        assert 0 <= busy <= total and cpus >= 1


def test_the_estimate_shares_the_parts_over_the_workers_and_is_at_least_the_longest():
    from agents.warmup import PART_SECONDS, SHARED_SHARE, estimate_s

    parts = ["ising:sharing", "ising-paper:tour+path", "ising:tour+path"]
    secs = [PART_SECONDS[p] for p in parts]
    assert estimate_s(parts, 2) == max(max(secs), SHARED_SHARE * sum(secs) / 2)
    assert estimate_s(["ising:sharing"], 2) == PART_SECONDS["ising:sharing"]
    assert estimate_s(parts, 1) == SHARED_SHARE * sum(secs)


def test_compiles_are_counted_not_cache_loads():
    """The bars count numba's compiles (``numba:compile`` events) in the process that compiles."""
    import numba

    from agents.warmup import count_compiles

    names = []
    with count_compiles(names.append):
        numba.njit(cache=False)(lambda x: x + 1)(1)
    assert len(names) == 1
    with count_compiles(names.append):
        pass  # nothing compiled: nothing counted
    assert len(names) == 1


def test_each_part_has_a_bar_of_its_kernels_filled_when_done(monkeypatch, capsys):
    from agents import warmup

    monkeypatch.setitem(warmup.PART_KERNELS, "fast", 7)
    assert main(["warmup", "--pipelines", "fast", "--jobs", "1", "--force"]) == 0
    err = capsys.readouterr().err.replace("\r", "\n")
    assert "compiling fast" in err and "7/7" in err and "done" in err
