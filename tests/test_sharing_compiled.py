"""The Ising target sharing against the Python search in tests, its oracle.

``planners.ising.sharing.IsingSharing.assign`` (a search over compiled steps on node-set ids) must make every decision of the Python
search in ``tests/sharing_search_reference.py`` (stages, memo, beam, coarse splits of groups
beyond the chip, spin-budget branches, bundle placement, state choice, boundary refinement): the
same assignment, statistics, chip charges, rng state and failures, for every option.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ising_backend import ChipSpec, EmulatedChip
from mrmt_env.generation import generate_world
from planners.ising.sharing import IsingSharing, PaperIsingSharing, SharingConfig
from planners.ising.sharing.split_problem import pair_mean
from planners.tours_classical import ThreeOptTour
from sharing_search_reference import reference_assign

CONFIGS = [
    {},
    {"bundle_order": "far_first", "pair_neighbours": 1},
    {"bundle_order": "near_first", "beam": 1, "max_states": 4},
    {"bundle_order": "largest_first", "refine_stages": 0, "pair_neighbours": 2},
    {"reject_empty_robot_side": True, "robot_weight": 0.5, "weight_shift": 0.0},
    {"weight_power": 2.0, "retries": 0, "reads": 1, "rules": ("linear", "rank"), "base_max": None},
    {"pair_shifts": (0.0,), "pair_rounds": 1, "refine_beam": 3},
]


def _pair(config: SharingConfig, spec: ChipSpec = ChipSpec(), paper: bool = False):
    cls = PaperIsingSharing if paper else IsingSharing
    fast, ref = cls(EmulatedChip(spec), config), cls(EmulatedChip(spec), config)
    ref.assign = lambda dist, R, tour, rng: reference_assign(ref, dist, R, tour, rng)  # the Python search
    return fast, ref


def _same(fast, ref, dist, R, seed):
    r1, r2 = np.random.default_rng(seed), np.random.default_rng(seed)
    a = fast.assign(dist, R, ThreeOptTour(), r1)
    b = ref.assign(dist, R, ThreeOptTour(), r2)
    assert a.assignment == b.assignment and a.failure == b.failure
    assert a.stats == b.stats
    assert (a.compute.chip_calls, a.compute.chip_batches) == (b.compute.chip_calls, b.compute.chip_batches)
    assert a.compute.accelerator_energy_j == pytest.approx(b.compute.accelerator_energy_j)
    assert fast.chip.ledger.physical_calls == ref.chip.ledger.physical_calls
    assert r1.bit_generator.state == r2.bit_generator.state
    return a


@pytest.mark.parametrize("options", CONFIGS + ["paper"])
def test_compiled_sharing_makes_the_python_searchs_decisions(options):
    paper = options == "paper"
    fast, ref = _pair(SharingConfig.paper() if paper else SharingConfig(**options), paper=paper)

    resplits = accepted = 0
    for s in range(20, 32):
        R, N = 2 + s % 4, 4 + s % 10
        w = generate_world(s, n_robots=R, n_targets=N, placement="centre" if s % 2 else "uniform")
        res = _same(fast, ref, w.distance_matrix, R, s)
        if res.failure is not None:  # a split with no valid candidate, named as the Python search names it
            assert "invalid after" in res.failure
            continue
        assert sorted(t for ts in res.assignment for t in ts) == list(range(N))
        resplits += res.stats.get("pair_resplits", 0)
        accepted += res.stats.get("pair_accepted", 0)
    assert (resplits > 0) == (not paper)  # the boundary refinement ran, in both searches
    if options == {}:
        assert accepted > 0  # and moved targets


@pytest.mark.parametrize("spec, R, N", [(ChipSpec(n_spins=8), 2, 12),  # 12 free spins: spin-budget branching
                                        (ChipSpec(n_spins=6), 2, 13),  # 13 free spins > 6 + max_frozen: coarse
                                        (ChipSpec(n_spins=6), 9, 20)])  # robots beyond half the chip: clustered
def test_groups_beyond_the_chip_split_on_branches_and_clusters_as_the_python_search_splits_them(spec, R, N):
    for options in ({}, {"pair_rounds": 0, "beam": 1}, {"max_frozen": 0}):
        fast, ref = _pair(SharingConfig(**options), spec)
        w = generate_world(3 + N, n_robots=R, n_targets=N)
        res = _same(fast, ref, w.distance_matrix, R, 3)
        assert res.failure is None
        assert (res.stats.get("coarse_splits", 0) > 0) == (spec.n_spins == 6 or not options.get("max_frozen", 4))


@pytest.mark.parametrize("paper", [False, True])
def test_big_worlds_take_coarse_splits_and_branches_as_the_python_search_takes_them(paper):
    """The 45-spin chip: 50-51 nodes branch, 70-160 nodes split on clusters (robots clustered when
    they alone fill half the chip)."""
    fast, ref = _pair(SharingConfig.paper() if paper else SharingConfig(), paper=paper)
    coarse = 0
    for H, R, N in [(32, 4, 46), (32, 3, 48), (40, 6, 90), (48, 30, 40), (64, 10, 150)]:
        w = generate_world(7 + N, height=H, width=H, n_robots=R, n_targets=N)
        res = _same(fast, ref, w.distance_matrix, R, N)
        assert res.failure is None
        assert sorted(t for ts in res.assignment for t in ts) == list(range(N))
        coarse += res.stats.get("coarse_splits", 0)
    assert coarse > 0


@pytest.mark.parametrize("options", [{}, {"bundle_order": "far_first", "pair_neighbours": 1}, "paper"])
def test_more_targets_than_held_karp_takes_are_priced_by_the_3opt_kernel_in_the_compiled_call(options):
    """14-30 targets: bundles above 13 targets are priced by the host 3-opt tour in both searches."""
    paper = options == "paper"
    fast, ref = _pair(SharingConfig.paper() if paper else SharingConfig(**options), paper=paper)
    big_sets = 0
    for s in range(40, 46):
        R, N = 2 + s % 3, 14 + 3 * (s % 6)
        w = generate_world(s, height=16, width=16, n_robots=R, n_targets=N)
        res = _same(fast, ref, w.distance_matrix, R, s)
        big_sets += res.failure is None and max(len(ts) for ts in res.assignment) > 13
    assert big_sets > 0


@pytest.mark.parametrize("options", [{"balance": 0.5}, {"balance": 2.0, "beam": 1}, {"pricing_tour": "3opt"},
                                     {"pricing_tour": "downstream"}, {"pricing_tour": "ising", "balance": 1.0}])
def test_balance_and_pricing_tours_run_in_the_compiled_call_with_the_python_searchs_decisions(options):
    """The balance term in the compiled split models; bundles priced by a pricing tour other than
    "auto" through the callback into the call's pricer (the Ising tour's chip calls and rng draws
    interleaved with the sharing's own, as in the Python search)."""
    fast, ref = _pair(SharingConfig(**options))
    solves = 0
    for s in range(40, 46):
        R, N = 2 + s % 3, 6 + s % 7
        w = generate_world(s, n_robots=R, n_targets=N, placement="uniform")
        res = _same(fast, ref, w.distance_matrix, R, s)
        solves += res.stats["tour_solves"]
    assert solves > 0


def test_a_failing_pricing_tour_fails_the_sharing_with_the_chip_calls_charged():
    class Broken(ThreeOptTour):
        def solve(self, dist, rng=None):
            res = super().solve(dist, rng)
            return type(res)(order=res.order, cost=res.cost, compute=res.compute, failure="no tour today")

    w = generate_world(3, n_robots=3, n_targets=9, placement="uniform")
    for sharing in _pair(SharingConfig(pricing_tour=Broken())):
        res = sharing.assign(w.distance_matrix, 3, ThreeOptTour(), np.random.default_rng(3))
        assert res.failure == "tour solver failed while pricing a bundle: no tour today"
        assert res.compute.chip_calls == sharing.chip.ledger.physical_calls > 0


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 2**31), st.integers(2, 9), st.integers(1, 4), st.sampled_from([0.0, 0.5, -1.0]),
       st.sampled_from([1.0, 0.25, 3.0]), st.sampled_from([1.0, 2.0]))
def test_split_weights_are_the_shifted_powered_distances_with_robot_edges_scaled(seed, n, R, shift, robot_weight,
                                                                                power):
    R = min(R, n)
    x = np.random.default_rng(seed).integers(0, 20, size=(n, n)).astype(float)
    dist = x + x.T
    np.fill_diagonal(dist, 0.0)
    sharing = IsingSharing(config=SharingConfig(robot_weight=robot_weight, weight_power=power))
    base = dist ** power
    want = base - shift * (base[np.triu_indices(n, 1)].mean() if n > 1 else 0.0)
    np.fill_diagonal(want, 0.0)
    want[:R, R:] *= robot_weight
    want[R:, :R] *= robot_weight
    got = sharing.split_weights(dist, R, shift=shift)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-9)
    assert np.array_equal(sharing._powered(dist)[0], base)  # the cached base is not changed in place


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 2**31), st.integers(0, 40))
def test_pair_mean_is_numpys_mean_over_pairs(seed, n):
    w = np.random.default_rng(seed).normal(size=(n, n)) * 10.0 ** np.random.default_rng(seed).integers(-3, 4)
    want = float(w[np.triu_indices(n, 1)].mean()) if n > 1 else 0.0
    assert pair_mean(w) == want


def test_a_split_without_a_valid_candidate_fails_as_the_python_search_fails():
    """Noisy reads and no retries: splits end without a valid candidate; the package's sharing stops
    there and names the group as the Python search does (same statistics, charges and rng state)."""
    config = SharingConfig(reads=1, retries=0, reject_empty_robot_side=True, fallback="never")
    fast, ref = _pair(config, ChipSpec(readout_flip_prob=0.2))
    failures = 0
    for s in (2, 3, 7, 10):
        R, N = 2 + s % 4, 4 + s % 10
        res = _same(fast, ref, generate_world(s, n_robots=R, n_targets=N).distance_matrix, R, s)
        failures += res.failure is not None and "was invalid after 1 submissions" in res.failure
    assert failures >= 2


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 2**31), st.integers(1, 9), st.integers(0, 3))
def test_spin_budget_branches_keep_the_split_energy_up_to_a_constant_per_branch(seed, n, k):
    """Each branch of :func:`branch_problems` is the split QUBO with its frozen nodes fixed: over the
    branch's free nodes its energy differs from the whole split's by one constant, the frozen nodes
    are the strongest, and the branches enumerate every sign pattern of them."""
    from planners.ising.sharing.split_problem import branch_problems

    rng = np.random.default_rng(seed)
    k = min(k, n)
    q = rng.normal(size=(1, n))
    Q = np.triu(rng.normal(size=(1, n, n)), 1)
    free = (100 + np.arange(n))[None]
    bq, bQ, bfree, bsizes, nfix, fixed, parent = branch_problems(q, Q, free, np.array([n]), n - k)
    assert len(parent) == 2 ** k and (parent == 0).all() and (bsizes == n - k).all() and (nfix == k).all()
    assert len({tuple(row[:k]) for row in fixed.tolist()}) == 2 ** k
    J = Q[0] + Q[0].T
    strength = np.abs(q[0] / 2 + J.sum(axis=1) / 4) + np.abs(J).sum(axis=1) / 4
    frozen = bfree[0, n - k:n] - 100
    assert sorted(frozen.tolist()) == sorted(np.argsort(-strength, kind="stable")[:k].tolist())
    for e in range(len(parent)):
        order = bfree[e, :n] - 100
        gaps = set()
        for _ in range(4):
            y = rng.integers(0, 2, size=n - k).astype(float)
            x = np.empty(n)
            x[order[:n - k]] = y
            x[order[n - k:]] = (fixed[e, :k] > 0)
            whole = q[0] @ x + x @ Q[0] @ x
            branch = bq[e, :n - k] @ y + y @ bQ[e, :n - k, :n - k] @ y
            gaps.add(round(whole - branch, 9))
        assert len(gaps) == 1
