"""The decision audit: records every chip decision without changing a plan; judged against brute force."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from agents.lorr.run import MEASURED_KEYS
from ising_backend import CallLedger, ChipSpec, EmulatedChip
from ising_backend.audit.record import Audit, active_audit, program_arrays, read_records
from ising_backend.audit.judge import exact_ground, greedy_descent, judge, load_benchmark, table
from mrmt_env.generation import generate_world
from planners.pipeline import make_pipeline


def _energy(h, J, s):
    return float(h @ s + s @ np.triu(J, 1) @ s)


def _brute(h, J):
    n = h.shape[0]
    return min(_energy(h, J, np.array(s, dtype=float)) for s in itertools.product((-1.0, 1.0), repeat=n))


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 10), st.integers(0, 2**31 - 1))
def test_exact_ground_and_greedy_match_brute_force(n, seed):
    rng = np.random.default_rng(seed)
    h = rng.integers(-7, 8, size=n).astype(float)
    J = np.triu(rng.integers(-7, 8, size=(n, n)), 1).astype(float)
    e, s = exact_ground(h, J)
    assert e == pytest.approx(_brute(h, J)) and _energy(h, J, s) == pytest.approx(e)
    g, gs = greedy_descent(h, J)
    assert _energy(h, J, gs) == pytest.approx(g) and g >= e - 1e-9
    for i in range(n):  # a local minimum: no single flip lowers it
        t = gs.copy()
        t[i] = -t[i]
        assert _energy(h, J, t) >= g - 1e-9


def _plans(preset, worlds, chip=None):
    pipe = make_pipeline(preset) if chip is None else make_pipeline(preset, chip=chip)
    out = []
    for s, w in enumerate(worlds):
        p = pipe.plan(w, seed=s)
        out.append([(tuple(r.targets), np.asarray(r.path).tolist()) for r in p.routes] + [p.compute.chip_calls,
                                                                                         p.compute.logical_calls])
    return out


@pytest.mark.parametrize("preset,chip", [("ising-paper", None), ("ising", None),
                                         ("ising-paper", lambda: EmulatedChip(ChipSpec(dead_cores=1), seed=2))])
def test_audit_changes_no_plan_and_its_charges_add_up_to_the_ledger(tmp_path, preset, chip):
    worlds = [generate_world(s) for s in range(3)]
    plain = _plans(preset, worlds, chip and chip())
    machine = chip() if chip else EmulatedChip()
    with Audit(tmp_path) as audit:
        assert active_audit() is audit
        audited = _plans(preset, worlds, machine)
    assert active_audit() is None
    assert audited == plain
    rows = read_records(tmp_path)
    classes = {r["class"] for r in rows}
    assert {"sharing_split"} <= classes and "unlabelled" not in classes
    physical = sum(r["calls"] for r in rows if not r["logical"])
    logical = sum(r["calls"] for r in rows if r["logical"])
    assert (physical, logical) == (machine.ledger.physical_calls - machine.ledger.probe_calls,
                                   machine.ledger.logical_calls)
    for r in rows[:50]:  # the recorded best energy is the energy of the recorded spins
        h, J = program_arrays(r)
        assert _energy(h, J, np.array(r["chip_spins"], dtype=float)) == pytest.approx(r["chip_energy"])


def test_judge_and_table_against_brute_force(tmp_path):
    rng = np.random.default_rng(5)
    h = rng.integers(-7, 8, size=(6, 8)).astype(np.int64)
    J = np.triu(rng.integers(-7, 8, size=(6, 8, 8)), 1).astype(np.int64)
    chip = EmulatedChip(seed=1)
    with Audit(tmp_path):
        with chip.session(CallLedger(), decision="toy") as link:
            from ising_backend import anneal_submit

            spins = np.empty((6, 2, 8), dtype=np.int8)
            anneal_submit(h, J, 2, np.uint64(3), link.args, spins, np.empty((6, 2)))
    rows = read_records(tmp_path)
    judged = judge(rows)
    for r, j in zip(rows, judged):
        hh, JJ = program_arrays(r)
        assert j["optimum_kind"] == "exact" and j["optimum"] == pytest.approx(_brute(hh, JJ))
        assert j["host_energy"] == pytest.approx(float(greedy_descent(hh, JJ)[0]))
    [row] = table(judged)
    chip_e = np.array([j["chip_energy"] for j in judged])
    host_e = np.array([j["host_energy"] for j in judged])
    opt = np.array([j["optimum"] for j in judged])
    assert row["decisions"] == 6 and row["chip_better"] == pytest.approx(np.mean(chip_e < host_e - 1e-9))
    assert row["chip_gap"] == pytest.approx(np.mean((chip_e - opt) / np.maximum(np.abs(opt), 1)))


def test_audits_do_not_nest(tmp_path):
    with Audit(tmp_path / "a"):
        with pytest.raises(RuntimeError, match="do not nest"):
            Audit(tmp_path / "b").__enter__()


def _mrmt(*args):
    return subprocess.run([sys.executable, "-m", "agents.cli", *args], capture_output=True, text=True)


def test_cli_records_judges_and_exports(tmp_path):
    from mrmt_env.io import world_to_dict

    worlds = tmp_path / "w.jsonl"
    worlds.write_text("".join(json.dumps(world_to_dict(generate_world(s))) + "\n" for s in range(2)))
    d = tmp_path / "audit"
    r = _mrmt("plan", str(worlds), "--pipeline", "ising-paper", "--audit", str(d), "--out", str(tmp_path / "p"),
              "--no-progress")
    assert r.returncode == 0, r.stderr
    r = _mrmt("audit", str(d), "--json", "--export", str(tmp_path / "set"))
    assert r.returncode == 0, r.stderr
    rows = [json.loads(line) for line in r.stdout.splitlines()]
    assert {"path_query", "sharing_split", "tour_order"} <= {x["class"] for x in rows}
    for x in rows:
        assert set(x) >= {"class", "decisions", "chip_better", "chip_worse", "chip_gap", "host_gap", "chip_s", "host_s"}
    n = {x["class"]: x["decisions"] for x in rows}
    problems = load_benchmark(tmp_path / "set" / "path_query.jsonl")
    assert len(problems) == n["path_query"]
    bqm, rec = problems[0]
    assert rec["spec"]["n_spins"] == 45 and rec["optimum"] <= rec["chip_energy"] + 1e-9
    bad = _mrmt("audit", str(tmp_path / "nothing"))
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1 and "no audit" in bad.stderr
    bad = _mrmt("audit", str(d), "--exact-max", "40")
    assert bad.returncode == 2 and "26" in bad.stderr


def test_lorr_run_and_compare_record_an_audit_without_changing_results(tmp_path):
    from mrmt_env.lorr.instance import example_instance_path

    inst = str(example_instance_path())
    base = ["lorr", "run", inst, "--scheduler", "ising", "--steps", "40", "--json", "--no-progress"]
    plain = _mrmt(*base)
    audited = _mrmt(*base, "--audit", str(tmp_path / "l"))
    assert plain.returncode == audited.returncode == 0, audited.stderr

    def strip(out):  # timings, energy and memory differ run to run; counts and tasks do not
        row = json.loads(out.splitlines()[-1])
        return {k: v for k, v in row.items() if k not in MEASURED_KEYS}

    assert strip(plain.stdout) == strip(audited.stdout)
    assert {r["class"] for r in read_records(tmp_path / "l")} == {"sharing_split"}
    refused = _mrmt(*base, "--seeds", "2", "--backend", "process", "--audit", str(tmp_path / "x"))
    assert refused.returncode == 2 and "--backend inline" in refused.stderr
    r = _mrmt("compare", "--controllers", "ising", "--worlds", "1", "--jobs", "1", "--audit", str(tmp_path / "c"),
              "--no-progress")
    assert r.returncode == 0, r.stderr
    assert {"sharing_split", "tour_moves"} <= {x["class"] for x in read_records(tmp_path / "c")}
    refused = _mrmt("compare", "--controllers", "ising", "--worlds", "1", "--jobs", "2", "--audit", str(tmp_path / "d"))
    assert refused.returncode == 2 and "--jobs 1" in refused.stderr


def test_joint_moves_decisions_are_audited_against_pibt_and_charged_to_the_run(tmp_path):
    from agents.lorr.run import run_lorr
    from mrmt_env.lorr.instance import example_instance_path

    with Audit(tmp_path):
        record, _sim, _steps = run_lorr(example_instance_path(), "lorr-greedy", "pibt-ising", steps=60)
    rows = read_records(tmp_path)
    assert rows and {r["class"] for r in rows} == {"joint_moves"} and {r["host_rule"] for r in rows} == {"pibt"}
    assert record["chip_calls"] == sum(r["calls"] for r in rows) > 0  # the executor's chip calls are the run's
    for r, j in zip(rows, judge(rows)):
        assert j["host_energy"] == r["host_energy"] >= j["optimum"] - 1e-9
        assert j["chip_energy"] >= j["optimum"] - 1e-9


def test_lorr_run_host_rule_flag_reaches_the_executors_decision_class(tmp_path):
    from mrmt_env.lorr.instance import example_instance_path

    base = ["lorr", "run", str(example_instance_path()), "--scheduler", "lorr-greedy", "--planner", "epibt-ising",
            "--steps", "20", "--json", "--no-progress"]
    rows = {}
    for name, extra in (("chip", []), ("flag", ["--host-rule", "lns_groups", "--audit", str(tmp_path / "f")]),
                        ("option", ["--planner-option", "decider=host"])):
        r = _mrmt(*base, *extra)
        assert r.returncode == 0, r.stderr
        rows[name] = json.loads(r.stdout.splitlines()[-1])
    assert rows["chip"]["chip_calls"] > 0
    assert rows["flag"]["chip_calls"] == rows["option"]["chip_calls"] == 0
    keep = ("tasks_finished", "errands", "errors", "schedule_errors")
    assert {k: rows["flag"][k] for k in keep} == {k: rows["option"][k] for k in keep}
    assert [r for r in read_records(tmp_path / "f") if r["class"] == "lns_groups"] == []
