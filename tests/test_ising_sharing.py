"""Recursive Ising target sharing (paper 5.3): formulation, planner behaviour, failures."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from mrmt_env.generation import generate_world
from planners.base import SharingResult
from planners.ising_sharing import (
    IsingSharing,
    SplitProblem,
    build_split_qubo,
    choose_anchors,
    cut_value,
    decode_split,
)
from planners.sharing_classical import ExactSharing, SSASharing
from planners.tours_classical import BruteTour


def _random_dist(n, seed):
    rng = np.random.default_rng(seed)
    pts = rng.integers(0, 10, size=(n, 2))
    d = np.abs(pts[:, None, :] - pts[None, :, :]).sum(-1).astype(float)
    return d


def _bits(f):
    return np.array(list(itertools.product([0, 1], repeat=f)), dtype=float)


# ----------------------------------------------------------------- formulation


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("n_robots", [0, 1, 2, 3])
def test_split_qubo_is_minus_cut_with_anchors_substituted(seed, n_robots):
    d = _random_dist(7, seed)
    nodes = np.arange(7)
    a, b = choose_anchors(d, nodes, n_robots)
    free = np.array([i for i in nodes if i not in (a, b)])
    q, Q, off = build_split_qubo(d, free, a, b, n_robots)
    assert np.allclose(Q, np.triu(Q, 1))
    for x in _bits(len(free)):
        e = off + q @ x + x @ Q @ x
        side1 = [b] + [int(v) for v, xi in zip(free, x) if xi]
        side0 = [a] + [int(v) for v, xi in zip(free, x) if not xi]
        assert e == pytest.approx(-cut_value(d, side0, side1))


def test_balance_term_adds_the_documented_penalty():
    d = _random_dist(8, 11)
    R = 3
    nodes = np.arange(8)
    a, b = choose_anchors(d, nodes, R)
    free = np.array([i for i in nodes if i not in (a, b)])
    lam = 0.7
    q0, Q0, o0 = build_split_qubo(d, free, a, b, R)
    q1, Q1, o1 = build_split_qubo(d, free, a, b, R, balance=lam)
    mean_w = d[np.triu_indices(8, 1)].mean()
    N = 8 - R
    for x in _bits(len(free)):
        side1 = [b] + [int(v) for v, xi in zip(free, x) if xi]
        T1 = sum(1 for v in side1 if v >= R)
        R1 = sum(1 for v in side1 if v < R)
        pen = lam * mean_w * (R * T1 - N * R1) ** 2 / R**2
        e0 = o0 + q0 @ x + x @ Q0 @ x
        e1 = o1 + q1 @ x + x @ Q1 @ x
        assert e1 - e0 == pytest.approx(pen)


def test_anchor_rules():
    # nodes 0,1,2 robots; 3..6 targets on a line
    pos = np.array([0, 5, 9, 1, 2, 20, 30])
    d = np.abs(pos[:, None] - pos[None, :]).astype(float)
    assert choose_anchors(d, [0, 1, 2, 3, 4, 5, 6], 3) == (0, 2)  # farthest robot pair
    assert choose_anchors(d, [1, 3, 4, 5, 6], 3) == (1, 6)  # robot + farthest target
    assert choose_anchors(d, [3, 4, 5], 3) == (3, 5)  # farthest target pair
    with pytest.raises(ValueError, match="at least 2"):
        choose_anchors(d, [3], 3)


def test_decode_rejects_malformed_spins():
    p = SplitProblem(nodes=np.arange(5), a=0, b=4, free=np.array([1, 2, 3]), q=np.zeros(3),
                     Q=np.zeros((3, 3)), offset=0.0, kind="refine")
    s0, s1 = decode_split(p, np.array([1, -1, 1]))
    assert s0.tolist() == [0, 2] and s1.tolist() == [1, 3, 4]
    assert decode_split(p, np.array([1, 0, 1])) is None
    assert decode_split(p, np.array([1, 1])) is None
    assert decode_split(p, np.array([1, np.nan, 1])) is None
