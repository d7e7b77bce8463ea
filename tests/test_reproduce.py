"""``mrmt reproduce --quick`` writes every file it promises; figures are valid PNGs."""

from __future__ import annotations

import csv
import json
import struct

import pytest

from agents.cli import main
from agents.experiments import PAPER, PAPER_SIZES, plot_experiment, ExperimentResult

EXPERIMENTS = ("path", "tour", "sharing", "endtoend")
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def assert_png(path):
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE, f"{path} is not a PNG"
    assert data[12:16] == b"IHDR"
    width, height = struct.unpack(">II", data[16:24])
    assert width >= 400 and height >= 200, (width, height)
    assert len(data) > 5000, f"{path} is suspiciously small ({len(data)} bytes)"
    assert data[-8:-4] == b"IEND", f"{path} is truncated (no IEND chunk at the end)"


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce")
    sizes = {"path": 12, "tour": 3, "sharing": 3, "endtoend": 2}
    args = ["reproduce", "--quick", "--out", str(out), "--no-progress", "--jobs", "2"]
    for k, v in sizes.items():
        args += [f"--{k}", str(v)]
    assert main(args) == 0
    return out, sizes


def test_every_promised_file(quick_run):
    out, sizes = quick_run
    for name in EXPERIMENTS + ("mapping",):
        assert (out / f"{name}.csv").is_file() and (out / f"{name}.json").is_file()
    for name in EXPERIMENTS:
        assert_png(out / f"fig_{name}.png")
    assert (out / "summary.md").is_file() and (out / "summary.json").is_file()


def test_rows_cover_every_method_and_instance(quick_run):
    out, sizes = quick_run
    from agents.experiments.paper import endtoend_methods

    methods = {"path": 4, "tour": 5, "sharing": 5, "endtoend": len(endtoend_methods())}  # + PyVRP when installed
    for name in EXPERIMENTS:
        with open(out / f"{name}.csv") as f:
            rows = list(csv.DictReader(f))
        assert len(rows) == sizes[name] * methods[name]
        assert {r["instance"] for r in rows} == {str(i) for i in range(sizes[name])}
        assert len(json.loads((out / f"{name}.json").read_text())) == len(rows)
    mapping = json.loads((out / "mapping.json").read_text())
    assert {m["layer"] for m in mapping} == {"path", "sharing"}
    if "pyvrp" in endtoend_methods():  # the classical peer: every plan valid, never above strong's route
        rows = json.loads((out / "endtoend.json").read_text())
        cost = {(r["instance"], r["method"]): r["cost"] for r in rows}
        peer = [r for r in rows if r["method"] == "pyvrp"]
        assert peer and all(r["success"] for r in peer)
        assert all(cost[(r["instance"], "pyvrp")] <= cost[(r["instance"], "strong")] for r in peer)


def test_summary_puts_measured_beside_paper(quick_run):
    out, _ = quick_run
    md = (out / "summary.md").read_text()
    for title in ("Pathfinding", "Tour construction", "Target sharing", "End-to-end", "Table 5"):
        assert title in md
    assert "| ssa median total | 28 |" in md
    assert "| ising median gap to strong (%) | 9.10 |" in md
    data = json.loads((out / "summary.json").read_text())
    assert set(data["measured"]) == set(EXPERIMENTS)
    assert data["measured"]["endtoend"]["strong success"] == "2/2"
    assert data["paper"]["sharing"]["ssa median total"] == PAPER["sharing"]["ssa median total"]


def test_paper_sizes_are_the_papers():
    assert PAPER_SIZES == {"path": 1000, "tour": 100, "sharing": 100, "endtoend": 100}


def test_plot_handles_methods_without_values(tmp_path):
    rows = [{"instance": 0, "method": m, "success": m == "a", "cost": 1.0, "time_s": 1e-3, "energy_j": 1e-2}
            for m in ("a", "b")]
    path = plot_experiment(ExperimentResult("path", rows, ("a", "b")), tmp_path / "f.png")
    assert_png(path)


def test_bad_arguments_exit_2(tmp_path, capsys):
    assert main(["reproduce", "--out", str(tmp_path), "--only", "path,warp"]) == 2
    assert "unknown experiment 'warp'" in capsys.readouterr().err
    assert main(["reproduce", "--out", str(tmp_path), "--path", "0"]) == 2
    assert "--path must be >= 1" in capsys.readouterr().err


def test_experiment_rows_deterministic_across_worker_counts():
    from agents.experiments import sharing_experiment

    keys = ("instance", "method", "success", "cost", "chip_calls", "chip_batches", "makespan")
    a = sharing_experiment(3, n_jobs=1, progress=False)
    b = sharing_experiment(3, n_jobs=2, progress=False)
    assert [tuple(r[k] for k in keys) for r in a.rows] == [tuple(r[k] for k in keys) for r in b.rows]
