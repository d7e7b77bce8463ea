"""``--chip`` on ``mrmt compare`` and ``evaluate(chip=...)``: the Ising planners run on the chip given."""

from __future__ import annotations

import pytest

from agents.cli import main
from agents.errors import ControllerError
from agents.evaluation import evaluate, make_controller, uses_chip
from agents.runner import RunConfig
from ising_backend import ChipSpec


def test_uses_chip_reads_presets_and_layer_triples():
    assert uses_chip("ising") and uses_chip("ssa+3opt+ising") and uses_chip("ising+3opt+astar")
    assert not uses_chip("strong") and not uses_chip("fast") and not uses_chip("ssa+3opt+astar")


def test_make_controller_builds_the_ising_layers_on_the_given_chip():
    spec = ChipSpec(n_spins=64, j_range=(-15, 15), cores_per_chip=4)
    policy = make_controller("ising", chip=spec)
    pipe = policy.pipeline
    assert pipe.sharing.chip is pipe.tour.chip  # one chip per pipeline (the legs come from the BFS field)
    assert pipe.tour.chip.spec == spec and pipe.path.name == "field"
    classical = make_controller("strong", chip=spec)  # no chip to use: the plain preset
    assert classical.name == "strong"


def test_evaluate_with_a_chip_uses_its_accounting_numbers():
    slow = ChipSpec(solve_time_s=100e-6)  # twice the paper's 50 us per call (and so twice the energy)
    base = evaluate("ising", n_worlds=2, env_kwargs={"n_targets": 6}, run=RunConfig.from_jobs(1, progress=False))
    res = evaluate("ising", n_worlds=2, env_kwargs={"n_targets": 6}, chip=slow,
                   run=RunConfig.from_jobs(1, progress=False))
    assert res.config["chip"]["solve_time_s"] == 100e-6 and base.config["chip"] is None
    for a, b in zip(base.rows, res.rows):
        assert a["route_cost"] == b["route_cost"] and a["chip_calls"] == b["chip_calls"]
        assert b["chip_time_s"] == pytest.approx(2 * a["chip_time_s"])
        assert b["accelerator_energy_j"] == pytest.approx(2 * a["accelerator_energy_j"])


def test_a_chip_without_a_chip_controller_is_refused():
    with pytest.raises(ControllerError, match="none of the controllers"):
        evaluate("fast,strong", n_worlds=1, chip=ChipSpec(n_spins=64), run=RunConfig.from_jobs(1, progress=False))


def test_compare_chip_option_errors_are_one_line(capsys):
    assert main(["compare", "--worlds", "1", "--controllers", "strong", "--chip", "n_spins=64", "--jobs", "1",
                 "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "none of the controllers" in err[0]
    assert main(["compare", "--worlds", "1", "--controllers", "ising", "--chip", "bogus=1", "--jobs", "1",
                 "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown chip field 'bogus'" in err[0]


def test_reproduce_runs_the_ising_methods_on_the_given_chip(tmp_path, capsys):
    import json

    out = tmp_path / "r"
    rc = main(["reproduce", "--quick", "--out", str(out), "--jobs", "1", "--no-progress", "--path", "5", "--tour", "2",
               "--sharing", "2", "--endtoend", "2", "--chip", "solve_time_s=0.0001"])
    assert rc == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["chip"]["solve_time_s"] == 0.0001
    rows = json.loads((out / "endtoend.json").read_text())
    ising = [r for r in rows if r["method"] == "ising"]
    assert len(ising) == 2 and all(r["success"] and r["chip_calls"] > 0 for r in ising)
    # 100 us per call: the chip time is calls x 100 us
    assert all(r["chip_time_s"] == pytest.approx((r["chip_calls"] + r["logical_calls"]) * 1e-4) for r in ising)
    assert main(["reproduce", "--quick", "--out", str(out), "--chip", "n_spins=x"]) == 2
    assert "n_spins = 'x' must be an integer" in capsys.readouterr().err
