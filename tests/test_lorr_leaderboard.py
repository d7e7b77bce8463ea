"""benchmarks/lorr.place: a row's place among the 2024 main round's teams, and the table it reads."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

_spec = importlib.util.spec_from_file_location("bench_lorr", Path(__file__).resolve().parents[1] / "benchmarks" / "lorr.py")
lorr = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(lorr)
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
