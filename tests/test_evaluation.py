"""The evaluation runner and ``mrmt compare``."""

from __future__ import annotations

import csv
import json

import pytest

from agents.cli import main
from agents.evaluation import (
    COMPUTE_KEYS,
    ROUTE_KEYS,
    ControllerError,
    evaluate,
    parse_controllers,
)
from agents.runner import RunConfig

SMALL = {"n_robots": 2, "n_targets": 5}


def _route_view(rows):
    return [(r["controller"], r["seed"], r["world_seed"]) + tuple(r[k] for k in ROUTE_KEYS) for r in rows]


def test_rows_join_route_metrics_and_compute(tmp_path):
    res = evaluate("fast,strong", n_worlds=3, seeds=[0, 1], env_kwargs=SMALL,
                   run=RunConfig.from_jobs(1, progress=False))
    assert len(res.rows) == 2 * 2 * 3
    for r in res.rows:
        assert set(ROUTE_KEYS) <= set(r) and set(COMPUTE_KEYS) <= set(r)
        assert r["is_success"] and r["route_cost"] == r["plan_route_cost"]
        assert r["chip_calls"] == 0 and r["accelerator_energy_j"] == 0.0
        assert r["cpu_s"] > 0 and r["host_energy_j"] == pytest.approx(15.0 * r["cpu_s"])
        assert r["latency_s"] == pytest.approx(r["cpu_s"] + r["chip_time_s"])
    # the same worlds for every controller: same target counts per world seed, and
    # a better planner is never worse in total across them (strong >= fast quality)
    fast = {r["world_seed"]: r for r in res.by_controller("fast")}
    strong = {r["world_seed"]: r for r in res.by_controller("strong")}
    assert fast.keys() == strong.keys() == {0, 1, 2}
    assert sum(r["route_cost"] for r in strong.values()) <= sum(r["route_cost"] for r in fast.values())

    csv_path = res.to_csv(tmp_path / "ep.csv")
    json_path = res.to_json(tmp_path / "ep.json")
    with open(csv_path) as f:
        assert len(list(csv.DictReader(f))) == len(res.rows)
    data = json.loads(json_path.read_text())
    assert len(data["rows"]) == len(res.rows) and data["config"]["controllers"] == ["fast", "strong"]
    table = res.format_summary()
    assert "fast" in table and "strong" in table and "100%" in table


def test_deterministic_and_pool_matches_inline():
    a = evaluate(["strong"], n_worlds=3, env_kwargs=SMALL, run=RunConfig.from_jobs(1, progress=False))
    b = evaluate(["strong"], n_worlds=3, env_kwargs=SMALL, run=RunConfig.from_jobs(2, progress=False))
    assert _route_view(a.rows) == _route_view(b.rows)


def test_layer_triple_controller():
    res = evaluate(["ssa+brute+bfs"], n_worlds=2, env_kwargs=SMALL, run=RunConfig.from_jobs(1, progress=False))
    assert all(r["is_success"] for r in res.rows)


def test_ising_controller_reports_chip_compute():
    pytest.importorskip("planners.ising.path")
    res = evaluate(["ising"], n_worlds=1, env_kwargs=SMALL, run=RunConfig.from_jobs(1, progress=False))
    (row,) = res.rows
    assert row["chip_calls"] > 0 and row["accelerator_energy_j"] > 0
    assert row["chip_time_parallel_s"] <= row["chip_time_s"]
    if row["plan_success"]:
        assert row["is_success"] and row["route_cost"] == row["plan_route_cost"]


@pytest.mark.parametrize(
    "text, match",
    [
        ("fast,bogus", "unknown controller 'bogus'"),
        ("fast,fast", "listed twice"),
        ("ssa+nope+astar", "unknown tour method 'nope'"),
        ("ppo:", "needs a model path"),
        ("ppo:/no/such/model.zip", "does not exist"),
    ],
)
def test_bad_controller_specs(text, match):
    with pytest.raises(ControllerError, match=match):
        parse_controllers(text)


def test_compare_cli_errors_are_one_line_exit_2(tmp_path, capsys):
    assert main(["compare", "--controllers", "fast,warp-drive", "--worlds", "1", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "warp-drive" in err
    notzip = tmp_path / "model.zip"
    notzip.write_text("not a model")
    assert main(["compare", "--controllers", f"strong,ppo:{notzip}", "--worlds", "1", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "not a stable-baselines3" in err
    assert main(["compare", "--controllers", "ppo:missing.zip", "--worlds", "1", "--no-progress"]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["compare", "--worlds", "0", "--controllers", "fast", "--no-progress"]) == 2
    assert "--worlds must be >= 1" in capsys.readouterr().err


def test_compare_cli_writes_table_and_files(tmp_path, capsys):
    code = main([
        "compare", "--worlds", "2", "--robots", "2", "--targets", "4", "--controllers", "fast,strong",
        "--jobs", "1", "--out", str(tmp_path), "--no-progress",
    ])
    assert code == 0
    out = capsys.readouterr().out
    assert "strong" in out and "cost" in out
    assert (tmp_path / "episodes.csv").is_file() and (tmp_path / "episodes.json").is_file()
    assert len(json.loads((tmp_path / "episodes.json").read_text())["rows"]) == 4


def test_ising_route_metrics_do_not_depend_on_workers():
    pytest.importorskip("planners.ising.path")
    a = evaluate(["ising"], n_worlds=2, env_kwargs=SMALL, run=RunConfig.from_jobs(1, progress=False))
    b = evaluate(["ising"], n_worlds=2, env_kwargs=SMALL, run=RunConfig.from_jobs(2, progress=False))
    assert _route_view(a.rows) == _route_view(b.rows)
    assert [r["chip_calls"] for r in a.rows] == [r["chip_calls"] for r in b.rows]


def test_si_units_round_before_choosing_the_prefix():
    from agents.evaluation import _si

    assert _si(0.0009996, "s") == "1 ms"
    assert _si(0.000123456, "s") == "123 us"
    assert _si(1.5e-5, "J") == "15 uJ"
    assert _si(0.0, "J") == "0 J" and _si(float("nan"), "s") == "-"


def _fast_policy(seed):
    from agents.policy import PlannerPolicy

    return PlannerPolicy("fast", seed=seed)


def test_summary_shows_long_controller_labels_whole():
    label = "fast pipeline, a label longer than the column"
    res = evaluate([(label, _fast_policy)], n_worlds=1, env_kwargs=SMALL, run=RunConfig.from_jobs(1, progress=False))
    header, row = res.format_summary().splitlines()[:2]
    assert row.startswith(label + " ") and "..." not in row
    assert header.startswith("controller".ljust(len(label)) + " ")  # the column widens to the label
