"""Clustered Ising tour construction (planners.ising.tour, paper 5.2)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from ising_backend import ChipSpec, EmulatedChip, LogicalIsingSolver
from mrmt_env.generation import generate_world
from planners.base import TourResult, TourSolver
from planners.ising.tour import IsingTour, PaperIsingTour
from planners.ising.tour.cluster import cut_value
from tour_qubo_reference import (
    decode_onehot,
    decode_onehot_batch,
    maxcut_qubo,
    open_path_qubo,
    path_cost,
    qubo_energy,
)
from planners.pipeline import make_pipeline
from planners.plan import validate_plan
from planners.tours_classical import BruteTour, route_cost


def _line_dist(positions) -> np.ndarray:
    """Robot at 0 then targets at ``positions`` on a line (distance = |a - b|)."""
    p = np.asarray([0, *positions], dtype=float)
    return np.abs(p[:, None] - p[None, :])


def _is_perm(order, n) -> bool:
    return sorted(order) == list(range(1, n + 1))


# ------------------------------------------------------------------ formulation (pure numpy)


def _all_bits(n):
    return np.array(list(itertools.product([0, 1], repeat=n)), dtype=np.int8)


@pytest.mark.parametrize("s", [2, 3, 4])
def test_open_path_qubo_ground_state_is_best_permutation(s):
    rng = np.random.default_rng(s)
    for _ in range(3):
        pts = rng.integers(0, 10, (s, 2))
        d = np.abs(pts[:, None] - pts[None]).sum(-1).astype(float)
        entry = rng.integers(0, 10, s).astype(float)
        ex = rng.integers(0, 10, s).astype(float)
        q, Q, off, A = open_path_qubo(d, entry, ex)
        assert A > max(d.max(), entry.max(), ex.max())
        X = _all_bits(s * s)
        E = qubo_energy(q, Q, off, X)
        orders, valid = decode_onehot_batch(X, s)
        # valid states: energy == original route cost exactly
        for x, e in zip(X[valid], E[valid]):
            assert e == pytest.approx(path_cost(d, decode_onehot(x, s), entry, ex))
        best = min(path_cost(d, p, entry, ex) for p in itertools.permutations(range(s)))
        assert E.min() == pytest.approx(best)
        assert E[~valid].min() > best  # every ground state is a valid permutation


def test_decode_onehot_rejects_violations():
    x = np.eye(3, dtype=np.int8)[[2, 0, 1]]  # item i at position perm
    assert decode_onehot(x.reshape(-1), 3) is not None
    bad = x.copy()
    bad[0, 0] = 1  # item 0 at two positions
    assert decode_onehot(bad.reshape(-1), 3) is None
    assert decode_onehot(np.zeros(9), 3) is None


def test_maxcut_qubo_energy_is_minus_cut():
    rng = np.random.default_rng(1)
    w = rng.random((6, 6))
    w = w + w.T
    np.fill_diagonal(w, 0)
    q, Q, off = maxcut_qubo(w)
    X = _all_bits(6)
    assert np.allclose(qubo_energy(q, Q, off, X), -cut_value(w, X))
    # cut of a split = sum of weights across it
    x = np.array([1, 0, 0, 1, 0, 1])
    assert cut_value(w, x) == pytest.approx(w[np.ix_(x == 1, x == 0)].sum())


# ------------------------------------------------------------------ the planner


def test_protocol_and_trivial_sizes():
    tour = PaperIsingTour()
    assert isinstance(tour, TourSolver)
    r0 = tour.solve(np.zeros((1, 1)), np.random.default_rng(0))
    assert r0.order == () and r0.cost == 0 and r0.success
    r1 = tour.solve(_line_dist([4]), np.random.default_rng(0))
    assert r1.order == (1,) and r1.cost == 4 and r1.compute.logical_calls == 0


def test_three_targets_on_a_line():
    tour = PaperIsingTour()
    r = tour.solve(_line_dist([1, 2, 3]), np.random.default_rng(0))
    assert r.order == (1, 2, 3) and r.cost == 3
    r = tour.solve(_line_dist([3, 1, 2]), np.random.default_rng(0))
    assert r.order == (2, 3, 1) and r.cost == 3


def test_two_separated_clusters_exact():
    # four targets near the robot, four far away: go through the near group, then the far one
    dist = _line_dist([3, 1, 4, 2, 22, 20, 23, 21])
    r = PaperIsingTour().solve(dist, np.random.default_rng(3))
    assert r.order == (2, 4, 1, 3, 6, 8, 5, 7)
    assert r.cost == 23


@pytest.mark.parametrize("n", [2, 3, 4, 5, 6])
def test_small_tours_match_exact(n):
    # n <= patch_size: the refinement patch is the whole tour (n^2 <= 36 spins, one call)
    bt = BruteTour()
    for seed in range(3):
        world = generate_world(seed, n_robots=1, n_targets=n)
        dist = world.distance_matrix
        r = PaperIsingTour().solve(dist, np.random.default_rng(seed))
        assert _is_perm(r.order, n)
        assert r.cost == pytest.approx(bt.solve(dist).cost)


def test_random_worlds_valid_and_near_optimal():
    bt = BruteTour()
    tour = PaperIsingTour()
    gaps = []
    for seed in range(8):
        dist = generate_world(100 + seed, n_robots=1, n_targets=10).distance_matrix
        r = tour.solve(dist, np.random.default_rng(seed))
        assert r.success and _is_perm(r.order, 10)
        assert r.cost == pytest.approx(route_cost(dist, r.order))
        opt = bt.solve(dist).cost
        assert r.cost >= opt - 1e-9
        gaps.append((r.cost - opt) / opt)
        st = r.stats
        assert len(st["clusters"]) == 8 and sum(st["clusters"]) == 10  # refined up to 8 clusters
        assert max(st["clusters"]) <= 7
    assert np.median(gaps) == 0.0
    assert np.mean(gaps) < 0.05


def test_compute_report_and_branching():
    spec = ChipSpec()
    dist = generate_world(5, n_robots=1, n_targets=10).distance_matrix
    r = PaperIsingTour().solve(dist, np.random.default_rng(0))
    c = r.compute
    assert c.chip_calls == 0 and c.chip_batches == 0 and c.cpu_s == 0
    assert c.logical_calls >= 16  # the 8-cluster ordering model (49 vars) is branched 16 ways
    assert c.chip_time_s == pytest.approx(c.logical_calls * spec.solve_time_s)
    assert c.accelerator_energy_j == pytest.approx(c.logical_calls * spec.energy_per_call_j)
    assert c.chip_time_parallel_s < c.chip_time_s  # branches dispatched together
    st = r.stats
    m = st["mapping"]["tour"]["logical"]  # the logical solver maps nothing: one choice
    assert set(st["mapping"]["tour"]) == {"logical"}
    assert m["programs"] > st["subproblems"] > 0  # branches are programs of one subproblem
    assert m["reads"] == m["programs"] * PaperIsingTour().config.num_reads and m["map_errors"] == 0
    assert 0 < st["valid_programs"] <= m["programs"] and st["valid_subproblems"] == st["subproblems"]
    assert m["wins"] == st["valid_subproblems"] and 0 < m["valid"] <= m["reads"]


def test_deterministic_under_seed():
    dist = generate_world(7, n_robots=1, n_targets=10).distance_matrix
    a = PaperIsingTour().solve(dist, np.random.default_rng(42))
    b = PaperIsingTour().solve(dist, np.random.default_rng(42))
    assert a.order == b.order and a.cost == b.cost and a.compute == b.compute
    assert a.stats == b.stats


def test_unreachable_target_is_a_clear_failure():
    dist = _line_dist([1, 2, 3])
    dist[2, :] = dist[:, 2] = np.inf
    dist[2, 2] = 0
    r = PaperIsingTour().solve(dist, np.random.default_rng(0))
    assert not r.success and r.order == () and math.isinf(r.cost)
    assert "infinite" in r.failure


class _GarbageSolver:
    """A logical solver that returns all spins +1 (never a valid one-hot or cut)."""

    def __init__(self):
        self.inner = LogicalIsingSolver()
        self.ledger = self.inner.ledger

    def solve_many(self, models, num_reads=1, seed=None):
        res = self.inner.solve_many(models, num_reads=num_reads, seed=seed)
        return [type(r)(np.ones_like(r.spins), r.energies) for r in res]


class _NoisySolver(_GarbageSolver):
    """Random spins: sometimes valid by chance, mostly not."""

    def solve_many(self, models, num_reads=1, seed=None):
        res = self.inner.solve_many(models, num_reads=num_reads, seed=seed)
        g = np.random.default_rng(seed % 2**32)
        return [type(r)(g.choice(np.array([-1, 1], dtype=np.int8), size=r.spins.shape), r.energies) for r in res]


@pytest.mark.parametrize("n", [3, 10])
def test_garbage_solver_ends_in_clear_failure(n):
    dist = generate_world(3, n_robots=1, n_targets=n).distance_matrix
    r = PaperIsingTour(solver=_GarbageSolver(), max_retries=2).solve(dist, np.random.default_rng(0))
    assert isinstance(r, TourResult)
    assert not r.success and r.order == () and "degenerate" in r.failure
    assert r.compute.logical_calls > 0


def test_many_targets_hierarchical_ordering():
    # 70 targets: more clusters of <= 7 than the ordering limit, and a first split above the spin budget
    dist = generate_world(1, height=20, width=20, n_robots=1, n_targets=70).distance_matrix
    r = PaperIsingTour(n_starts=1).solve(dist, np.random.default_rng(0))
    assert r.success and _is_perm(r.order, 70)
    assert r.cost == pytest.approx(route_cost(dist, r.order))
    assert r.stats["ordering_splits"] >= 1 and len(r.stats["clusters"]) > 8


def test_noisy_solver_never_gives_invalid_tour():
    for seed in range(4):
        dist = generate_world(seed, n_robots=1, n_targets=6).distance_matrix
        r = PaperIsingTour(solver=_NoisySolver()).solve(dist, np.random.default_rng(seed))
        if r.success:
            assert _is_perm(r.order, 6) and r.cost == pytest.approx(route_cost(dist, r.order))
        else:
            assert r.order == () and r.failure


def test_onehot_chip_backend_reports_physical_validity():
    chip = EmulatedChip(ChipSpec(), seed=0)
    dist = generate_world(2, n_robots=1, n_targets=5).distance_matrix
    r = IsingTour(chip=chip, backend="chip-onehot").solve(dist, np.random.default_rng(0))
    m = r.stats["mapping"]["tour"]["linear"]  # the one-hot programs' quantization rule (chip_quantize)
    assert set(r.stats["mapping"]["tour"]) == {"linear"}
    assert m["programs"] > 0 and 0 <= r.stats["valid_programs"] <= m["programs"]
    assert m["reads"] == m["programs"] * IsingTour().config.num_reads
    assert r.compute.chip_calls > 0 and r.compute.chip_calls == chip.ledger.physical_calls
    if r.success:
        assert _is_perm(r.order, 5)
    else:
        assert r.order == () and "no valid permutation" in r.failure


def test_onehot_chip_backend_solves_small_tours_on_the_chip():
    """The success branch: 4-target one-hot programs decode to valid orders on the physical chip."""
    for seed in range(4):
        chip = EmulatedChip(ChipSpec(), seed=0)
        dist = generate_world(seed, n_robots=1, n_targets=4).distance_matrix
        r = IsingTour(chip=chip, backend="chip-onehot").solve(dist, np.random.default_rng(seed))
        assert r.success and _is_perm(r.order, 4) and r.cost == pytest.approx(route_cost(dist, r.order))
        m = r.stats["mapping"]["tour"]["linear"]
        assert 0 < r.stats["valid_programs"] <= m["programs"] and r.compute.chip_calls == chip.ledger.physical_calls


class _GarbageChip:
    """An emulated chip whose read-out is stuck at -1 (charges the calls, returns garbage)."""

    def __init__(self):
        self.inner = EmulatedChip(ChipSpec(), seed=0)
        self.spec = self.inner.spec
        self.ledger = self.inner.ledger

    def anneal_batch(self, h, J, num_reads=1, seed=None):
        spins, energies = self.inner.anneal_batch(h, J, num_reads=num_reads, seed=seed)
        self.last_call = self.inner.last_call
        return -np.ones_like(spins), energies


def test_garbage_chip_ends_in_clear_failure():
    dist = generate_world(4, n_robots=1, n_targets=6).distance_matrix
    chip = _GarbageChip()
    r = IsingTour(chip=chip, backend="chip-onehot").solve(dist, np.random.default_rng(0))
    assert not r.success and r.order == () and r.failure
    assert r.compute.chip_calls == chip.ledger.physical_calls > 0 and r.compute.logical_calls == 0


def test_bad_options_are_refused():
    with pytest.raises(ValueError, match="backend"):
        IsingTour(backend="quantum")
    with pytest.raises(ValueError, match="64 variables"):
        PaperIsingTour(patch_size=8)
    with pytest.raises(ValueError, match="penalty_factor"):
        PaperIsingTour(penalty_factor=0.5)
    with pytest.raises(ValueError, match="dist"):
        PaperIsingTour().solve(np.zeros((2, 3)))


@pytest.mark.parametrize("name", ["ising", "ising-paper"])
def test_in_the_pipeline(name):
    """``ising`` runs the tour on the physical chip, ``ising-paper`` on the logical solver."""
    world = generate_world(11, n_robots=2, n_targets=8)
    pipe = make_pipeline(sharing="ssa", tour=name, path="astar")
    plan = pipe.plan(world, seed=0)
    assert plan.success
    validate_plan(world, plan)
    ledger = pipe.tour.chip.ledger  # the logical solver charges the chip's ledger too
    assert (plan.compute.chip_calls, plan.compute.logical_calls) == (ledger.physical_calls, ledger.logical_calls)
    if name == "ising":
        assert plan.compute.chip_calls > 0 and plan.compute.logical_calls == 0
    else:
        assert plan.compute.logical_calls > 0 and plan.compute.chip_calls == 0
    tour = plan.stats["mapping"]["tour"]
    assert set(tour) == ({"linear", "rank"} if name == "ising" else {"logical"})
    assert all(m["programs"] > 0 and m["reads"] == m["programs"] for m in tour.values())  # one read a program
