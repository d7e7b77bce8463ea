"""QuantizeComposite: dimod conformance on the strict chip, original energies, rules, refusals, determinism."""

import doctest
import itertools
import unittest

import dimod
import dimod.testing
import numpy as np
import pytest

import ising_backend
import ising_backend.machines.composite
from ising_backend import (
    COMPOSITE_RULES,
    QUANTIZE_RULES,
    ChipSpec,
    EmulatedChip,
    IsingModel,
    QuantizeComposite,
    QuantizeError,
)


@dimod.testing.load_sampler_bqm_tests(lambda: QuantizeComposite(EmulatedChip(seed=0)))
class TestCompositeDimodBQMs(unittest.TestCase):
    """dimod's full generic sampler tests (every size) through the composite on the default strict chip."""


@dimod.testing.load_sampler_bqm_tests(lambda: QuantizeComposite(EmulatedChip(seed=0), rule="saturate", scale=0.5))
class TestCompositeDimodBQMsSaturate(unittest.TestCase):
    """The same tests under the fixed-scale saturating rule (it clips: energies must still be the BQM's)."""


def test_generic_test_count():
    names = [n for n in dir(TestCompositeDimodBQMs) if n.startswith("test_")]
    assert len(names) == 32


class SpyChip(EmulatedChip):
    """An EmulatedChip that records every BQM it is asked to sample."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.programs = []

    def sample(self, bqm, **kwargs):
        self.programs.append(bqm.copy())
        return super().sample(bqm, **kwargs)


def _random_bqm(n, vartype, seed, labels=None, scale=100.0):
    rng = np.random.default_rng(seed)
    labels = list(range(n)) if labels is None else labels
    lin = {v: float(rng.normal() * scale) for v in labels}
    quad = {(labels[i], labels[j]): float(rng.normal() * scale)
            for i, j in itertools.combinations(range(n), 2) if rng.random() < 0.6}
    return dimod.BQM(lin, quad, float(rng.normal()), vartype)


def test_sampler_and_composite_api():
    chip = EmulatedChip(seed=0)
    sampler = QuantizeComposite(chip)
    dimod.testing.assert_sampler_api(sampler)
    dimod.testing.assert_composite_api(sampler)
    assert isinstance(sampler, dimod.ComposedSampler)
    assert sampler.child is chip and sampler.children == [chip]
    assert sampler.properties["child_properties"] == chip.properties
    assert sampler.properties["rules"] == list(QUANTIZE_RULES) + ["saturate"] == list(COMPOSITE_RULES)
    assert {"num_reads", "seed", "rule", "scale"} <= set(sampler.parameters)
    assert set(chip.parameters) <= set(sampler.parameters)
    assert ising_backend.QuantizeComposite is ising_backend.machines.composite.QuantizeComposite
    assert "QuantizeComposite" in ising_backend.__all__


@pytest.mark.parametrize("vartype", [dimod.SPIN, dimod.BINARY])
@pytest.mark.parametrize("rule", COMPOSITE_RULES)
def test_energies_are_the_original_bqms(vartype, rule):
    labels = ["a", ("b", 1), 7, frozenset({2}), 2.5, "z" * 3, (("x",),), -1]
    bqm = _random_bqm(len(labels), vartype, seed=3, labels=labels)
    sampler = QuantizeComposite(EmulatedChip(seed=1), rule=rule, scale=0.05)
    ss = sampler.sample(bqm, num_reads=6, seed=2)
    assert ss.vartype is vartype and set(ss.variables) == set(labels)
    assert set(np.unique(ss.record.sample)) <= ({-1, 1} if vartype is dimod.SPIN else {0, 1})
    dimod.testing.assert_sampleset_energies(ss, bqm)
    assert len(ss) == 6 and ss.record.num_occurrences.sum() == 6
    assert ss.info["rule"] == rule and ss.info["ledger"]["physical_calls"] == 6
    assert ss.info["scale"] == (0.05 if rule == "saturate" else None)
    # program_energy is the child's (chip-unit) energy of the integer program for the same spins
    program, variables = sampler.quantized(bqm)
    spins = ss.record.sample[:, [ss.variables.index(v) for v in variables]]
    spins = 2 * spins - 1 if vartype is dimod.BINARY else spins
    assert np.array_equal(program.energy(spins), ss.record.program_energy)


@pytest.mark.parametrize("rule", COMPOSITE_RULES)
@pytest.mark.parametrize("spec", [ChipSpec(), ChipSpec(n_spins=60, h_range=(-15, 15), j_range=(-3, 5))])
def test_each_rule_programs_the_child_with_integer_in_range_coefficients(rule, spec):
    chip = SpyChip(spec, seed=0)
    sampler = QuantizeComposite(chip, rule="linear", scale=0.37)
    n = min(spec.n_spins, 40)
    for vartype, seed in ((dimod.SPIN, 0), (dimod.BINARY, 1)):
        bqm = _random_bqm(n, vartype, seed, scale=[0.01, 1000.0][seed])
        sampler.sample(bqm, rule=rule, num_reads=2)
        prog = chip.programs[-1]
        assert prog.vartype is dimod.SPIN and prog.offset == 0
        assert sorted(prog.variables) == list(range(n))
        hl = np.array([0.0, *prog.linear.values()])
        jq = np.array([0.0, *prog.quadratic.values()])
        assert np.all(hl == np.round(hl)) and np.all(jq == np.round(jq))
        assert hl.min() >= spec.h_range[0] and hl.max() <= spec.h_range[1]
        assert jq.min() >= spec.j_range[0] and jq.max() <= spec.j_range[1]
        if rule != "saturate":  # keep_sign: every non-zero coupling of the Ising form survives with its sign
            ising = IsingModel.from_bqm(bqm, list(bqm.variables))
            qj = np.zeros((n, n))
            for (u, v), b in prog.quadratic.items():
                qj[min(u, v), max(u, v)] = b
            assert np.array_equal(np.sign(qj), np.sign(ising.J))
            # the scale uses the full symmetric range: some coefficient reaches a limit
            lim_h, lim_j = min(-spec.h_range[0], spec.h_range[1]), min(-spec.j_range[0], spec.j_range[1])
            assert np.abs(hl).max() == lim_h or np.abs(jq).max() == lim_j
    assert chip.ledger.physical_calls == 4


def test_quantized_program_matches_quantize_and_saturate():
    bqm = _random_bqm(10, dimod.SPIN, seed=5)
    chip = EmulatedChip(seed=0)
    ising = IsingModel.from_bqm(bqm, list(bqm.variables))
    for rule in QUANTIZE_RULES:
        for keep in (True, False):
            prog, variables = QuantizeComposite(chip, rule=rule, keep_sign=keep).quantized(bqm)
            ref = ising_backend.quantize(ising, rule, (-7, 7), (-7, 7), keep_sign=keep)
            assert variables == list(bqm.variables)
            assert np.array_equal(prog.h, ref.h) and np.array_equal(prog.J, ref.J)
    prog, _ = QuantizeComposite(chip, rule="saturate", scale=0.04).quantized(bqm)
    ref = ising_backend.saturate(ising, 0.04, (-7, 7), (-7, 7))
    assert np.array_equal(prog.h, ref.h) and np.array_equal(prog.J, ref.J)


def test_rule_per_call_override_and_sample_ising_qubo():
    chip = SpyChip(seed=0)
    sampler = QuantizeComposite(chip)
    ss = sampler.sample_ising({"a": 0.25}, {("a", "b"): -40.0}, rule="rank", num_reads=3, seed=4)
    assert ss.info["rule"] == "rank" and ss.first.energy == -40.25
    assert dict(chip.programs[-1].quadratic) == {(1, 0): -7.0} or dict(chip.programs[-1].quadratic) == {(0, 1): -7.0}
    ss = sampler.sample_qubo({("x", "x"): 0.3, ("x", "y"): -2.2}, rule="saturate", scale=3.0, num_reads=2)
    assert ss.info["rule"] == "saturate" and ss.info["scale"] == 3.0 and ss.vartype is dimod.BINARY
    dimod.testing.assert_sampleset_energies(ss, dimod.BQM.from_qubo({("x", "x"): 0.3, ("x", "y"): -2.2}))
    assert sampler.rule == "linear"  # the override does not stick
    ss = sampler.sample_ising({"a": 1.0}, {})
    assert ss.info["rule"] == "linear" and len(ss) == 1  # the chip's default num_reads


def test_finds_ground_state_of_a_real_valued_problem():
    """A frustrated real-valued problem the strict chip refuses: the composite still solves it."""
    h = {0: 0.31, 1: -0.17, 2: 0.05}
    J = {(0, 1): 1.9, (1, 2): -2.4, (0, 2): 1.3}
    bqm = dimod.BQM.from_ising(h, J)
    with pytest.raises(ValueError, match="not an integer"):
        EmulatedChip(seed=0).sample(bqm)
    ss = QuantizeComposite(EmulatedChip(seed=0)).sample(bqm, num_reads=20, seed=0)
    ground = dimod.ExactSolver().sample(bqm).first.energy
    assert ss.first.energy == pytest.approx(ground)


def test_oversize_bqm_names_size_and_limit_and_charges_nothing():
    chip = SpyChip(seed=0)
    sampler = QuantizeComposite(chip)
    bqm = dimod.BQM({v: 1.0 for v in range(46)}, {}, 0.0, "SPIN")
    with pytest.raises(ValueError, match=r"BQM has 46 variables; the child has 45 spins"):
        sampler.sample(bqm)
    assert chip.programs == [] and chip.ledger.physical_calls == 0
    big = QuantizeComposite(EmulatedChip(ChipSpec(n_spins=46), seed=0))
    assert len(big.sample(bqm, num_reads=2).variables) == 46


def test_empty_offset_only_and_all_zero_bqms():
    chip = SpyChip(seed=0)
    sampler = QuantizeComposite(chip)
    for vartype in (dimod.SPIN, dimod.BINARY):
        for offset in (0.0, -2.5):
            ss = sampler.sample(dimod.BQM({}, {}, offset, vartype), num_reads=5)
            assert len(ss) == 0 and len(ss.variables) == 0 and ss.vartype is vartype
            assert ss.info["ledger"]["physical_calls"] == 0 and ss.info["rule"] == "linear"
    assert chip.programs == [] and chip.ledger.physical_calls == 0
    for rule in COMPOSITE_RULES:
        bqm = dimod.BQM({"p": 0.0, "q": 0.0}, {("p", "q"): 0.0}, 4.0, "BINARY")
        ss = sampler.sample(bqm, rule=rule, scale=1.0, num_reads=3)
        assert list(ss.record.energy) == [4.0] * 3 and set(ss.variables) == {"p", "q"}
        prog = chip.programs[-1]
        assert all(b == 0 for b in prog.linear.values()) and all(b == 0 for b in prog.quadratic.values())


def test_determinism_with_seed():
    bqm = _random_bqm(30, dimod.BINARY, seed=9, labels=[f"v{i}" for i in range(30)])
    a = QuantizeComposite(EmulatedChip(seed=1)).sample(bqm, num_reads=8, seed=123)
    b = QuantizeComposite(EmulatedChip(seed=2)).sample(bqm, num_reads=8, seed=123)
    assert a.variables == b.variables
    assert np.array_equal(a.record.sample, b.record.sample) and np.array_equal(a.record.energy, b.record.energy)
    # without a per-call seed, the chip's own generator replays call sequences
    c1, c2 = QuantizeComposite(EmulatedChip(seed=7)), QuantizeComposite(EmulatedChip(seed=7))
    for _ in range(2):
        x, y = c1.sample(bqm, num_reads=4), c2.sample(bqm, num_reads=4)
        assert np.array_equal(x.record.sample, y.record.sample)


def test_bad_rule_scale_child_and_biases_are_named():
    chip = EmulatedChip(seed=0)
    with pytest.raises(QuantizeError, match=r"rule = 'round' not in \('linear', 'clip95', 'rank', 'sqrt', 'saturate'\)"):
        QuantizeComposite(chip, rule="round")
    with pytest.raises(QuantizeError, match="needs a fixed scale"):
        QuantizeComposite(chip, rule="saturate")
    with pytest.raises(QuantizeError, match=r"scale = -1 must be a positive"):
        QuantizeComposite(chip, rule="saturate", scale=-1)
    sampler = QuantizeComposite(chip)
    with pytest.raises(QuantizeError, match=r"rule = 'nope' not in"):
        sampler.sample_ising({0: 1.0}, {}, rule="nope")
    with pytest.raises(QuantizeError, match="needs a fixed scale"):
        sampler.sample_ising({0: 1.0}, {}, rule="saturate")
    with pytest.raises(ValueError, match=r"has no properties \['h_range', 'j_range', 'num_spins'\]"):
        QuantizeComposite(dimod.ExactSolver())
    with pytest.raises(ValueError, match="not finite"):
        sampler.sample_ising({0: float("nan")}, {})
    assert chip.ledger.physical_calls == 0


def test_generic_child_with_ranges():
    """Any sampler exposing the three properties works as the child (here an exact solver wrapper)."""

    class Ranged(dimod.ExactSolver):
        def __init__(self):
            super().__init__()
            self.properties = {"h_range": [-3, 3], "j_range": [-2, 2], "num_spins": 6}

    bqm = _random_bqm(5, dimod.BINARY, seed=11, labels=list("abcde"))
    ss = QuantizeComposite(Ranged()).sample(bqm)
    assert len(ss) == 32
    dimod.testing.assert_sampleset_energies(ss, bqm)
    assert ss.info["rule"] == "linear"


def test_docstring_example_runs():
    assert doctest.testmod(ising_backend.machines.composite).failed == 0
