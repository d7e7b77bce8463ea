"""LogicalIsingSolver: budget enforced, range not, exactness on small problems, dwave Tabu parity, ledger."""

import itertools
import math
import unittest

import dimod
import dimod.testing
import numpy as np
import pytest

from ising_backend import ChipProgramError, IsingModel, LogicalIsingSolver


@dimod.testing.load_sampler_bqm_tests(lambda: LogicalIsingSolver(seed=0))
class TestLogicalDimodBQMs(unittest.TestCase):
    """dimod's own sampler tests (all sizes: the logical solver has no coefficient range)."""


def _ground(m):
    S = np.array(list(itertools.product([-1, 1], repeat=m.n)))
    return m.energy(S).min()


def test_api_budget_and_finite_checks():
    sol = LogicalIsingSolver(seed=0)
    dimod.testing.assert_sampler_api(sol)
    big = IsingModel(np.full(3, 1e6), np.triu(np.full((3, 3), -250.75), 1))
    r = sol.solve(big)  # coefficient range is not enforced
    assert r.best_energy == _ground(big)
    with pytest.raises(ChipProgramError, match="46 spins; the logical solver's spin budget is 45"):
        sol.solve(IsingModel(np.zeros(46), np.zeros((46, 46))))
    with pytest.raises(ChipProgramError, match="not finite"):
        sol.anneal_batch(np.array([[np.inf, 0.0]]), np.zeros((1, 2, 2)))
    assert LogicalIsingSolver(budget=10).properties["num_spins"] == 10


def test_fast_tabu_is_exact_on_small_random_problems():
    rng = np.random.default_rng(0)
    sol = LogicalIsingSolver(seed=1)
    models = []
    for _ in range(40):
        n = int(rng.integers(2, 15))
        models.append(IsingModel(rng.normal(0, 10, n), np.triu(rng.normal(0, 10, (n, n)), 1), rng.normal()))
    results = sol.solve_many(models)
    for m, r in zip(models, results):
        assert r.best_energy == pytest.approx(_ground(m), abs=1e-9)
        assert r.best_energy == pytest.approx(m.energy(r.best_spins), abs=1e-9)
    assert sol.ledger.logical_calls == 40 and sol.ledger.physical_calls == 0
    assert sol.ledger.logical_batches == 5
    assert math.isclose(sol.ledger.chip_time_s, 40 * 50e-6)


def test_fast_tabu_matches_dwave_tabu_quality():
    """On 20-spin dense problems our tabu finds energies as good as TabuSampler's."""
    rng = np.random.default_rng(5)
    models = [IsingModel(rng.normal(0, 5, 20), np.triu(rng.normal(0, 5, (20, 20)), 1)) for _ in range(8)]
    ours = LogicalIsingSolver(seed=0).solve_many(models)
    theirs = LogicalIsingSolver(method="dwave-tabu", timeout_ms=20, seed=0).solve_many(models)
    for a, b in zip(ours, theirs):
        assert a.best_energy <= b.best_energy + 1e-9


def test_deterministic_given_seed():
    rng = np.random.default_rng(2)
    m = IsingModel(rng.normal(size=30), np.triu(rng.normal(size=(30, 30)), 1))
    a = LogicalIsingSolver().solve(m, num_reads=3, seed=4)
    b = LogicalIsingSolver().solve(m, num_reads=3, seed=4)
    assert np.array_equal(a.spins, b.spins)
    assert a.spins.shape == (3, 30) and a.spins.dtype == np.int8
