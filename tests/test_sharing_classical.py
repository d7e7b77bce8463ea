"""Classical sharing: round robin, PSA, SSA (insertion and tour bids), exact."""

import itertools

import numpy as np
import pytest

from mrmt_env import generate_world
from planners.sharing_classical import (
    MAX_EXACT_TARGETS,
    ExactSharing,
    PSASharing,
    RoundRobinSharing,
    SSASharing,
)
from planners.tours_classical import BruteTour

METHODS = [RoundRobinSharing(), PSASharing(), SSASharing(), SSASharing(bid="tour"), ExactSharing()]


def _total(d, r, assignment):
    bt = BruteTour()
    total = 0.0
    for k, group in enumerate(assignment):
        idx = [k] + [r + t for t in group]
        total += bt.solve(d[np.ix_(idx, idx)]).cost
    return total


def _euclid(seed, r, n):
    pts = np.random.default_rng(seed).random((r + n, 2)) * 10
    return np.sqrt(((pts[:, None] - pts[None]) ** 2).sum(-1))


@pytest.mark.parametrize("method", METHODS, ids=repr)
@pytest.mark.parametrize("seed", range(8))
def test_every_target_exactly_once(method, seed):
    r, n = 1 + seed % 4, seed + 2
    world = generate_world(seed, n_robots=r, n_targets=n)
    res = method.assign(world.distance_matrix, r, BruteTour())
    assert len(res.assignment) == r
    flat = [t for g in res.assignment for t in g]
    assert sorted(flat) == list(range(n))


@pytest.mark.parametrize("seed", range(10))
def test_exact_equals_enumeration(seed):
    r, n = 2 + seed % 2, 4 + seed % 3
    d = _euclid(seed, r, n) if seed % 2 else generate_world(seed, n_robots=r, n_targets=n).distance_matrix
    res = ExactSharing().assign(d, r, BruteTour())
    best = min(
        _total(d, r, [[t for t in range(n) if owner[t] == k] for k in range(r)])
        for owner in itertools.product(range(r), repeat=n)
    )
    assert res.stats["optimum"] == pytest.approx(best)
    assert _total(d, r, res.assignment) == pytest.approx(best)


@pytest.mark.parametrize("seed", range(10))
def test_exact_is_a_lower_bound_for_the_others(seed):
    world = generate_world(seed, n_robots=3, n_targets=10)
    d = world.distance_matrix
    opt = ExactSharing().assign(d, 3, BruteTour()).stats["optimum"]
    for m in METHODS:
        assert _total(d, 3, m.assign(d, 3, BruteTour()).assignment) >= opt - 1e-9


def test_round_robin_deals_in_index_order():
    d = np.zeros((3 + 7, 3 + 7))
    assert RoundRobinSharing().assign(d, 3).assignment == ((0, 3, 6), (1, 4), (2, 5))


def test_psa_gives_each_target_to_nearest_robot():
    d = _euclid(4, 3, 9)
    res = PSASharing().assign(d, 3)
    for k, group in enumerate(res.assignment):
        for t in group:
            assert d[k, 3 + t] == d[:3, 3 + t].min()


def test_psa_ties_go_to_lowest_robot():
    d = np.zeros((4, 4))  # every bid equal
    assert PSASharing().assign(d, 2).assignment == ((0, 1), ())


def test_ssa_insertion_matches_a_reference_auction():
    """A plain-Python re-statement of the MiniSum insertion auction."""
    for seed in range(6):
        r, n = 3, 8
        d = _euclid(seed, r, n)
        paths = [[k] for k in range(r)]
        left = list(range(n))
        while left:
            best = None
            for k in range(r):
                for t in left:
                    node = r + t
                    options = [(d[paths[k][-1], node], len(paths[k]))]
                    options += [(d[paths[k][p - 1], node] + d[node, paths[k][p]] - d[paths[k][p - 1], paths[k][p]], p)
                                for p in range(1, len(paths[k]))]
                    cost = options[0][0]
                    pos = options[0][1]
                    for c, p in options[1:]:
                        if c < cost:
                            cost, pos = c, p
                    if best is None or cost < best[0]:
                        best = (cost, k, t, pos)
            _, k, t, pos = best
            paths[k].insert(pos, r + t)
            left.remove(t)
        expected = tuple(tuple(x - r for x in p[1:]) for p in paths)
        assert SSASharing().assign(d, r).assignment == expected


def test_ssa_tour_bids_need_a_tour_solver():
    with pytest.raises(ValueError, match="needs the downstream tour solver"):
        SSASharing(bid="tour").assign(np.zeros((4, 4)), 2, None)
    with pytest.raises(ValueError, match="bid must be one of"):
        SSASharing(bid="price")


def test_exact_refuses_too_many_targets():
    d = np.zeros((1 + MAX_EXACT_TARGETS + 1,) * 2)
    with pytest.raises(ValueError, match="17 targets exceeds the limit of 16"):
        ExactSharing().assign(d, 1)


def test_no_targets_and_bad_robot_count():
    d = np.zeros((2, 2))
    for m in METHODS:
        assert m.assign(d, 2, BruteTour()).assignment == ((), ())
    with pytest.raises(ValueError, match="n_robots must be an integer in 1..2"):
        PSASharing().assign(d, 3)


def test_unreachable_targets_go_to_a_robot_that_reaches_them():
    d = _euclid(2, 2, 4)
    d[0, 2:] = d[2:, 0] = np.inf  # robot 0 reaches nothing
    d[0, 1] = d[1, 0] = np.inf
    for m in (PSASharing(), SSASharing(), SSASharing(bid="tour"), ExactSharing()):
        res = m.assign(d, 2, BruteTour())
        assert res.assignment[0] == () and sorted(res.assignment[1]) == [0, 1, 2, 3]
