"""mrmt sweep: chip grids, rows per (spec, world, controller, seed), Pareto fronts, report files, CLI."""

from __future__ import annotations

import csv
import math

import pytest

from agents.cli import main
from agents.runner import RunConfig
from agents.sweep import MAX_SPECS, SweepConfig, chip_grid, parse_axes, run_sweep, spec_columns
from agents.sweep_report import pareto_front, spec_stats, write_report
from ising_backend import ChipSpec

INLINE = RunConfig(backend="inline", progress=False)


def test_grid_is_the_product_of_the_axes_last_axis_fastest():
    grid = chip_grid(parse_axes(["n_spins=32,64", "j_range=3,7,15"]))
    assert [(s.n_spins, s.j_range) for _, s in grid] == [
        (32, (-3, 3)), (32, (-7, 7)), (32, (-15, 15)), (64, (-3, 3)), (64, (-7, 7)), (64, (-15, 15))]
    assert grid[0][0] == {"n_spins": "32", "j_range": "3"}


def test_aliases_ranges_and_base_fields():
    base = ChipSpec(sweeps=20)
    (labels, spec), = chip_grid(parse_axes(["n_cores=32", "h_range=-3..5"]), base)
    assert (spec.n_chips, spec.cores_per_chip, spec.n_cores) == (32, 1, 32)
    assert spec.h_range == (-3, 5) and spec.sweeps == 20
    cols = spec_columns(spec)
    assert cols["h_range"] == "-3..5" and cols["j_range"] == 7 and cols["n_cores"] == 32


@pytest.mark.parametrize("items, match", [
    (["n_spin=32"], r"unknown chip field 'n_spin'.*valid fields"),
    (["bogus=1,2"], r"unknown chip field 'bogus'.*valid fields: n_spins.*n_cores, coef_range"),
    (["n_spins=32", "n_spins=45"], "given twice"),
    (["n_spins"], r"must look like KEY=VALUE \(e.g. n_spins=32,45,64\)"),
    (["n_spins=32,,45"], "empty value"),
    (["n_spins=32,32"], "lists a value twice"),
    (["n_spins=0"], "n_spins = 0 must be a positive integer"),
    (["n_cores=0"], "n_cores='0' must be a positive integer"),
    (["j_range=0"], "must be >= 1"),
])
def test_bad_axes_are_named(items, match):
    with pytest.raises(ValueError, match=match):
        chip_grid(parse_axes(items))


def test_a_grid_larger_than_the_limit_is_refused_before_any_work():
    many = ",".join(str(v) for v in range(8, 8 + 70))
    with pytest.raises(ValueError, match=f"at most {MAX_SPECS}"):
        chip_grid(parse_axes([f"n_spins={many}", f"sweeps={many}"]))


CHIP_PATHS = "ising+ising+ising"


@pytest.fixture(scope="module")
def small_sweep():
    # the chip's path layer (the ising preset's legs come from the BFS fields and fit a 4-spin chip)
    cfg = SweepConfig(axes=parse_axes(["n_spins=4,45,64"]), controllers=(CHIP_PATHS, "strong"), n_worlds=3)
    return run_sweep(cfg, INLINE)


def test_rows_per_spec_world_controller_and_seed(small_sweep):
    rows = small_sweep.rows
    ising = [r for r in rows if r["controller"] == CHIP_PATHS]
    strong = [r for r in rows if r["controller"] == "strong"]
    assert len(ising) == 3 * 3 and len(strong) == 3  # the chip-free controller runs once
    assert {r["spec_id"] for r in strong} == {-1} and "n_spins" not in strong[0]
    assert sorted({(r["n_spins"], r["world_seed"]) for r in ising}) == [
        (n, w) for n in (4, 45, 64) for w in (0, 1, 2)]


def test_a_chip_too_small_for_the_planner_is_a_failed_row_with_the_reason(small_sweep):
    tiny = [r for r in small_sweep.rows if r.get("n_spins") == 4]
    assert all(not r["is_success"] and "spins" in r["error"] for r in tiny)
    fine = [r for r in small_sweep.rows if r.get("n_spins") == 45]
    assert all(r["is_success"] and r["error"] == "" and r["chip_calls"] > 0 for r in fine)


def test_sweep_rows_equal_the_evaluation_of_the_same_spec(small_sweep):
    from agents.evaluation import evaluate

    ev = evaluate([CHIP_PATHS], n_worlds=3, chip=ChipSpec(n_spins=64), run=RunConfig.from_jobs(1, progress=False))
    mine = [r for r in small_sweep.rows if r.get("n_spins") == 64]
    keys = ("world_seed", "route_cost", "makespan", "chip_calls", "logical_calls", "accelerator_energy_j")
    assert [[r[k] for k in keys] for r in mine] == [[r[k] for k in keys] for r in ev.rows]


def test_stats_pareto_and_report_files(small_sweep, tmp_path):
    stats = spec_stats(small_sweep)
    by_spins = {s["n_spins"]: s for s in stats if s["spec_id"] >= 0}
    assert by_spins[4]["success_rate"] == 0.0 and by_spins[45]["success_rate"] == 1.0
    assert math.isfinite(by_spins[45]["mean_gap_pct"])
    assert by_spins[45]["fallbacks_per_plan"] == 0.0 and by_spins[45]["retries"] == 0.0
    front = pareto_front(stats, "accelerator_energy_j")
    assert front and all(s["success_rate"] == 1.0 for s in front)
    assert 4 not in {s["n_spins"] for s in front}
    files = write_report(small_sweep, tmp_path)
    assert {f.name for f in files} == {"sweep.csv", "sweep.json", "specs.csv", "pareto.png", "summary.md"}
    with open(tmp_path / "sweep.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(small_sweep.rows) and {"n_spins", "j_range", "route_cost", "error"} <= set(rows[0])
    md = (tmp_path / "summary.md").read_text()
    assert "Pareto-optimal specs" in md and "n_spins=45" in md


def test_pareto_front_keeps_only_undominated_full_success_specs():
    def s(i, cost, x, ok=1.0):
        return {"spec_id": i, "mean_gap_pct": cost, "e": x, "success_rate": ok}

    stats = [s(0, 1.0, 5.0), s(1, 2.0, 1.0), s(2, 2.0, 6.0), s(3, 0.5, 0.5, ok=0.9), s(4, 1.5, 3.0),
             {"spec_id": -1, "mean_gap_pct": 0.0, "e": 0.1, "success_rate": 1.0}]
    assert [x["spec_id"] for x in pareto_front(stats, "e", "mean_gap_pct")] == [1, 4, 0]


def test_a_fault_axis_counts_retries_and_fallbacks():
    cfg = SweepConfig(axes=parse_axes(["program_error_prob=0,0.3"]), controllers=("ising",), n_worlds=2)
    stats = {s["spec"]: s for s in spec_stats(run_sweep(cfg, INLINE), reference=None)}
    assert stats["program_error_prob=0"]["retries"] == 0
    assert stats["program_error_prob=0.3"]["retries"] > 0
    assert all(s["success_rate"] == 1.0 for s in stats.values())


def test_sweep_cli_writes_the_report(tmp_path, capsys):
    out = tmp_path / "sw"
    code = main(["sweep", "--chip", "j_range=7,15", "--worlds", "2", "--backend", "inline", "--out", str(out),
                 "--no-progress"])
    assert code == 0
    assert (out / "pareto.png").stat().st_size > 0
    assert "# Chip sweep" in capsys.readouterr().out


@pytest.mark.parametrize("argv, match", [
    (["--chip", "nspins=3"], "unknown chip field 'nspins'"),
    (["--chip", "n_spins=45", "--controllers", "strong"], "none of the controllers"),
    (["--chip", "n_spins=45", "--controllers", "ising", "--reference", "strong"], "--reference 'strong'"),
    (["--chip", "n_spins=45", "--worlds", "0"], "--worlds must be >= 1"),
    (["--chip", "n_spins=45", "--seed", "-1"], "--seed must be in"),
    (["--chip", "n_spins=45", "--controllers", "magic"], "unknown controller 'magic'"),
    (["--chip", "n_spins=45", "--base-chip", "sweeps=-1"], "sweeps = -1"),
    (["--chip", "n_spins=45", "--backend", "process", "--address", "1.2.3.4:1"], "--address is for --backend ray"),
])
def test_sweep_cli_bad_input_is_one_line_and_exit_2(argv, match, tmp_path, capsys):
    code = main(["sweep", *argv, "--out", str(tmp_path / "x"), "--no-progress"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and match in err and "Traceback" not in err


@pytest.mark.parametrize("axis", ["n_spins=abc", "sweeps=-1", "nspins=3"])
def test_a_bad_axis_value_is_named_before_anything_compiles(axis, tmp_path, capsys, monkeypatch):
    import agents.warmup

    compiled = []
    monkeypatch.setattr(agents.warmup, "warm", lambda *a, **k: compiled.append(a) or [])
    code = main(["sweep", "--chip", axis, "--worlds", "1", "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and axis.split("=")[0] in err
    assert compiled == []  # no compile notice or progress bar before the error


def test_step_limit_scales_with_the_world_and_is_an_option():
    from agents.evaluation import evaluate, step_limit

    assert step_limit("mrmt_env/MRMT-v0", {}) == 200
    assert step_limit("mrmt_env/MRMT-v0", {"height": 200, "width": 200}) == 4000
    assert step_limit("mrmt_env/MRMT-v0", {"height": 200, "width": 200, "n_targets": 20}) == 8000
    assert step_limit("mrmt_env/MRMT-5x5-v0", {}) == 50
    short = evaluate(["strong"], n_worlds=2, max_steps=3, run=RunConfig.from_jobs(1, progress=False))
    assert all(r["steps"] == 3 and r["truncated"] and not r["is_success"] for r in short.rows)
    assert short.config["max_steps"] == 3
    with pytest.raises(ValueError, match="max_steps = 0"):
        evaluate(["strong"], n_worlds=1, max_steps=0, run=RunConfig.from_jobs(1, progress=False))


@pytest.mark.parametrize("spread", [1.07, 1e3])  # a tiny sweep's points within a decade, and across decades
def test_pareto_tick_labels_do_not_overlap(spread):
    from agents.sweep_report import pareto_figure

    def spec(i, e):
        return {"spec_id": i, "success_rate": 1.0, "n_spins": 32 + 13 * i, "mean_cost": 28.0 - i,
                "mean_gap_pct": 1.0 - i, "controller": "ising",
                "accelerator_energy_j": e, "chip_time_parallel_s": e * 30, "total_energy_j": e * 400,
                "latency_parallel_s": e * 60, "h_range": 7, "j_range": 7, "n_cores": 8}
    stats = [spec(0, 5.25e-5), spec(1, 5.25e-5 * spread)]
    fig = pareto_figure(stats)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        for labels in (ax.get_xticklabels(which="both"), ax.get_yticklabels(which="both")):
            boxes = [t.get_window_extent(renderer) for t in labels if t.get_visible() and t.get_text()]
            assert all(not a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1:]), \
                [t.get_text() for t in labels]
    import matplotlib.pyplot as plt

    plt.close(fig)
