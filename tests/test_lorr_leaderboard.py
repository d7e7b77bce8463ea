"""benchmarks/lorr.place: a row's place among the 2024 main round's teams, and the table it reads."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from benchmark_modules import load

lorr = load("lorr")
BOARD = json.loads(lorr.LEADERBOARD.read_text())
SHARED = Path(__file__).resolve().parents[2] / "shared" / "lorr"


def test_the_table_has_a_row_of_tasks_per_team_for_each_random_instance():
    assert BOARD["columns"] == lorr.RANDOM
    assert len(BOARD["teams"]) == 40
    for team, row in BOARD["teams"].items():
        assert len(row) == 5 and all(isinstance(v, int) and v >= 0 for v in row), team


@pytest.mark.skipif(not SHARED.is_dir(), reason="the LoRR instances (shared/lorr) are not beside the checkout")
def test_no_combined_entry_beats_the_archive_s_best_known():
    best = json.loads((SHARED / "best_known.json").read_text())["2024-main"]
    for k, name in enumerate(BOARD["columns"]):
        top = max(row[k] for row in BOARD["teams"].values())
        assert top <= best[name][2], name
    assert max(row[0] for row in BOARD["teams"].values()) == best["RANDOM-01"][2]  # RAPID's entry is the record


def test_place_counts_the_teams_that_finished_more():
    for k, name in enumerate(BOARD["columns"]):
        scores = sorted((row[k] for row in BOARD["teams"].values()), reverse=True)
        assert lorr.place(name, scores[0], BOARD) == (1, 40)
        assert lorr.place(name, scores[0] + 1, BOARD) == (1, 40)
        assert lorr.place(name, -1, BOARD) == (41, 40)
        for tasks in (scores[3], scores[3] - 1, scores[20]):
            assert lorr.place(name, tasks, BOARD) == (1 + len([s for s in scores if s > tasks]), 40)
    assert lorr.place("CITY-01", 100, BOARD) is None


def _row(instance, scheduler, executor, seed, tasks, best):
    return {"instance": instance, "robots": 700, "scheduler": scheduler, "executor": executor, "seed": seed,
            "steps": 1000, "tasks_finished": tasks, "best_known": best, "share_of_best": tasks / best,
            "step_p50_s": 0.1, "step_p99_s": 0.2, "errors": 0, "paper_energy_per_task_j": 0.001,
            "total_energy_per_task_j": 0.002, "peak_rss_mb": 200.0}


def test_the_summary_takes_each_instance_s_mean_over_its_seeds():
    rows = [_row("RANDOM-04", "s", "e", 0, 1300, 2600), _row("RANDOM-04", "s", "e", 1, 1040, 2600),
            _row("RANDOM-01", "s", "e", 0, 557, 696), {**_row("CITY-01", "s", "e", 0, 5, 8445), "share_of_best": None}]
    got = lorr.summary(rows)
    assert set(got) == {("s", "e")} and set(got["s", "e"]) == {"RANDOM-04", "RANDOM-01"}
    share, tasks, n = got["s", "e"]["RANDOM-04"]
    assert (tasks, n) == (1170, 2) and share == pytest.approx(0.45)
    assert got["s", "e"]["RANDOM-01"] == (pytest.approx(557 / 696), 557, 1)


def test_the_benchmark_runs_every_row_once_per_seed_and_places_the_means(monkeypatch, capsys):
    calls = []

    def one(name, scheduler, spec, steps, options, seed=0):
        calls.append((name, scheduler, spec, seed))
        return _row(name, scheduler, spec, seed, 1000 + 300 * seed, 2585)

    monkeypatch.setattr(lorr, "_one", one)
    lorr.main(["--instances", "RANDOM-04", "--executors", "epibt", "--schedulers", "lorr-greedy",
               "--seeds", "0,1", "--scale", ""])
    out = capsys.readouterr().out
    assert calls == [("RANDOM-04", "lorr-greedy", "epibt", 0), ("RANDOM-04", "lorr-greedy", "epibt", 1)]
    assert "| RANDOM-04 | 700 | lorr-greedy | epibt | 1 | 1000 | 1300 |" in out
    assert "| lorr-greedy | epibt | 2 | 44.5 % | 44.5 % | +0.0 % |" in out  # (1000 + 1300) / 2 of 2585
    assert "| lorr-greedy | epibt | 3 |" in out  # 1,150 tasks: behind No Man's Sky and Kitty Knight, ahead of 1,051
