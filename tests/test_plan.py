"""Plan metrics, serialisation and the validator (every kind of bad plan)."""

import numpy as np
import pytest

from mrmt_env import World
from planners.compute import RECORD_KEYS, ComputeReport
from planners.plan import Plan, PlanError, RobotRoute, validate_plan

# 4x5 grid, obstacle column at (0..2, 2)
GRID = np.zeros((4, 5), dtype=bool)
GRID[0:3, 2] = True
WORLD = World(GRID, [[0, 0], [0, 4]], [[2, 0], [3, 2], [0, 3]])


def good_plan():
    r0 = RobotRoute((0, 1), [[0, 0], [1, 0], [2, 0], [3, 0], [3, 1], [3, 2]])
    r1 = RobotRoute((2,), [[0, 4], [0, 3]])
    return Plan((r0, r1), compute=ComputeReport(cpu_s=0.002))


def test_good_plan_and_metrics():
    plan = good_plan()
    validate_plan(WORLD, plan)
    assert plan.lengths == [5, 1]
    assert (plan.route_cost, plan.makespan, plan.imbalance) == (6, 5, 4)
    d = plan.to_dict()
    assert d["robots"][0] == {"targets": [0, 1], "path": [[0, 0], [1, 0], [2, 0], [3, 0], [3, 1], [3, 2]]}
    assert (d["route_cost"], d["makespan"], d["imbalance"], d["success"]) == (6, 5, 4, True)
    assert d["compute"]["host_energy_j"] == pytest.approx(0.002 * 15)
    assert set(d["compute"]) == set(RECORD_KEYS) >= {"cpu_s", "emulation_s", "host_cpu_s", "host_energy_j", "chip_calls",
                                 "chip_batches", "logical_calls", "chip_time_s", "chip_time_parallel_s",
                                 "accelerator_energy_j"}


def test_emulation_time_is_not_charged_as_host_energy():
    rep = ComputeReport(cpu_s=0.010, chip_calls=4, emulation_s=0.004)
    assert rep.host_cpu_s == pytest.approx(0.006)
    assert rep.host_energy_j == pytest.approx(0.006 * 15)
    assert (rep + rep).emulation_s == pytest.approx(0.008)
    d = rep.to_dict()
    assert (d["emulation_s"], d["host_cpu_s"]) == (pytest.approx(0.004), pytest.approx(0.006))


def test_ising_layer_reports_its_emulation_time():
    from mrmt_env import generate_world
    from planners.pipeline import make_pipeline

    world = generate_world(3, n_robots=1, n_targets=1)
    plan = make_pipeline(sharing="ssa", tour="nn", path="ising").plan(world, seed=0)
    c = plan.compute
    assert c.chip_calls > 0
    assert 0.0 < c.emulation_s <= c.cpu_s
    assert c.host_cpu_s == pytest.approx(c.cpu_s - c.emulation_s)


def _with(route0=None, route1=None):
    plan = good_plan()
    return Plan((route0 or plan.routes[0], route1 or plan.routes[1]))


@pytest.mark.parametrize(
    "plan, message",
    [
        (_with(route0=RobotRoute((0, 1), [[0, 0], [1, 0], [2, 0], [3, 0], [3, 1], [2, 1], [2, 2], [3, 2]])),
         r"robot 0 step 6: cell \[2, 2\] is an obstacle"),
        (_with(route0=RobotRoute((0, 1), [[0, 0], [2, 0], [3, 0], [3, 1], [3, 2]])),
         r"robot 0 step 1: jump from \[0, 0\] to \[2, 0\]"),
        (_with(route1=RobotRoute((2,), [[1, 4], [0, 4], [0, 3]])),
         r"robot 1: path starts at \[1, 4\], not at its start cell \[0, 4\]"),
        (_with(route1=RobotRoute((), [[0, 4]])), r"targets \[2\] are not assigned"),
        (_with(route1=RobotRoute((2, 0), [[0, 4], [0, 3]])), r"robot 1: target 0 is already assigned to robot 0"),
        (_with(route1=RobotRoute((2, 5), [[0, 4], [0, 3]])), r"robot 1: target index 5 out of range 0..2"),
        (_with(route1=RobotRoute((2,), [[0, 4]])), r"robot 1: path never reaches target 2 at \[0, 3\]"),
        (_with(route0=RobotRoute((1, 0), [[0, 0], [1, 0], [2, 0], [3, 0], [3, 1], [3, 2]])),
         r"robot 0: path never reaches target 0 .* listed order"),
        (_with(route1=RobotRoute((2,), [[0, 4], [0, 5], [0, 3]])), r"robot 1 step 1: cell \[0, 5\] is off the 4x5 grid"),
        (Plan((good_plan().routes[0],)), r"plan has 1 routes for 2 robots"),
        (_with(route1=RobotRoute((2,), np.zeros((0, 2)))), r"robot 1: empty path"),
    ],
    ids=["obstacle", "jump", "wrong-start", "missed", "double", "index", "unreached", "order", "off-grid",
         "robots", "empty"],
)
def test_validator_catches_each_bad_plan(plan, message):
    with pytest.raises(PlanError, match=message):
        validate_plan(WORLD, plan)


def test_partial_plan_allowed_when_not_requiring_complete():
    plan = _with(route1=RobotRoute((), [[0, 4]]))
    validate_plan(WORLD, plan, require_complete=False)
    with pytest.raises(PlanError):
        validate_plan(WORLD, plan)


def test_compute_reports_add():
    a = ComputeReport(cpu_s=1.0, chip_calls=2, chip_batches=1, chip_time_s=1e-4, accelerator_energy_j=9e-7)
    b = ComputeReport(cpu_s=0.5, logical_calls=3)
    c = a + b
    assert (c.cpu_s, c.chip_calls, c.logical_calls, c.chip_batches) == (1.5, 2, 3, 1)
    assert c.total_energy_j == pytest.approx(1.5 * 15 + 9e-7)
    assert a.replace(cpu_s=0.0).chip_calls == 2
    # every field adds, whatever its place in the dataclass
    from dataclasses import fields

    names = [f.name for f in fields(ComputeReport)]
    x = ComputeReport(**{n: i + 1 for i, n in enumerate(names)})
    y = ComputeReport(**{n: 10 * (i + 1) for i, n in enumerate(names)})
    assert [getattr(x + y, n) for n in names] == [11 * (i + 1) for i in range(len(names))]


def test_reused_ising_pipeline_reports_bit_identical_accelerator_figures():
    # the layers charge themselves from ledger snapshots; a pipeline that has already
    # planned (larger running totals) must report exactly what a fresh one reports
    from mrmt_env import generate_world
    from planners.pipeline import make_pipeline

    world = generate_world(1, placement="centre")
    reused = make_pipeline("ising")
    reused.plan(generate_world(2, placement="centre"), seed=0)
    a = reused.plan(world, seed=3).compute
    b = make_pipeline("ising").plan(world, seed=3).compute
    # counts, chip times and energies, bit for bit (cpu_s is measured wall time)
    assert a.replace(cpu_s=0.0) == b.replace(cpu_s=0.0)
    assert (a.chip_time_s, a.accelerator_energy_j) == (b.chip_time_s, b.accelerator_energy_j)


def test_planners_do_not_import_the_env_classes():
    # layering (ARCHITECTURE.md): planners use the world model, never the envs
    import subprocess
    import sys

    code = ("import sys, planners.pipeline, planners.ising.path, planners.ising.tour, planners.ising.sharing; "
            "print(sorted(m for m in sys.modules if m in ('mrmt_env.grid.env', 'mrmt_env.grid.pz', 'agents')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_to_record_reports_system_and_paper_figures_side_by_side():
    rep = ComputeReport(cpu_s=0.010, chip_calls=4, chip_batches=1, chip_time_s=200e-6, chip_time_parallel_s=50e-6,
                        accelerator_energy_j=1.8e-6, emulation_s=0.004)
    d = rep.to_record()
    assert tuple(d) == RECORD_KEYS
    assert d["latency_s"] == pytest.approx(0.006 + 200e-6)
    assert d["latency_parallel_s"] == pytest.approx(0.006 + 50e-6)
    assert d["total_energy_j"] == pytest.approx(1.8e-6 + 0.006 * 15)
    # the paper's convention: an accelerated method is charged its accelerator only
    assert (d["paper_time_s"], d["paper_energy_j"]) == (pytest.approx(200e-6), pytest.approx(1.8e-6))
    classical = ComputeReport(cpu_s=0.001).to_record()
    assert (classical["paper_time_s"], classical["paper_energy_j"]) == (pytest.approx(0.001), pytest.approx(0.015))
    assert rep.to_record(accelerated=False)["paper_energy_j"] == pytest.approx(0.006 * 15)
