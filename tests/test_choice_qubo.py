"""The at-most-one reduction of a one-choice-per-robot QUBO against brute force over every assignment."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from planners.mapf.chip.choice_qubo import read_option, reduce_to_reference


def random_problem(rng):
    sizes = rng.integers(1, 5, size=rng.integers(1, 5))
    starts = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    n = int(starts[-1])
    q = np.triu(rng.integers(-9, 10, size=(n, n)) * (rng.random((n, n)) < 0.6)).astype(np.int64)
    ref = np.array([rng.integers(0, k) for k in sizes], dtype=np.int64)
    return sizes, starts, q, ref


@pytest.mark.parametrize("seed", range(40))
def test_reduced_energy_is_the_objective_less_the_references_on_every_choice(seed):
    rng = np.random.default_rng(seed)
    sizes, starts, q, ref = random_problem(rng)
    n, size = int(starts[-1]), len(sizes)
    robot = np.repeat(np.arange(size), sizes)
    cross = np.where(robot[:, None] != robot[None, :], q, np.diag(np.diag(q)))  # a choice never sets two of a robot
    amo = int(rng.integers(1, 20))
    out = np.full((n, n), 99, np.int64)
    m = reduce_to_reference(q, starts, ref, amo, out)
    assert m == n - size
    others = [[x for x in range(starts[t], starts[t + 1]) if x != starts[t] + ref[t]] for t in range(size)]
    spin = {x: i for i, x in enumerate(x for t in range(size) for x in others[t])}  # reduced spins in order
    x_ref = np.zeros(n, np.int64)
    x_ref[starts[:-1] + ref] = 1
    base = int(x_ref @ cross @ x_ref)
    for choice in itertools.product(*[range(k) for k in sizes]):
        x = np.zeros(n, np.int64)
        x[starts[:-1] + np.array(choice)] = 1
        y = np.zeros(m, np.int64)
        for t, c in enumerate(choice):
            if c != ref[t]:
                y[spin[starts[t] + c]] = 1
        assert int(y @ np.triu(out[:m, :m]) @ y) == int(x @ cross @ x) - base
        # decoding a read: the robot's spin up, its reference when none is up
        read = np.where(y > 0, 1, -1).astype(np.int8)
        assert [read_option(read, starts, ref, t) for t in range(size)] == list(choice)
    for t in range(size):  # two spins of one robot: exactly the at-most-one penalty between them
        for a, b in itertools.combinations(others[t], 2):
            assert out[spin[a], spin[b]] == amo
            read = -np.ones(m, np.int8)
            read[[spin[a], spin[b]]] = 1
            assert read_option(read, starts, ref, t) == -1
