"""Classical tours: NN, 2-opt, 3-opt (4 and 7 moves), Held-Karp brute."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mrmt_env import generate_world
from planners.tours_classical import (
    MAX_BRUTE_TARGETS,
    BruteTour,
    _held_karp_dp,
    NearestNeighbourTour,
    ThreeOptTour,
    TwoOptTour,
    held_karp_subset_costs,
    route_cost,
)

SOLVERS = [NearestNeighbourTour(), TwoOptTour(), TwoOptTour(free_end=True), ThreeOptTour("4"), ThreeOptTour("7"),
           BruteTour()]


def _instance(seed, n, kind="grid"):
    if kind == "grid":
        return generate_world(seed, n_robots=1, n_targets=n).distance_matrix
    pts = np.random.default_rng(seed).random((n + 1, 2))
    return np.sqrt(((pts[:, None] - pts[None]) ** 2).sum(-1))


def _enumerate(d):
    n = d.shape[0] - 1
    return min(route_cost(d, p) for p in itertools.permutations(range(1, n + 1)))


@pytest.mark.parametrize("seed", range(12))
@pytest.mark.parametrize("kind", ["grid", "euclid"])
def test_brute_equals_all_permutations(seed, kind):
    n = 2 + seed % 6  # 2..7 targets
    d = _instance(seed, n, kind)
    res = BruteTour().solve(d)
    assert sorted(res.order) == list(range(1, n + 1))
    assert res.cost == pytest.approx(_enumerate(d))
    assert res.cost == pytest.approx(route_cost(d, res.order))


@pytest.mark.parametrize("seed", range(40))
def test_improvers_never_worse_than_nn_and_never_better_than_brute(seed):
    kind = "grid" if seed % 2 else "euclid"
    d = _instance(seed, 10, kind)
    results = {repr(s): s.solve(d) for s in SOLVERS}
    nn = results[repr(NearestNeighbourTour())].cost
    opt = results[repr(BruteTour())].cost
    for name, res in results.items():
        assert sorted(res.order) == list(range(1, 11)), name
        assert res.cost == pytest.approx(route_cost(d, res.order)), name
        assert opt - 1e-9 <= res.cost <= nn + 1e-9, name


def test_nearest_neighbour_is_greedy():
    d = _instance(3, 8, "euclid")
    order = NearestNeighbourTour().solve(d).order
    cur, left = 0, set(range(1, 9))
    for x in order:
        assert d[cur, x] == min(d[cur, y] for y in left)
        left.remove(x)
        cur = x


def test_three_opt_seven_moves_at_least_as_good_on_average():
    costs4, costs7 = [], []
    for seed in range(30):
        d = _instance(seed, 10)
        costs4.append(ThreeOptTour("4").solve(d).cost)
        costs7.append(ThreeOptTour("7").solve(d).cost)
    assert np.mean(costs7) <= np.mean(costs4)


def test_trivial_sizes():
    d0 = np.zeros((1, 1))
    d1 = np.array([[0.0, 3.0], [3.0, 0.0]])
    for s in SOLVERS:
        assert s.solve(d0).order == () and s.solve(d0).cost == 0
        assert s.solve(d1).order == (1,) and s.solve(d1).cost == 3


def test_brute_refuses_too_many_targets():
    d = _instance(0, MAX_BRUTE_TARGETS + 1, "euclid")
    with pytest.raises(ValueError, match="14 targets exceeds the limit of 13"):
        BruteTour().solve(d)


def test_bad_inputs():
    with pytest.raises(ValueError, match="moves must be one of"):
        ThreeOptTour(moves="5")
    with pytest.raises(ValueError, match="square"):
        NearestNeighbourTour().solve(np.zeros((2, 3)))


def test_infinite_distances_give_infinite_cost_not_crash():
    d = _instance(1, 5, "euclid")
    d[0, 3] = d[3, 0] = np.inf
    d[2, 3] = d[3, 2] = np.inf
    d[1, 3] = d[3, 1] = d[4, 3] = d[3, 4] = d[5, 3] = d[3, 5] = np.inf
    for s in SOLVERS:
        res = s.solve(d)
        assert sorted(res.order) == [1, 2, 3, 4, 5]
        assert res.cost == np.inf


def test_held_karp_subset_costs_match_brute():
    d = _instance(5, 6, "euclid")
    best = held_karp_subset_costs(d)
    assert best[0] == 0
    for mask in range(1, 1 << 6):
        nodes = [j + 1 for j in range(6) if mask >> j & 1]
        sub = d[np.ix_([0] + nodes, [0] + nodes)]
        assert best[mask] == pytest.approx(_enumerate(sub))


def _held_karp_push(d):
    """The textbook push-form Held-Karp (the reference of the compiled pull form)."""
    n = d.shape[0] - 1
    dp = np.full((1 << n, n), np.inf)
    par = np.full((1 << n, n), -1, dtype=np.int64)
    best = np.full(1 << n, np.inf)
    best[0] = 0.0
    for j in range(n):
        dp[1 << j, j] = d[0, j + 1]
    for s in range(1, 1 << n):
        best[s] = min(dp[s, j] for j in range(n) if s >> j & 1)
        for j in range(n):
            if not s >> j & 1 or dp[s, j] == np.inf:
                continue
            for x in range(n):
                if not s >> x & 1 and dp[s, j] + d[j + 1, x + 1] < dp[s | 1 << x, x]:
                    dp[s | 1 << x, x] = dp[s, j] + d[j + 1, x + 1]
                    par[s | 1 << x, x] = j
    return dp, par, best


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 7), st.integers(0, 2**32 - 1), st.sampled_from(["ties", "euclid", "inf"]))
def test_held_karp_table_matches_push_reference(n, seed, kind):
    """Same values (bit for bit), parents (the smallest j of least cost) and subset minima,
    on tie-heavy integer, Euclidean and partly unreachable instances."""
    rng = np.random.default_rng(seed)
    if kind == "euclid":
        d = _instance(seed % 1000, n, "euclid")
    else:
        d = rng.integers(1, 4, (n + 1, n + 1)).astype(float)
        if kind == "inf":
            d[rng.random(d.shape) < 0.3] = np.inf
    ref_dp, ref_par, ref_best = _held_karp_push(d)
    par = np.full((1 << n, n), -1, dtype=np.int64)
    best = np.full(1 << n, -1.0)
    dp = _held_karp_dp(d, par, best)
    member = np.array([[s >> j & 1 for j in range(n)] for s in range(1 << n)], dtype=bool)
    assert np.array_equal(dp[member], ref_dp[member])
    assert np.array_equal(par, ref_par)
    assert np.array_equal(best, ref_best)
    bare = _held_karp_dp(d, None, None)  # no parents, no subset minima: the same table
    assert np.array_equal(bare[member], ref_dp[member])
