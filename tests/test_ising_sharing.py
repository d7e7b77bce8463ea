"""Recursive Ising target sharing (paper 5.3): formulation, planner behaviour, failures."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mrmt_env.generation import generate_world
from planners.base import SharingResult
from planners.ising.sharing import IsingSharing
from planners.sharing_classical import ExactSharing
from planners.tours_classical import BruteTour, ThreeOptTour
from sharing_search_reference import SplitProblem, build_split_qubo, choose_anchors, cut_value, decode_split


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


# ----------------------------------------------------------------- planner

TOUR = BruteTour()


def _totals(dist, R, assignment):
    lengths = []
    for k, group in enumerate(assignment):
        nodes = [k] + [R + t for t in group]
        lengths.append(TOUR.solve(dist[np.ix_(nodes, nodes)]).cost if group else 0.0)
    return lengths


def _check_partition(assignment, R, N):
    assert len(assignment) == R
    flat = sorted(t for g in assignment for t in g)
    assert flat == list(range(N))


@pytest.mark.parametrize("placement", ["uniform", "centre"])
@pytest.mark.parametrize("seed", range(6))
def test_valid_assignment_on_random_worlds(seed, placement):
    world = generate_world(seed, n_robots=3, n_targets=10, placement=placement)
    sharing = IsingSharing()
    res = sharing.assign(world.distance_matrix, world.n_robots, TOUR, np.random.default_rng(seed))
    assert isinstance(res, SharingResult)
    assert "failure" not in res.stats
    _check_partition(res.assignment, 3, 10)
    c = res.compute
    assert c.chip_calls >= 1 and c.chip_batches >= 1
    ledger = sharing.chip.ledger  # charged exactly what the chip recorded
    assert (c.chip_calls, c.chip_batches, c.logical_calls) == (ledger.physical_calls, ledger.batches,
                                                              ledger.logical_calls)
    assert c.accelerator_energy_j == pytest.approx(c.chip_calls * 0.45e-6)
    assert c.chip_time_s == pytest.approx(c.chip_calls * 50e-6)
    m = res.stats["mapping"]["sharing"]
    assert set(m) == {"linear", "clip95", "rank", "sqrt"}
    assert sum(v["wins"] for v in m.values()) == res.stats["splits"] - res.stats.get("trivial_splits", 0)
    for v in m.values():
        assert v["valid"] <= v["reads"] == v["programs"] * sharing.config.reads and v["map_errors"] == 0


@pytest.mark.parametrize("shape", [(2, 5), (4, 12), (5, 20), (1, 6), (3, 1), (3, 0)])
def test_other_sizes(shape):
    R, N = shape
    world = generate_world(7, n_robots=R, n_targets=N, placement="uniform")
    tour = ThreeOptTour() if N > 12 else TOUR  # Held-Karp prices at most 13 targets
    res = IsingSharing().assign(world.distance_matrix, R, tour, np.random.default_rng(0))
    assert "failure" not in res.stats
    _check_partition(res.assignment, R, N)
    if R == 1 or N == 0:
        assert res.compute.chip_calls == 0


def test_deterministic_under_seed():
    world = generate_world(3, placement="centre")
    d = world.distance_matrix
    a = IsingSharing().assign(d, 3, TOUR, np.random.default_rng(42))
    b = IsingSharing().assign(d, 3, TOUR, np.random.default_rng(42))
    assert a.assignment == b.assignment
    assert a.compute == b.compute
    assert a.stats == b.stats


def test_two_separated_clusters_go_to_their_robots():
    # a corridor: robot 0 at x=0 with targets at 1,2,3; robot 1 at x=30 with targets at 27,28,29
    pos = np.array([0, 30, 1, 2, 3, 27, 28, 29], dtype=float)
    d = np.abs(pos[:, None] - pos[None, :])
    res = IsingSharing().assign(d, 2, TOUR, np.random.default_rng(0))
    assert res.assignment == ((0, 1, 2), (3, 4, 5))
    assert sum(_totals(d, 2, res.assignment)) == 6.0


def test_three_targets_on_a_line_single_robot_gets_all():
    pos = np.array([0, 1, 2, 3], dtype=float)
    d = np.abs(pos[:, None] - pos[None, :])
    res = IsingSharing().assign(d, 1, TOUR, np.random.default_rng(0))
    assert res.assignment == ((0, 1, 2),)


def test_quality_close_to_exact_on_centre_worlds():
    """Few worlds, loose bound: the mean total stays within 10% of the min-sum optimum."""
    ising, exact = [], []
    for seed in range(8):
        world = generate_world(seed, placement="centre")
        d = world.distance_matrix
        res = IsingSharing().assign(d, 3, TOUR, np.random.default_rng(seed))
        ising.append(sum(_totals(d, 3, res.assignment)))
        ex = ExactSharing().assign(d, 3, TOUR)
        exact.append(sum(_totals(d, 3, ex.assignment)))
    assert all(i >= e for i, e in zip(ising, exact))
    assert np.mean(ising) <= 1.10 * np.mean(exact)


def test_unrefined_split_has_one_group_per_robot_and_no_bundles():
    world = generate_world(5, placement="centre")
    res = IsingSharing(refine_stages=0, beam=1, pair_rounds=0).assign(world.distance_matrix, 3, TOUR,
                                                                     np.random.default_rng(0))
    assert res.stats["bundles"] == 0 and res.stats["tour_solves"] == 0
    assert res.stats["stages"] == 2  # 3 robots: two robot stages
    _check_partition(res.assignment, 3, 10)


# ----------------------------------------------------------------- failures


class GarbageChip:
    """A chip that returns zeros (not +-1) for every spin: nothing decodes."""

    def __init__(self):
        from ising_backend import CallLedger, ChipSpec

        self.spec = ChipSpec()
        self.ledger = CallLedger()

    def anneal_batch(self, h, J, num_reads=1, seed=None):
        h = np.asarray(h)
        self.ledger.record_physical(h.shape[0] * num_reads, self.spec)
        return np.zeros((h.shape[0], num_reads, h.shape[1]), dtype=np.int8), np.zeros((h.shape[0], num_reads))


def test_garbage_chip_gives_a_clear_failure():
    world = generate_world(1, placement="centre")
    chip = GarbageChip()
    res = IsingSharing(chip=chip, retries=1).assign(world.distance_matrix, 3, TOUR, np.random.default_rng(0))
    assert "malformed samples" in res.failure and "failure" not in res.stats
    assert res.assignment == ((), (), ())
    assert res.compute.chip_calls == chip.ledger.physical_calls > 0
    m = res.stats["mapping"]["sharing"]
    assert all(v["valid"] == 0 for v in m.values())


def test_unreachable_node_gives_a_clear_failure():
    world = generate_world(2)
    d = world.distance_matrix.copy()
    d[0, 5] = d[5, 0] = np.inf
    res = IsingSharing().assign(d, 3, TOUR, np.random.default_rng(0))
    assert "cannot reach" in res.failure


def test_split_slightly_over_the_spin_limit_uses_branching():
    from ising_backend import ChipSpec, EmulatedChip

    world = generate_world(4, n_robots=3, n_targets=10, placement="centre")
    chip = EmulatedChip(ChipSpec(n_spins=9))  # root split: 11 free spins -> 2 frozen, 4 branches per rule
    res = IsingSharing(chip=chip).assign(world.distance_matrix, 3, TOUR, np.random.default_rng(0))
    assert res.failure is None
    _check_partition(res.assignment, 3, 10)
    full = IsingSharing().assign(world.distance_matrix, 3, TOUR, np.random.default_rng(0))
    assert sum(_totals(world.distance_matrix, 3, res.assignment)) <= 1.1 * sum(
        _totals(world.distance_matrix, 3, full.assignment))


def test_group_over_the_spin_limit_is_split_on_clusters_not_refused():
    from ising_backend import ChipSpec, EmulatedChip

    world = generate_world(4, n_robots=3, n_targets=10)
    chip = EmulatedChip(ChipSpec(n_spins=8))
    res = IsingSharing(chip=chip, max_frozen=2).assign(world.distance_matrix, 3, TOUR, np.random.default_rng(0))
    assert res.failure is None and res.stats["coarse_splits"] >= 1
    assert sorted(t for g in res.assignment for t in g) == list(range(10))
    assert res.compute.chip_calls == chip.ledger.physical_calls > 0  # every call charged, exactly


@pytest.mark.parametrize(
    "kw, match",
    [
        ({"reads": 0}, "reads"),
        ({"rules": ("linear", "bogus")}, "bogus"),
        ({"bundle_order": "random"}, "bundle_order"),
        ({"refine_above": 0}, "refine_above"),
        ({"weight_power": -1.0}, "weight_power"),
        ({"balance": float("nan")}, "balance"),
    ],
)
def test_bad_options_are_refused(kw, match):
    with pytest.raises(ValueError, match=match):
        IsingSharing(**kw)


def test_bad_inputs_are_refused():
    with pytest.raises(ValueError, match="square"):
        IsingSharing().assign(np.zeros((3, 4)), 1, TOUR)
    with pytest.raises(ValueError, match="n_robots"):
        IsingSharing().assign(np.zeros((3, 3)), 4, TOUR)


def test_in_a_pipeline_plans_are_valid_and_mapping_counts_merge():
    from planners.pipeline import make_pipeline
    from planners.plan import validate_plan

    world = generate_world(11, placement="centre")
    pipe = make_pipeline(sharing="ising", tour="brute", path="astar")
    plan = pipe.plan(world, seed=3)
    assert plan.success
    validate_plan(world, plan)
    assert plan.stats["layers"]["sharing"].chip_calls >= 1
    ledger = pipe.sharing.chip.ledger  # the sharing layer is the only chip user: its calls, exactly
    assert plan.compute.chip_calls == plan.stats["layers"]["sharing"].chip_calls == ledger.physical_calls
    assert plan.compute.logical_calls == ledger.logical_calls == 0
    assert set(plan.stats["mapping"]["sharing"]) == {"linear", "clip95", "rank", "sqrt"}
    again = make_pipeline(sharing="ising", tour="brute", path="astar").plan(world, seed=3)
    assert [r.targets for r in again.routes] == [r.targets for r in plan.routes]


def test_pricing_tour_option_is_used_and_charged():
    class CountingTour:
        name = "counting"

        def __init__(self):
            self.calls = 0

        def solve(self, dist, rng=None):
            self.calls += 1
            return TOUR.solve(dist, rng)

    world = generate_world(2, placement="centre")
    downstream, pricing = CountingTour(), CountingTour()
    res = IsingSharing(pricing_tour=pricing).assign(world.distance_matrix, 3, downstream, np.random.default_rng(0))
    assert downstream.calls == 0 and pricing.calls == res.stats["tour_solves"] > 0
    by_name = IsingSharing(pricing_tour="brute").assign(world.distance_matrix, 3, downstream, np.random.default_rng(0))
    assert by_name.assignment == res.assignment
    with pytest.raises(ValueError, match="pricing_tour"):
        IsingSharing(pricing_tour=42)
    # 'downstream' uses the tour handed to assign; 'auto' prices up to 13 targets exactly on the host
    down = CountingTour()
    IsingSharing(pricing_tour="downstream").assign(world.distance_matrix, 3, down, np.random.default_rng(0))
    assert down.calls > 0
    auto = CountingTour()
    res_auto = IsingSharing().assign(world.distance_matrix, 3, auto, np.random.default_rng(0))
    assert auto.calls == 0 and res_auto.assignment == res.assignment


def test_chip_refusing_programs_gives_a_clear_failure():
    from ising_backend import ChipProgramError

    class RefusingChip(GarbageChip):
        def anneal_batch(self, h, J, num_reads=1, seed=None):
            raise ChipProgramError("h[0] = 9 is outside h_range (-7, 7)")

    world = generate_world(1, placement="centre")
    res = IsingSharing(chip=RefusingChip()).assign(world.distance_matrix, 3, TOUR, np.random.default_rng(0))
    assert "refused" in res.failure and "h_range" in res.failure
    assert res.assignment == ((), (), ())


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(R=st.integers(1, 4), N=st.integers(0, 11), seed=st.integers(0, 10_000))
def test_property_any_metric_instance_gives_a_partition(R, N, seed):
    d = _random_dist(R + N, seed)  # Manhattan distances of random points (ties and zeros included)
    res = IsingSharing().assign(d, R, TOUR, np.random.default_rng(seed))
    assert res.failure is None
    _check_partition(res.assignment, R, N)


def test_three_targets_on_a_line_between_two_robots_match_the_exact_optimum():
    pos = np.array([0, 10, 1, 2, 9], dtype=float)  # robots at 0 and 10, targets at 1, 2, 9
    d = np.abs(pos[:, None] - pos[None, :])
    res = IsingSharing().assign(d, 2, TOUR, np.random.default_rng(0))
    assert res.assignment == ((0, 1), (2,))
    ex = ExactSharing().assign(d, 2, TOUR)
    assert sum(_totals(d, 2, res.assignment)) == sum(_totals(d, 2, ex.assignment)) == 3.0


def test_worlds_of_several_components_are_shared_per_component():
    from mrmt_env import World
    from planners.pipeline import make_pipeline
    from planners.plan import validate_plan

    grid = np.zeros((5, 9), dtype=bool)
    grid[:, 4] = True  # a wall: two components
    world = World(grid, [[0, 0], [4, 1], [0, 8]], [[2, 2], [4, 3], [0, 6], [3, 7], [1, 0]])
    res = IsingSharing().assign(world.distance_matrix, 3, TOUR, np.random.default_rng(0))
    assert res.failure is None and res.stats["components"] == 2
    assert sorted(res.assignment[2]) == [2, 3]  # the right-hand robot takes the right-hand targets
    assert sorted(res.assignment[0] + res.assignment[1]) == [0, 1, 4]
    plan = make_pipeline("ising").plan(world, seed=0)
    assert plan.success, plan.failure
    validate_plan(world, plan)


# ---------------------------------------------------------------- groups larger than the chip
def test_coarse_cut_equals_the_fine_cut_of_cluster_respecting_partitions():
    from sharing_search_reference import coarsen, expand_sides

    rng = np.random.default_rng(3)
    for _ in range(20):
        n, R = int(rng.integers(6, 40)), int(rng.integers(0, 4))
        pts = rng.random((n, 2)) * 10
        w = np.abs(pts[:, None, :] - pts[None, :, :]).sum(-1) - 3.0  # shifted weights may be negative
        np.fill_diagonal(w, 0.0)
        group = np.arange(n)
        k = int(rng.integers(1, max(2, n - R)))
        members, wc = coarsen(w, group, R, k)
        assert sorted(np.concatenate(members).tolist()) == list(range(n))
        assert all(len(m) == 1 and m[0] < R for m in members[:R])
        side = rng.random(len(members)) < 0.5
        s0, s1 = np.flatnonzero(~side), np.flatnonzero(side)
        f0, f1 = expand_sides(members, s0, s1)
        assert cut_value(wc, s0, s1) == pytest.approx(cut_value(w, f0, f1))


def test_a_group_larger_than_the_chip_is_split_on_clusters():
    from ising_backend import ChipSpec, EmulatedChip
    from mrmt_env.generation import generate_world

    world = generate_world(5, height=16, width=16, n_robots=3, n_targets=40)
    chip_spec = ChipSpec(n_spins=16)
    tour = ThreeOptTour()
    chips = [EmulatedChip(chip_spec) for _ in range(2)]
    runs = [IsingSharing(chip=chip).assign(world.distance_matrix, 3, tour, np.random.default_rng(1)) for chip in chips]
    res = runs[0]
    assert res.failure is None
    assert sorted(t for group in res.assignment for t in group) == list(range(40))
    assert res.stats["coarse_splits"] >= 1 and res.compute.chip_calls == chips[0].ledger.physical_calls > 0
    assert runs[1].assignment == res.assignment  # deterministic under the seed


def test_more_robots_than_the_chip_holds_are_clustered_and_split_on_the_chip():
    """9 robots on a 6-spin chip: neighbouring robots are clustered for the coarse splits, every
    target is assigned once, every robot keeps its own group, and the chip made the splits."""
    from ising_backend import ChipSpec, EmulatedChip
    from mrmt_env.generation import generate_world

    world = generate_world(2, height=12, width=12, n_robots=9, n_targets=20)
    chip = EmulatedChip(ChipSpec(n_spins=6))
    res = IsingSharing(chip=chip, fallback="never").assign(world.distance_matrix, 9, ThreeOptTour(),
                                                           np.random.default_rng(0))
    assert res.failure is None and len(res.assignment) == 9
    assert sorted(t for group in res.assignment for t in group) == list(range(20))
    assert res.stats["coarse_splits"] >= 1 and res.compute.chip_calls == chip.ledger.physical_calls > 0


def test_a_fleet_beyond_the_chip_plans_end_to_end():
    from mrmt_env.generation import generate_world
    from planners.pipeline import make_pipeline
    from planners.plan import validate_plan

    world = generate_world(3, height=32, width=32, n_robots=50, n_targets=70, layout="warehouse")
    # the preset's layers by name (preset ising hands worlds above FLEET_ABOVE targets to the fleet search)
    pipe = make_pipeline(sharing="ising", tour="ising", path="field")
    plan = pipe.plan(world, seed=0)  # 50 robots > 45 spins
    assert plan.success, plan.failure
    validate_plan(world, plan)
    assert plan.stats["coarse_splits"] >= 1 and plan.compute.chip_calls > 0
    ledger = pipe.sharing.chip.ledger  # one chip for the layers: the plan charges exactly its ledger
    assert pipe.tour.chip is pipe.sharing.chip
    assert (plan.compute.chip_calls, plan.compute.logical_calls) == (ledger.physical_calls, ledger.logical_calls)


def test_coarse_clusters_of_shifted_split_weights_are_not_degenerate():
    """Split weights are shifted distances (negative for near pairs); the clusters of a coarse split
    are those of the distances themselves, never one cluster swallowing the group."""
    from sharing_search_reference import _clusters

    rng = np.random.default_rng(0)
    pts = rng.uniform(0, 50, size=(60, 2))
    d = np.abs(pts[:, None, :] - pts[None, :, :]).sum(-1)
    nodes = np.arange(60)
    shifted = d - 1.0 * d[np.triu_indices(60, 1)].mean()
    np.fill_diagonal(shifted, 0.0)
    a, b = _clusters(d, nodes, 12), _clusters(shifted, nodes, 12)
    assert len(a) == len(b) == 12
    assert [x.tolist() for x in a] == [x.tolist() for x in b]  # the same clusters as on the distances
