"""The Ising machine interface: SamplerChip on real dimod samplers, a socket device driver, the CLI."""

from __future__ import annotations

import importlib.util
import pickle
import sys
import unittest
from pathlib import Path

import dimod
import dimod.testing
import numpy as np
import pytest

from ising_backend import (ChipProgramError, ChipSpec, EmulatedChip, IsingMachine, LogicalIsingSolver, MachineBase,
                           MachineSpec, QuantizeComposite, SamplerChip, as_machine, build_machine)
from mrmt_env.generation import generate_world
from planners.pipeline import make_pipeline
from planners.plan import validate_plan

ROOT = Path(__file__).resolve().parents[1]
SAMPLER_NAMES = ["dwave-sa", "dwave-tabu", "neal", "openjij-sa"]


def sampler_chip(name: str, spec: ChipSpec | None = None, **params) -> SamplerChip:
    if name.startswith("openjij"):
        pytest.importorskip("openjij")
    if name == "dwave-tabu":
        params.setdefault("timeout", 1)
    return MachineSpec(spec or ChipSpec(), name, tuple(params.items())).build()


def random_programs(rng, B=5, n=12, lim=7):
    h = rng.integers(-lim, lim + 1, size=(B, n))
    J = np.triu(rng.integers(-lim, lim + 1, size=(B, n, n)), 1)
    return h, J


def _composite_on_sampler_chip():
    import dwave.samplers

    return QuantizeComposite(SamplerChip(dwave.samplers.SimulatedAnnealingSampler(), seed=0))


@dimod.testing.load_sampler_bqm_tests(_composite_on_sampler_chip)
class TestSamplerChipBehindComposite(unittest.TestCase):
    """dimod's generic sampler tests: any BQM mapped onto a SamplerChip through the quantize composite."""


def test_every_machine_satisfies_the_protocol():
    for machine in (EmulatedChip(seed=0), LogicalIsingSolver(), sampler_chip("dwave-sa"),
                    EmulatedChip(ChipSpec(dead_cores=1), seed=0)):
        assert isinstance(machine, IsingMachine)
    dimod.testing.assert_sampler_api(sampler_chip("dwave-sa"))


@pytest.mark.parametrize("name", SAMPLER_NAMES)
def test_sampler_chip_anneals_charges_by_the_spec_and_is_seeded(name):
    spec = ChipSpec(n_chips=2, cores_per_chip=2)
    chip = sampler_chip(name, spec)
    h, J = random_programs(np.random.default_rng(1))
    spins, energies = chip.anneal_batch(h, J, num_reads=3, seed=7)
    assert spins.shape == (5, 3, 12) and spins.dtype == np.int8 and set(np.unique(spins)) <= {-1, 1}
    s = spins.astype(float)
    want = np.einsum("brn,bn->br", s, h) + np.einsum("brn,bnm,brm->br", s, J, s)
    np.testing.assert_allclose(energies, want)
    led = chip.last_call
    assert led.physical_calls == 15 and led.batches == 4  # ceil(15 / 4 cores)
    assert led.chip_time_s == pytest.approx(15 * spec.solve_time_s)
    assert led.energy_j == pytest.approx(15 * spec.energy_per_call_j)
    assert chip.ledger.physical_calls == 15
    again, _ = sampler_chip(name, spec).anneal_batch(h, J, num_reads=3, seed=7)
    np.testing.assert_array_equal(spins, again)
    # the samplers find the ground state (-5, brute force) of a 3-spin program
    h1, J1 = np.array([1, -1, 0]), np.array([[0, -2, 0], [0, 0, 3], [0, 0, 0]])
    ground = min(dimod.ExactSolver().sample_ising(dict(enumerate(h1)), {(0, 1): -2, (1, 2): 3}).record.energy)
    _, en = chip.anneal_batch(h1, J1, 4, seed=1)
    assert en.min() == ground == -5.0


@pytest.mark.parametrize("bad, match", [
    ((np.array([[8, 0]]), np.zeros((1, 2, 2))), r"outside h_range \[-7, 7\]"),
    ((np.array([[1.5, 0]]), np.zeros((1, 2, 2))), "not an integer"),
    ((np.zeros((1, 46)), np.zeros((1, 46, 46))), "46 spins; the chip has 45"),
    ((np.zeros((1, 2)), np.array([[[0, 0], [1, 0]]])), "below the diagonal"),
    ((np.array([[np.nan, 0]]), np.zeros((1, 2, 2))), "not finite"),
])
def test_sampler_chip_refuses_exactly_as_the_emulator(bad, match):
    chip = sampler_chip("dwave-sa")
    with pytest.raises(ChipProgramError, match=match) as got:
        chip.anneal_batch(*bad)
    with pytest.raises(ChipProgramError) as emulator:
        EmulatedChip(seed=0).anneal_batch(*bad)
    assert str(got.value) == str(emulator.value)
    assert chip.ledger.physical_calls == 0  # nothing is charged for a refused program


def test_bad_sampler_setups_are_named():
    import dwave.samplers

    with pytest.raises(TypeError, match="not a dimod.Sampler"):
        SamplerChip(object())
    with pytest.raises(ValueError, match="'foo' is not one of SimulatedAnnealingSampler's"):
        SamplerChip(dwave.samplers.SimulatedAnnealingSampler(), foo=1)
    with pytest.raises(ValueError, match="set per call"):
        SamplerChip(dwave.samplers.SimulatedAnnealingSampler(), num_reads=1)
    with pytest.raises(ValueError, match="emulated by EmulatedChip only"):
        SamplerChip(dwave.samplers.SimulatedAnnealingSampler(), ChipSpec(stuck_spins=1))
    with pytest.raises(ValueError, match="unknown sampler 'bogus'; known: dwave-sa"):
        MachineSpec(sampler="bogus")
    with pytest.raises(TypeError, match="missing spec, ledger, anneal_batch"):
        as_machine(object())


def test_broken_device_answers_are_refused():
    class Broken(MachineBase):
        def _sample(self, h, J, num_reads, seed):
            return np.zeros((h.shape[0], num_reads, h.shape[1]))  # zeros are not spins

    from ising_backend import SolverOutputError

    with pytest.raises(SolverOutputError, match="spins in"):
        Broken().anneal_batch(np.zeros((1, 3)), np.zeros((1, 3, 3)))


def test_machine_spec_with_a_list_option_stays_hashable():
    m = MachineSpec(sampler="dwave-sa", options=(("beta_range", [0.1, 5.0]),))
    assert hash(m) == hash(MachineSpec(sampler="dwave-sa", options=(("beta_range", (0.1, 5.0)),)))
    assert m.build().params == {"beta_range": (0.1, 5.0)}


def test_machine_spec_pickles_and_builds():
    m = MachineSpec(ChipSpec(n_spins=30), "dwave-sa", (("num_sweeps", 20),))
    back = pickle.loads(pickle.dumps(m))
    assert back == m
    chip = build_machine(back)
    assert isinstance(chip, SamplerChip) and chip.spec.n_spins == 30 and chip.params == {"num_sweeps": 20}
    assert m.to_dict()["sampler"] == "dwave-sa" and m.to_dict()["sampler.num_sweeps"] == 20
    assert isinstance(build_machine(ChipSpec()), EmulatedChip)


@pytest.mark.parametrize("preset", ["ising", "ising-paper"])
@pytest.mark.parametrize("layout", ["uniform", "warehouse"])
def test_a_bare_dimod_sampler_plans_valid_routes(preset, layout):
    import dwave.samplers

    size = 10 if layout == "uniform" else 16
    pipe = make_pipeline(preset, chip=dwave.samplers.SimulatedAnnealingSampler())
    chip = pipe.sharing.chip
    assert isinstance(chip, SamplerChip) and pipe.tour.chip is chip and getattr(pipe.path, "chip", chip) is chip  # one ledger
    for seed in range(3):
        world = generate_world(seed, height=size, width=size, n_robots=3, n_targets=8, layout=layout)
        before = chip.ledger.physical_calls
        plan = pipe.plan(world, seed=seed)
        assert plan.success, plan.failure
        validate_plan(world, plan)
        calls = chip.ledger.physical_calls - before
        assert plan.compute.chip_calls == calls > 0
        assert plan.compute.accelerator_energy_j == pytest.approx(
            (calls + plan.compute.logical_calls) * chip.spec.energy_per_call_j)


def _load_example():
    spec = importlib.util.spec_from_file_location("socket_chip", ROOT / "examples" / "socket_chip.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["socket_chip"] = mod
    spec.loader.exec_module(mod)
    return mod


def test_socket_device_driver_behind_the_pipeline():
    ex = _load_example()
    with ex.FakeDevice() as device:
        chip = ex.SocketChip("127.0.0.1", device.port, seed=0)
        h, J = random_programs(np.random.default_rng(2), B=3, n=6)
        spins, energies = chip.anneal_batch(h, J, num_reads=2, seed=5)
        local, local_e = EmulatedChip().anneal_batch(h, J, num_reads=2, seed=5)
        np.testing.assert_array_equal(spins, local)  # the device is the emulator behind a socket
        np.testing.assert_allclose(energies, local_e)
        with pytest.raises(ChipProgramError, match="outside j_range"):
            chip.anneal_batch(np.zeros((1, 2)), np.array([[[0, 9], [0, 0]]]))
        world = generate_world(3)
        plan = make_pipeline("ising", chip=chip).plan(world, seed=0)
        assert plan.success and plan.compute.chip_calls == chip.ledger.physical_calls - 3 * 2


def test_device_errors_surface():
    ex = _load_example()
    with ex.FakeDevice(ChipSpec(n_spins=4)) as device:
        chip = ex.SocketChip("127.0.0.1", device.port)  # the driver claims 45 spins, the device has 4
        with pytest.raises(ex.DeviceError, match="6 spins; the chip has 4"):
            chip.anneal_batch(np.zeros((1, 6)), np.zeros((1, 6, 6)))


def test_cli_plan_with_a_sampler(tmp_path, capsys):
    from agents.cli import main

    worlds = ROOT / "mrmt_env" / "data" / "example_worlds.jsonl"
    out = tmp_path / "plans.jsonl"
    assert main(["plan", str(worlds), "--pipeline", "ising", "--sampler", "dwave-sa",
                 "--sampler-option", "num_sweeps=100", "--out", str(out), "--no-progress"]) == 0
    import json

    rows = [json.loads(line) for line in out.read_text().splitlines()]
    assert rows and all(r["success"] and r["compute"]["chip_calls"] > 0 for r in rows)
    capsys.readouterr()  # the first run's compile notice, if this process had not compiled yet
    for argv, msg in ((["--sampler", "bogus"], "unknown sampler 'bogus'"),
                      (["--sampler", "dwave-sa", "--sampler-option", "nope=1"], "'nope' is not one of"),
                      (["--sampler-option", "num_sweeps=1"], "without --sampler")):
        assert main(["plan", str(worlds), "--pipeline", "ising", *argv]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and msg in err[0]


def test_sampler_parameter_types_come_from_the_sampler():
    import dwave.samplers

    from ising_backend.machines.sampler_options import describe, parameter_types, parse_value

    types = parameter_types(dwave.samplers.SimulatedAnnealingSampler())
    assert describe(types["num_sweeps"]) == "an integer" and describe(types["randomize_order"]) == "true or false"
    assert describe(types["beta_schedule_type"]) == "one of 'linear', 'geometric', 'custom'"
    assert parse_value(types["num_sweeps"], "num_sweeps", "100") == 100
    assert parse_value(types["beta_range"], "beta_range", "[0.1, 5]") == [0.1, 5]
    assert parse_value(types["beta_range"], "beta_range", "0.1,5") == (0.1, 5)  # a Python literal
    assert parse_value(types["beta_schedule_type"], "beta_schedule_type", "linear") == "linear"
    assert parse_value(types["randomize_order"], "randomize_order", "true") is True
    for name, text, expected in (("num_sweeps", "abc", "an integer"), ("num_sweeps", "1.5", "an integer"),
                                 ("randomize_order", "yes", "true or false"),
                                 ("beta_schedule_type", "5", "one of 'linear'")):
        with pytest.raises(ValueError, match=f"^{name}='{text}': expected {expected}"):
            parse_value(types[name], name, text)
    with pytest.raises(ValueError, match="sampler parameter num_sweeps='abc': expected an integer"):
        SamplerChip(dwave.samplers.SimulatedAnnealingSampler(), num_sweeps="abc")  # held to the types in Python too
    with pytest.raises(ValueError, match="'seed' is set per call"):
        MachineSpec(sampler="dwave-sa", options=(("seed", 3),))  # was a TypeError from build()


@pytest.mark.parametrize("command", [["plan", str(ROOT / "mrmt_env" / "data" / "example_worlds.jsonl"),
                                      "--pipeline", "ising"],
                                     ["compare", "--controllers", "ising", "--worlds", "1", "--jobs", "1"],
                                     ["compare", "--env-id", "mrmt_env/MRMT-Lifelong-v0", "--controllers", "ising",
                                      "--worlds", "1"],
                                     ["sweep", "--chip", "n_spins=32,45", "--controllers", "ising", "--worlds", "1",
                                      "--out", "never-written"],
                                     ["reproduce", "--quick", "--out", "never-written"]])
def test_sampler_option_values_are_read_by_their_type(command, capsys, tmp_path, monkeypatch):
    from agents.cli import main

    monkeypatch.chdir(tmp_path)
    cases = ((["num_sweeps=abc"], "--sampler-option num_sweeps='abc': expected an integer"),
             (["num_sweeps=10", "beta_range=x"], "--sampler-option beta_range='x': expected a list of numbers"),
             (["randomize_order=yes"], "--sampler-option randomize_order='yes': expected true or false"),
             (["nope=1"], "'nope' is not one of the parameters of dwave-sa (SimulatedAnnealingSampler): "
                          "beta_range, beta_schedule,"),
             (["seed=3"], "--sampler-option seed='3': 'seed' is set per call by the planner"),
             (["num_sweeps=1", "num_sweeps=2"], "--sampler-option num_sweeps given twice"),
             (["num_sweeps=-1"], "--sampler dwave-sa: SimulatedAnnealingSampler refuses num_sweeps=-1: ValueError"))
    for options, msg in cases:
        argv = [*command, "--sampler", "dwave-sa"]
        for option in options:
            argv += ["--sampler-option", option]
        assert main([*argv, "--no-progress"]) == 2, options
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(f"mrmt {command[0]}: error: --sampler") and msg in err[0], \
            (options, err)
    assert not (tmp_path / "never-written").exists()
