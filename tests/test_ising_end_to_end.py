"""The Ising presets end to end, through the public API and the command line, on every chip kind.

Validity on many seeded worlds of every map family, the accounting identities of the records
that `mrmt compare` and `mrmt reproduce` write, and plans identical across fresh interpreters.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from agents.cli import main
from ising_backend import ChipSpec, EmulatedChip, MachineSpec
from mrmt_env.generation import generate_world
from planners.compute import CPU_WATTS_PER_CORE
from planners.pipeline import make_pipeline
from planners.plan import validate_plan

ROOT = Path(__file__).resolve().parents[1]
FAULTS = {"readout_flip_prob": 0.01, "dead_cores": 1, "stuck_spins": 2}
CHIPS = {
    "healthy": lambda: EmulatedChip(),
    "faulty": lambda: EmulatedChip(ChipSpec(**FAULTS)),
    "dwave-sa": lambda: MachineSpec(ChipSpec(), "dwave-sa", (("num_sweeps", 100),)).build(),
}
FAMILIES = {"uniform": {}, "warehouse": {}, "rooms": {}, "maze": {}}


def _worlds(layout: str, n: int):
    size = 10 if layout == "uniform" else 16
    return [generate_world(1000 + k, height=size, width=size, n_robots=2 + k % 2, n_targets=6 + 2 * k,
                           layout=layout, placement=("uniform", "centre")[k % 2]) for k in range(n)]


@pytest.mark.parametrize("chip", list(CHIPS))
@pytest.mark.parametrize("preset", ["ising", "ising-paper"])
def test_ising_presets_plan_valid_routes_on_every_map_family(preset, chip):
    machine = CHIPS[chip]()
    pipe = make_pipeline(preset, chip=machine)
    n = 2 if chip == "dwave-sa" else 3
    for layout in FAMILIES:
        for k, world in enumerate(_worlds(layout, n)):
            before, before_logical = machine.ledger.physical_calls, machine.ledger.logical_calls
            plan = pipe.plan(world, seed=k)
            assert plan.success, (layout, k, plan.failure)
            validate_plan(world, plan)  # raises on any invalid route
            c = plan.compute
            assert c.chip_calls == machine.ledger.physical_calls - before > 0  # the chip decided something
            assert c.logical_calls == machine.ledger.logical_calls - before_logical  # ising-paper's tour
            assert c.fallbacks == 0 and "fallback" not in plan.stats
            spec = machine.spec
            assert c.accelerator_energy_j == pytest.approx((c.chip_calls + c.logical_calls) * spec.energy_per_call_j)
            assert c.chip_time_s == pytest.approx((c.chip_calls + c.logical_calls) * spec.solve_time_s)


def _check_record_identities(row: dict) -> None:
    assert row["host_cpu_s"] == pytest.approx(row["cpu_s"] - row["emulation_s"], abs=1e-12)
    assert row["host_energy_j"] == pytest.approx(CPU_WATTS_PER_CORE * row["host_cpu_s"], rel=1e-9, abs=1e-12)
    assert row["latency_s"] == pytest.approx(row["host_cpu_s"] + row["chip_time_s"], rel=1e-9, abs=1e-12)
    calls = row["chip_calls"] + row["logical_calls"]
    spec = ChipSpec()
    assert row["accelerator_energy_j"] == pytest.approx(calls * spec.energy_per_call_j, rel=1e-9, abs=1e-15)
    assert row["chip_time_s"] == pytest.approx(calls * spec.solve_time_s, rel=1e-9, abs=1e-15)
    assert row["total_energy_j"] == pytest.approx(row["host_energy_j"] + row["accelerator_energy_j"], rel=1e-9)


def test_compare_records_keep_the_accounting_identities(tmp_path):
    out = tmp_path / "cmp"
    assert main(["compare", "--worlds", "3", "--controllers", "ising,ising-paper,strong", "--out", str(out),
                 "--jobs", "1", "--no-progress"]) == 0
    rows = json.loads((out / "episodes.json").read_text())
    rows = rows["rows"]
    ising = [r for r in rows if r["controller"].startswith("ising")]
    strong = [r for r in rows if r["controller"] == "strong"]
    assert len(ising) == 6 and len(strong) == 3
    for r in ising:
        assert r["is_success"] and r["chip_calls"] > 0 and r["emulation_s"] > 0
        _check_record_identities(r)
    for r in strong:
        assert r["chip_calls"] == r["logical_calls"] == 0 and r["emulation_s"] == 0
        _check_record_identities(r)


def test_reproduce_records_keep_the_accounting_identities(tmp_path):
    out = tmp_path / "r"
    assert main(["reproduce", "--quick", "--out", str(out), "--jobs", "1", "--no-progress", "--path", "3",
                 "--tour", "2", "--sharing", "2", "--endtoend", "3"]) == 0
    rows = json.loads((out / "endtoend.json").read_text())
    ising = [r for r in rows if r["method"] == "ising"]
    assert len(ising) == 3
    for r in ising:
        assert r["success"] and r["failure"] in (None, "") and np.isfinite(r["cost"])
        assert r["chip_calls"] > 0 and r["fallbacks"] == 0
        assert r["chip_calls"] == r["sharing_chip_calls"] + r["tour_chip_calls"] + r["path_chip_calls"]
        _check_record_identities(r)


def test_mrmt_plan_gives_the_same_plans_in_fresh_interpreters(tmp_path):
    worlds = ROOT / "mrmt_env" / "data" / "example_worlds.jsonl"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    outs = []
    for k in range(2):
        out = tmp_path / f"plans{k}.jsonl"
        proc = subprocess.run([sys.executable, "-m", "agents.cli", "plan", str(worlds), "--pipeline", "ising",
                               "--seed", "3", "--out", str(out), "--no-progress"], cwd=ROOT, env=env,
                              capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, proc.stderr[-2000:]
        rows = [json.loads(line) for line in out.read_text().splitlines()]
        for r in rows:  # measured times differ from run to run; everything else must not
            for key in ("cpu_s", "emulation_s", "host_cpu_s", "latency_s", "latency_parallel_s", "host_energy_j",
                        "total_energy_j", "warmup_s"):
                r["compute"].pop(key, None)
        outs.append(rows)
    assert outs[0] == outs[1] and len(outs[0]) >= 3
    assert all(r["success"] and r["compute"]["chip_calls"] > 0 for r in outs[0])
    assert np.isfinite([r["route_cost"] for r in outs[0]]).all()
