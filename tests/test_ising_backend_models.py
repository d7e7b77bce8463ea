"""Ising/QUBO models: exact conversions, energies vs brute force, dimod round trips."""

import itertools

import dimod
import numpy as np
import pytest

from ising_backend import IsingModel, ModelError, QuboModel, from_bqm


def _states(n):
    return np.array(list(itertools.product([-1, 1], repeat=n)), dtype=np.int8)


def _brute_ising(h, J, off, s):
    n = len(h)
    e = off + sum(h[i] * s[i] for i in range(n))
    e += sum(J[i][j] * s[i] * s[j] for i in range(n) for j in range(i + 1, n))
    return e


@pytest.mark.parametrize("seed", range(5))
def test_energy_matches_definition_and_conversions_exact(seed):
    rng = np.random.default_rng(seed)
    n = 6
    h = rng.integers(-9, 10, n).astype(float)
    J = np.triu(rng.integers(-9, 10, (n, n)), 1).astype(float)
    m = IsingModel(h, J, offset=2.5)
    S = _states(n)
    E = m.energy(S)
    for s, e in zip(S, E):
        assert e == _brute_ising(h, J, 2.5, s)
    q = m.to_qubo()
    X = (1 + S) // 2
    assert np.array_equal(q.energy(X), E)  # integer data: exact to the last bit
    back = q.to_ising()
    assert np.array_equal(back.h, m.h) and np.array_equal(back.J, m.J) and back.offset == m.offset
    bqm = m.to_bqm()
    for s, e in zip(S[:10], E[:10]):
        assert bqm.energy(dict(enumerate(s))) == e
    assert np.array_equal(IsingModel.from_bqm(bqm).energy(S), E)
    qb = q.to_bqm()
    assert qb.vartype is dimod.BINARY
    assert np.array_equal(from_bqm(qb).energy(X), E)
    assert np.array_equal(IsingModel.from_bqm(qb).energy(S), E)


def test_lower_triangle_is_folded_and_diagonal_refused():
    J = np.array([[0, 1.0, 0], [2.0, 0, 0], [0, 0, 0]])
    m = IsingModel([0, 0, 0], J)
    assert m.J[0, 1] == 3.0 and m.J[1, 0] == 0.0
    with pytest.raises(ModelError, match=r"J\[1, 1\]"):
        IsingModel([0, 0], [[0, 0], [0, 1.0]])
    with pytest.raises(ModelError, match="not finite"):
        IsingModel([0, np.nan], np.zeros((2, 2)))
    with pytest.raises(ModelError, match="shape"):
        IsingModel([0, 0], np.zeros((3, 3)))


def test_labels_round_trip_through_bqm():
    bqm = dimod.BinaryQuadraticModel({"a": 1.0, ("x", 1): -2.0}, {("a", ("x", 1)): 3.0}, 0.5, "SPIN")
    m = IsingModel.from_bqm(bqm)
    assert m.labels == ("a", ("x", 1))
    back = m.to_bqm()
    assert back == bqm
    q = QuboModel([1.0, 2.0], [[0, -4.0], [0, 0]], 1.0, labels=("u", "v"))
    assert q.to_bqm().energy({"u": 1, "v": 1}) == q.energy([1, 1]) == 1.0 + 2.0 - 4.0 + 1.0


def test_energy_vectorised_over_leading_axes():
    m = IsingModel([1.0, -1.0], [[0, 2.0], [0, 0]])
    S = _states(2).reshape(2, 2, 2)
    assert m.energy(S).shape == (2, 2)
    assert m.energy([1, 1]) == 2.0


def test_docstring_examples_run():
    import doctest

    import ising_backend
    import ising_backend.machines.chip

    for mod in (ising_backend, ising_backend.machines.chip):
        assert doctest.testmod(mod).failed == 0
