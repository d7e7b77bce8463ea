"""Any Ising machine behind the League's chip planners: ``--chip`` / ``--sampler`` reach ``epibt-ising`` and
``pibt-ising``, the machine's size shapes the neighbourhoods, the host-rule twin poses the same groups without a
call, and ``mrmt lorr sweep`` runs a grid of machines beside their twins."""

from __future__ import annotations

import csv
import json
import subprocess
import sys

import numpy as np
import pytest

from agents.lorr.run import make_roles, run_lorr
from ising_backend import ChipSpec, EmulatedChip, MachineSpec, SamplerChip
from ising_backend.audit.host_rule import HostRule
from mrmt_env.lorr.instance import example_instance_path, read_instance
from mrmt_env.lorr.loop import StepLoop
from mrmt_env.lorr.sim import LoRRSimulator
from agents.lorr.spec import PlannerSpec, SchedulerSpec
from planners.mapf import make_turning_planner
from test_mapf_turning import apply, random_instance, retarget

EXAMPLE = example_instance_path()


def _mrmt(*args, timeout=600):
    return subprocess.run([sys.executable, "-m", "agents.cli", *args], capture_output=True, text=True, timeout=timeout)


@pytest.mark.parametrize("spins, robots", [(45, 11), (64, 16), (16, 4), (8, 2), (120, 22)])
def test_group_size_follows_the_machines_spins_unless_given(spins, robots):
    rng = np.random.default_rng(1)
    grid = random_instance(rng, 8, 8, 0.1, 0.5)[0]
    chip = EmulatedChip(ChipSpec(n_spins=spins), seed=0)

    def limits(**options):
        return make_turning_planner("epibt-ising", grid, machine=options.pop("machine", None),
                                    **options).machine_step.rounds_.limits

    assert limits(machine=chip).max_robots == robots
    assert limits(machine=chip, max_robots=2).max_robots == 2
    twin = make_turning_planner("epibt-ising", grid, machine=chip, decider="host")  # shaped by it, never calling it
    lim = twin.machine_step.rounds_.limits
    assert (lim.max_robots, lim.max_spins, twin.machine) == (robots, spins, None)
    assert limits().max_robots == 11  # the paper's chip: as before the option followed the machine


def test_the_twin_of_a_larger_machine_poses_its_groups_and_answers_as_the_host_rule():
    rng = np.random.default_rng(8)
    grid, free, pos, orient, goals = random_instance(rng, 10, 10, 0.12, 0.6)
    spec = ChipSpec(n_spins=64)
    twin = make_turning_planner("epibt-ising", grid, seed=2, machine=EmulatedChip(spec, seed=3), decider="host", lns=0,
                                groups=8)
    chip = EmulatedChip(spec, seed=3)
    flagged = make_turning_planner("epibt-ising", grid, seed=2, machine=chip, lns=0, groups=8)
    for _ in range(12):
        a1 = twin.actions(pos, orient, goals)
        with HostRule("all"):
            a2 = flagged.actions(pos, orient, goals)
        assert np.array_equal(a1, a2)
        pos, orient, err = apply(grid, pos, orient, a1)
        assert err is None
        goals = retarget(rng, free, pos, goals)
    assert flagged.machine_step.stats["decisions"] == twin.machine_step.stats["decisions"] > 0
    assert chip.ledger.physical_calls == 0


def _drive(chip, planner="epibt-ising", steps=6, options=None):
    """A League run by hand: the roles ``make_roles`` builds for ``chip``, the chip calls each step reports."""
    inst = read_instance(EXAMPLE)
    sched, ex = make_roles(inst.grid, SchedulerSpec("lorr-greedy"), PlannerSpec.of(planner, options), seed=0,
                           chip=chip)
    loop = StepLoop(LoRRSimulator(inst), sched)
    sim = loop.sim
    calls = 0
    for _ in range(steps):
        loop.propose()
        actions = ex.actions(sim.pos, sim.orient, loop.goal_cells())
        calls += ex.last_compute.chip_calls
        loop.advance(actions)
    return ex, calls


@pytest.mark.parametrize("chip, kind", [
    (ChipSpec(n_spins=64), EmulatedChip),
    (ChipSpec(n_spins=45, stuck_spins=3), EmulatedChip),  # a faulty chip: fewer usable spins, the same planner
    (MachineSpec(ChipSpec(), "dwave-greedy"), SamplerChip),  # a dimod sampler held to the paper's spec
])
def test_the_run_gives_the_chip_planner_the_machine_it_names(chip, kind):
    ex, calls = _drive(chip, options={"lns": 0, "groups": 8})
    spec = chip if isinstance(chip, ChipSpec) else chip.spec
    assert isinstance(ex.machine, kind) and ex.machine.spec.n_spins == spec.n_spins
    assert ex.machine_step.rounds_.limits.max_spins == ex.machine.usable_spins
    ledger = ex.machine.ledger  # each step's report against the machine's own ledger (a faulty chip's probe apart)
    assert calls == ledger.physical_calls - ledger.probe_calls > 0


def test_pibt_ising_takes_the_machine_too():
    ex, calls = _drive(ChipSpec(n_spins=32), planner="pibt-ising", steps=8)
    assert ex.machine.spec.n_spins == 32 and ex.machine_step.max_spins == 32
    assert calls == ex.machine.ledger.physical_calls


def test_a_machine_nothing_runs_on_is_refused_not_dropped():
    inst = read_instance(EXAMPLE)
    with pytest.raises(ValueError, match="neither the scheduler 'lorr-greedy' nor the planner 'pibt'"):
        make_roles(inst.grid, SchedulerSpec("lorr-greedy"), PlannerSpec.of("pibt"), chip=ChipSpec(n_spins=64))
    make_roles(inst.grid, SchedulerSpec("ising"), PlannerSpec.of("pibt"), chip=ChipSpec(n_spins=64))  # it runs on it
    proc = _mrmt("lorr", "run", str(EXAMPLE), "--planner", "epibt", "--chip", "n_spins=64", "--no-progress")
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "neither the scheduler 'lorr-greedy' nor the planner 'epibt'" in lines[0]


def test_sweep_runs_each_machine_beside_its_twin_and_sums_what_the_runs_say(tmp_path):
    out = tmp_path / "sw"
    proc = _mrmt("lorr", "sweep", str(EXAMPLE), "--planner", "epibt-ising", "--planner-option", "lns=0",
                 "--planner-option", "groups=8", "--chip", "n_spins=16,64", "--steps", "30", "--seeds", "2",
                 "--jobs", "1", "--no-progress", "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    with open(out / "sweep.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 2 * 2 * 2  # specs x seeds x (machine, host rule)
    assert {(r["spec"], r["decider"], r["seed"]) for r in rows} == {
        (f"n_spins={n}", d, str(s)) for n in (16, 64) for d in ("machine", "host rule") for s in (0, 1)}
    assert all(int(r["chip_calls"]) == 0 for r in rows if r["decider"] == "host rule")
    assert all(int(r["chip_calls"]) > 0 for r in rows if r["decider"] == "machine")
    summary = json.loads((out / "sweep.json").read_text())["summary"]
    for s in summary:
        mine = [r for r in rows if r["spec"] == s["spec"]]
        assert s["machine_tasks"] == sum(int(r["tasks_finished"]) for r in mine if r["decider"] == "machine")
        assert s["host_rule_tasks"] == sum(int(r["tasks_finished"]) for r in mine if r["decider"] == "host rule")
    # a row is the run mrmt lorr run makes with that machine (work-bounded: deterministic)
    record, _, _ = run_lorr(EXAMPLE, "lorr-greedy", "epibt-ising", steps=30, seed=1, chip=ChipSpec(n_spins=64),
                            options={"executor_options": {"lns": 0, "groups": 8}})
    row = next(r for r in rows if (r["spec"], r["decider"], r["seed"]) == ("n_spins=64", "machine", "1"))
    assert (int(row["tasks_finished"]), int(row["chip_calls"])) == (record["tasks_finished"], record["chip_calls"])
    assert (out / "summary.md").read_text().count("| n_spins=") == 2 and (out / "sweep.png").stat().st_size > 0


@pytest.mark.parametrize("args, needle", [
    (["--chip", "n_spins=0,45"], "n_spins = 0 must be a positive integer"),
    (["--chip", "n_spins=45", "--step-limit", "rules", "--jobs", "2"], "give --jobs 1"),
    (["--chip", "n_spins=45", "--planner", "pibt"], "neither the scheduler 'lorr-greedy' nor the planner 'pibt'"),
    (["--chip", "n_spins=45", "--scheduler", "strong,ising"], "a sweep runs one scheduler"),
])
def test_sweep_bad_input_is_one_line_and_exit_2(args, needle, tmp_path):
    base = ["--planner", "epibt-ising"] if "--planner" not in args else []
    proc = _mrmt("lorr", "sweep", str(EXAMPLE), *base, *args, "--steps", "2", "--no-progress", "--out",
                 str(tmp_path / "x"))
    assert proc.returncode == 2, proc.stdout + proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in proc.stderr
