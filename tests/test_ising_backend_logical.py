"""LogicalIsingSolver: budget enforced, range not, exactness on small problems, dwave Tabu parity, ledger."""

import itertools
import math
import unittest

import dimod
import dimod.testing
import numpy as np
import pytest

from ising_backend import ChipProgramError, IsingModel, LogicalIsingSolver, MachineBase


@dimod.testing.load_sampler_bqm_tests(lambda: LogicalIsingSolver(seed=0))
class TestLogicalDimodBQMs(unittest.TestCase):
    """dimod's own sampler tests (all sizes: the logical solver has no coefficient range)."""


def test_the_logical_solver_is_a_machine_charging_logical_calls():
    sol = LogicalIsingSolver(seed=0)
    assert isinstance(sol, MachineBase)
    h, J = np.zeros((3, 4)), np.zeros((3, 4, 4))
    J[:, 0, 1] = 40.0  # beyond the chip's range: the logical solver keeps only the spin budget
    spins, energies = sol.anneal_batch(h, J, num_reads=2, seed=1)
    assert spins.shape == (3, 2, 4) and energies.shape == (3, 2)
    assert (sol.ledger.logical_calls, sol.ledger.physical_calls) == (6, 0) == (sol.last_call.logical_calls, 0)
    assert np.allclose(energies, 40.0 * spins[..., 0] * spins[..., 1])  # the programmed energies
    single, _ = sol.anneal_batch(h[0], J[0], num_reads=2, seed=1)  # one program: leading axis dropped
    assert np.array_equal(single, spins[0])
    with pytest.raises(ValueError, match="num_reads"):
        sol.anneal_batch(h, J, num_reads=0)
    # a read-only stack (a broadcast of one program) is solved as a writable copy: the same spins
    ro = np.broadcast_to(J[:1], (1, 4, 4))
    assert np.array_equal(sol.solve_stack(h[:1], ro, num_reads=2, seed=3), sol.solve_stack(h[:1], J[:1].copy(),
                                                                                            num_reads=2, seed=3))


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


def _tsp_onehot(D, A):
    """Open-path TSP one-hot QUBO (x[c, p] = city c at position p) as an Ising model."""
    n = D.shape[0]
    q = np.zeros(n * n)
    Q = np.zeros((n * n, n * n))
    off = 0.0
    for groups in ([[c * n + p for p in range(n)] for c in range(n)], [[c * n + p for c in range(n)] for p in range(n)]):
        for vs in groups:  # A * (1 - sum x)^2
            off += A
            q[vs] -= A
            for a, b in itertools.combinations(vs, 2):
                Q[a, b] += 2 * A
    for p in range(n - 1):
        for c1 in range(n):
            for c2 in range(n):
                if c1 != c2:
                    a, b = c1 * n + p, c2 * n + p + 1
                    Q[min(a, b), max(a, b)] += D[c1, c2]
    from ising_backend import QuboModel

    return QuboModel(q, Q, off).to_ising()


def test_fast_tabu_solves_onehot_tsp_like_dwave_tabu():
    """6-city one-hot permutation QUBOs (36 spins, the tour layer's workload): optimum as often as TabuSampler."""
    rng = np.random.default_rng(0)
    models, optima = [], []
    for _ in range(8):
        P = rng.random((6, 2)) * 10
        D = np.abs(P[:, None] - P[None]).sum(-1)
        models.append(_tsp_onehot(D, A=2 * D.max()))
        optima.append(min(sum(D[p[i], p[i + 1]] for i in range(5)) for p in itertools.permutations(range(6))))
    ours = LogicalIsingSolver(seed=0).solve_many(models)
    theirs = LogicalIsingSolver(method="dwave-tabu", timeout_ms=10, seed=0).solve_many(models)
    hits_ours = sum(abs(r.best_energy - o) < 1e-9 for r, o in zip(ours, optima))
    hits_theirs = sum(abs(r.best_energy - o) < 1e-9 for r, o in zip(theirs, optima))
    assert hits_ours >= hits_theirs and hits_ours >= 7


def _splitmix_sub_seed(seed: int, k: int) -> int:
    """The oracle of ``mix_seed``: splitmix64 of ``seed + golden x (k + 1)`` in Python integers."""
    m = 0xFFFFFFFFFFFFFFFF
    z = (seed + 0x9E3779B97F4A7C15 * (k + 1)) & m
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & m
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & m
    return z ^ (z >> 31)


def test_the_size_groups_sub_seed_is_splitmix64_over_every_call_seed():
    from ising_backend.machines.tabu import mix_seed

    rng = np.random.default_rng(7)
    seeds = [0, 1, 2**63 - 1, 2**63, 2**64 - 1] + [int(x) for x in rng.integers(0, 2**64 - 1, 200, dtype=np.uint64)]
    for seed in seeds:
        for k in (0, 1, 45, 1000):
            assert int(mix_seed(np.uint64(seed), k)) == _splitmix_sub_seed(seed, k), (seed, k)


def test_a_call_seed_above_2_63_solves():
    sol = LogicalIsingSolver(seed=0)
    m = IsingModel(np.array([1.0, -2.0, 0.5]), np.triu(np.ones((3, 3)), 1))
    a = sol.solve_many([m], num_reads=4, seed=2**64 - 1)
    b = sol.solve_many([m], num_reads=4, seed=2**64 - 1)
    assert np.array_equal(a[0].spins, b[0].spins)
