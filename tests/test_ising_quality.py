"""The planning-quality methods beyond the paper: move-selection tours on the physical chip,
boundary refinement of sharing, and the ``ising`` / ``ising-paper`` presets."""

from __future__ import annotations

import itertools
from dataclasses import fields

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ising_backend import ChipSpec, EmulatedChip
from mrmt_env.generation import generate_world
from planners import registry
from planners.fallback import answer
from planners.ising.fleet import FleetConfig
from planners.ising.path import IsingPath, PaperIsingPath, PathConfig
from planners.ising.sharing import IsingSharing, PaperIsingSharing, SharingConfig
from sharing_search_reference import neighbour_pairs
from planners.ising.tour import IsingTour, PaperIsingTour, TourConfig
from planners.ising.moves.selection import conflicts, pick_candidates, read_gain, selection_qubo
from planners.ising.moves.route_moves import route_moves as candidate_moves
from planners.ising.tour.selection import double_bridge
from tour_reference import apply_moves, nearest_neighbour_route
from planners.pipeline import make_pipeline
from planners.options import Options
from planners.plan import validate_plan
from planners.tours_classical import BruteTour, exact_route_cost


def _cost(d, r):
    return float(d[r[:-1], r[1:]].sum())


def _overlaps(spans, a, b) -> bool:
    """Two tour moves (spans on route 0) rewrite a common edge."""
    return spans[a, 1] <= spans[b, 2] and spans[b, 1] <= spans[a, 2]


def _qubo_reference(spans, gains):
    """The selection QUBO in numpy: ``-g`` and ``min(g, g') + 1`` over overlapping pairs, upper."""
    lo, hi = spans[:, 1], spans[:, 2]
    overlap = (lo[:, None] <= hi[None, :]) & (lo[None, :] <= hi[:, None])
    P = np.minimum(gains[:, None], gains[None, :]) + 1.0
    return -gains, np.triu(np.where(overlap, P, 0.0), k=1)


@st.composite
def _routes(draw):
    n = draw(st.integers(1, 11))
    pts = np.array(draw(st.lists(st.tuples(st.integers(0, 9), st.integers(0, 9)), min_size=n + 1, max_size=n + 1)))
    d = np.abs(pts[:, None] - pts[None]).sum(-1).astype(float)
    perm = draw(st.permutations(list(range(1, n + 1))))
    return d, np.array([0] + list(perm), dtype=np.int64)


# ------------------------------------------------------------------ moves
@settings(max_examples=150, deadline=None)
@given(_routes(), st.integers(1, 3))
def test_every_candidate_gain_is_the_route_cost_change(case, seg):
    d, r = case
    moves, spans, gains = candidate_moves(d, r, seg)
    assert (gains > 0).all() and (spans[:, 0] == 0).all() and (spans[:, 3] == -1).all()
    for m in range(len(gains)):
        new = apply_moves(r, moves, [m])
        assert new[0] == 0 and sorted(new.tolist()) == sorted(r.tolist())
        assert _cost(d, r) - _cost(d, new) == pytest.approx(gains[m])
        assert spans[m, 1] <= spans[m, 2]
        changed = np.flatnonzero(new != r)  # only positions inside the span move
        assert changed.size == 0 or (changed.min() > spans[m, 1] and changed.max() <= spans[m, 2])


@settings(max_examples=100, deadline=None)
@given(_routes(), st.randoms(use_true_random=False))
def test_disjoint_moves_add_and_overlapping_reads_are_invalid(case, rnd):
    d, r = case
    moves, spans, gains = candidate_moves(d, r, 3)
    if len(gains) == 0:
        return
    chosen = np.array([rnd.random() < 0.4 for _ in gains])
    taken, total = read_gain(chosen, conflicts(spans, np.arange(len(gains))), gains)
    idx = np.flatnonzero(chosen)
    overlap = any(_overlaps(spans, a, b) for a, b in itertools.combinations(idx, 2))
    if overlap:
        assert taken is None
    else:
        assert list(taken) == list(idx)
        assert _cost(d, r) - _cost(d, apply_moves(r, moves, taken)) == pytest.approx(total)


@settings(max_examples=100, deadline=None)
@given(_routes(), st.integers(1, 12), st.integers(0, 4))
def test_picked_candidates_respect_the_overlap_cap(case, k, cap):
    d, r = case
    _moves, spans, gains = candidate_moves(d, r, 3)
    picked = pick_candidates(spans, gains, k, cap)
    assert len(picked) <= k and len(set(picked.tolist())) == len(picked)
    assert all(gains[a] >= gains[b] for a, b in zip(picked[:-1], picked[1:]))
    for i, m in enumerate(picked):
        hits = sum(_overlaps(spans, m, o) for o in picked[:i])
        assert hits <= cap
    if len(gains):
        assert picked[0] == np.argsort(-gains, kind="mergesort")[0]  # the best move is always offered


def test_no_candidates_at_a_local_optimum_and_none_for_one_target():
    d = np.array([[0.0, 1.0], [1.0, 0.0]])
    moves, spans, gains = candidate_moves(d, np.array([0, 1]), 3)
    assert moves.shape == (0, 4) and spans.shape == (0, 6) and gains.shape == (0,)
    dist = generate_world(3, n_robots=1, n_targets=8).distance_matrix
    best = BruteTour().solve(dist)
    assert len(candidate_moves(dist, np.array((0,) + best.order), 3)[2]) == 0


def test_selection_qubo_ground_state_is_the_best_compatible_set():
    dist = generate_world(7, n_robots=1, n_targets=9).distance_matrix
    r = np.concatenate([[0], np.arange(9, 0, -1)])
    _moves, spans, gains = candidate_moves(dist, r, 3)
    keep = np.argsort(-gains, kind="stable")[:12]
    clashes, gains = conflicts(spans, keep), gains[keep]
    q, Q = selection_qubo(gains, clashes, 1.0)
    X = np.array(list(itertools.product([0, 1], repeat=len(gains))), dtype=float)
    E = X @ q + np.einsum("si,ij,sj->s", X, Q, X)
    best = X[np.argmin(E)].astype(bool)
    taken, total = read_gain(best, clashes, gains)
    assert taken is not None
    feasible = [read_gain(x.astype(bool), clashes, gains)[1] for x in X
                if read_gain(x.astype(bool), clashes, gains)[0] is not None]
    assert total == pytest.approx(max(feasible)) and -E.min() == pytest.approx(total)


def test_nearest_neighbour_route():
    d = np.array([[0, 5, 1, 9], [5, 0, 4, 2], [1, 4, 0, 8], [9, 2, 8, 0]], dtype=float)
    assert nearest_neighbour_route(d).tolist() == [0, 2, 1, 3]


def test_double_bridge_keeps_the_start_and_every_target():
    rng = np.random.default_rng(0)
    for n in (4, 5, 9, 30):
        route = np.concatenate([[0], 1 + rng.permutation(n)])
        kicked = double_bridge(route, rng)
        assert kicked[0] == 0 and sorted(kicked.tolist()) == list(range(n + 1))
        assert not np.array_equal(kicked, route)


def test_big_tours_kick_the_best_route_instead_of_restarting():
    """Above 16 targets later starts perturb the best route (fewer calls, no worse here)."""
    dist = generate_world(500, height=64, width=64, n_robots=1, n_targets=40, layout="warehouse").distance_matrix
    auto = IsingTour(EmulatedChip()).solve(dist, np.random.default_rng(0))
    rand = IsingTour(EmulatedChip(), chip_restart="random").solve(dist, np.random.default_rng(0))
    assert auto.success and rand.success and sorted(auto.order) == list(range(1, 41))
    assert auto.compute.chip_calls < rand.compute.chip_calls
    with pytest.raises(ValueError, match="chip_restart"):
        TourConfig(chip_restart="sometimes")


@settings(max_examples=100, deadline=None)
@given(_routes(), st.randoms(use_true_random=False))
def test_compiled_move_kernels_match_the_reference(case, rnd):
    from ising_backend import ising_from_qubo
    from ising_backend import STACK_OK, pack_qubo_stack, quantize_stack
    from ising_backend.mapping.numeric import ising_of_qubo
    from planners.ising.moves.routes import linked, route_of
    from planners.ising.moves.route_moves import apply_route_moves as compiled_apply

    d, r = case
    moves, spans, gains = candidate_moves(d, r, 3)
    if len(gains) == 0:
        return
    keep = pick_candidates(spans, gains, 8, 4)
    moves, spans, gains = moves[keep], spans[keep], gains[keep]
    clashes = conflicts(spans, np.arange(len(gains)))
    q, Q = selection_qubo(gains, clashes, 1.0)
    h, J, _offset = ising_of_qubo(q, Q, 0.0)
    ref = ising_from_qubo(*_qubo_reference(spans, gains))
    assert np.array_equal(h, ref.h) and np.array_equal(J, ref.J)  # bit for bit
    # one pack per rule at capacity M, in rule order: the programs quantize_stack gives
    M = len(gains)
    rules = np.array([0, 2], dtype=np.int64)  # linear, rank
    st, hp, Jp, where = pack_qubo_stack(q.reshape(1, M), Q.reshape(1, M, M), np.full(1, M), rules, 7.0, 7.0, M)
    hq, Jq = quantize_stack(ref, ("linear", "rank"), (-7, 7), (-7, 7))
    assert st == STACK_OK and where.tolist() == [[0, 0], [1, 0]]
    assert np.array_equal(hp, hq) and np.array_equal(Jp, Jq)
    chosen = np.array([rnd.random() < 0.4 for _ in gains])
    taken, _total = read_gain(chosen, clashes, gains)
    if taken is not None:
        nxt, prv = linked(r)
        compiled_apply(nxt, prv, r, moves, taken)  # by node, on the route's linked list
        assert np.array_equal(route_of(nxt), apply_moves(r, moves, taken))
        assert all(prv[y] == x for x in range(len(r)) for y in [nxt[x]] if y >= 0)  # the links agree


class _PlainChip(EmulatedChip):
    """The emulated chip seen through an overridden ``anneal_batch``: planners take the Python path."""

    def anneal_batch(self, *args, **kwargs):
        return super().anneal_batch(*args, **kwargs)


@pytest.mark.parametrize("n, restart", [(1, "auto"), (2, "auto"), (4, "auto"), (7, "auto"), (10, "auto"),
                                        (14, "auto"), (25, "auto"), (25, "random"), (9, "kick")])
def test_compiled_chip_tour_makes_the_reference_decisions(n, restart):
    """All starts in one compiled call (random restarts), or one call per start (kicks), against the
    Python loop: the same tour, statistics, charges and rng state."""
    for s in range(4):
        dist = generate_world(40 * n + s, height=20, width=20, n_robots=1, n_targets=n).distance_matrix
        r1, r2 = np.random.default_rng(s), np.random.default_rng(s)
        fast = IsingTour(EmulatedChip(), chip_restart=restart).solve(dist, r1)
        ref = IsingTour(_PlainChip(), chip_restart=restart).solve(dist, r2)
        assert fast.order == ref.order and fast.cost == ref.cost and fast.stats == ref.stats
        assert (fast.compute.chip_calls, fast.compute.chip_batches) == (ref.compute.chip_calls, ref.compute.chip_batches)
        assert fast.compute.accelerator_energy_j == ref.compute.accelerator_energy_j
        assert r1.bit_generator.state == r2.bit_generator.state


@settings(max_examples=80, deadline=None)
@given(st.integers(0, 2**31), st.integers(1, 14), st.integers(1, 6))
def test_compiled_nearest_neighbour_route_is_the_reference(seed, n, spread):
    """Small integer distances: many ties, which go to the lowest index in both."""
    from planners.ising.tour.selection import nearest_neighbour_kernel

    d = np.random.default_rng(seed).integers(0, spread, size=(n + 1, n + 1)).astype(float)
    assert nearest_neighbour_kernel(d).tolist() == nearest_neighbour_route(d).tolist()


# ------------------------------------------------------------------ chip tour
def test_chip_tour_is_valid_near_optimal_and_runs_on_the_physical_chip():
    chip = EmulatedChip(ChipSpec(), seed=0)
    tour = IsingTour(chip=chip)
    assert tour.config.backend == "chip"
    gaps, calls = [], 0
    for s in range(12):
        dist = generate_world(300 + s, n_robots=1, n_targets=10).distance_matrix
        r = tour.solve(dist, np.random.default_rng(s))
        assert r.success and sorted(r.order) == list(range(1, 11))
        assert r.cost == pytest.approx(_cost(dist, np.array((0,) + r.order)))
        assert r.compute.chip_calls > 0 and r.compute.logical_calls == 0
        m = r.stats["mapping"]["tour"]
        assert all(v["programs"] > 0 and 0 < v["valid"] <= v["reads"] == v["programs"] * tour.config.num_reads
                   for v in m.values())
        gaps.append(r.cost / BruteTour().solve(dist).cost - 1)
        calls += r.compute.chip_calls
    assert np.mean(gaps) <= 0.03
    assert chip.ledger.physical_calls == calls  # every call metered on the chip's own ledger


def test_chip_tour_takes_an_explicit_config_on_a_small_chip():
    """The move-selection programs fit any chip (at most its spins); the one-hot size limits
    concern the logical backend only."""
    small = EmulatedChip(ChipSpec(n_spins=16))
    dist = generate_world(8, n_robots=1, n_targets=9).distance_matrix
    r = IsingTour(chip=small, config=TourConfig()).solve(dist, np.random.default_rng(0))
    assert r.success and sorted(r.order) == list(range(1, 10))
    with pytest.raises(ValueError, match="spin budget"):
        IsingTour(chip=small, config=TourConfig.paper())


def test_chip_tour_is_deterministic():
    dist = generate_world(5, n_robots=1, n_targets=10).distance_matrix
    a = IsingTour(EmulatedChip()).solve(dist, np.random.default_rng(4))
    b = IsingTour(EmulatedChip()).solve(dist, np.random.default_rng(4))
    assert a.order == b.order and a.compute.chip_calls == b.compute.chip_calls


class _StuckChip:
    """An emulated chip whose read-out is stuck at -1: every read selects no move."""

    def __init__(self):
        self.inner = EmulatedChip(ChipSpec(), seed=0)
        self.spec, self.ledger = self.inner.spec, self.inner.ledger

    def anneal_batch(self, h, J, num_reads=1, seed=None):
        spins, energies = self.inner.anneal_batch(h, J, num_reads=num_reads, seed=seed)
        self.last_call = self.inner.last_call
        return -np.ones_like(spins), energies


class _RandomChip(_StuckChip):
    """Charges the calls and returns fair coin flips instead of annealed reads."""

    def anneal_batch(self, h, J, num_reads=1, seed=None):
        spins, energies = self.inner.anneal_batch(h, J, num_reads=num_reads, seed=seed)
        self.last_call = self.inner.last_call
        coin = np.random.default_rng(seed).random(spins.shape) < 0.5
        return np.where(coin, 1, -1).astype(np.int8), energies


def test_a_chip_that_selects_nothing_is_a_failure_not_the_host_route():
    dist = generate_world(4, n_robots=1, n_targets=8).distance_matrix
    chip = _StuckChip()
    r = IsingTour(chip=chip).solve(dist, np.random.default_rng(0))
    assert not r.success and r.order == () and "no valid improving move set" in r.failure
    assert r.compute.chip_calls == chip.ledger.physical_calls > 0
    layer = IsingTour(chip=_StuckChip(), fallback="failure")
    assert not layer.solve(dist, np.random.default_rng(0)).success  # a layer alone never falls back
    r = answer("tour", layer, dist, np.random.default_rng(0))  # as the pipeline calls it
    assert r.success and r.stats["fallback"] == {"tour": 1} and r.compute.fallbacks == 1


def test_the_annealed_reads_do_the_work():
    """Invalid reads are dropped, never repaired, so the chip's choices set the pace: coin-flip
    reads reach tours as good only with far more chip calls (measured: 2.2x on 100 worlds)."""
    calls = {"chip": 0, "coin": 0}
    gaps = {"chip": [], "coin": []}
    for s in range(10):
        dist = generate_world(900 + s, n_robots=1, n_targets=10).distance_matrix
        opt = BruteTour().solve(dist).cost
        for name, chip in (("chip", EmulatedChip(seed=s)), ("coin", _RandomChip())):
            r = IsingTour(chip=chip).solve(dist, np.random.default_rng(s))
            assert r.success
            gaps[name].append(r.cost / opt - 1)
            calls[name] += r.compute.chip_calls
    assert np.mean(gaps["chip"]) <= 0.01
    assert calls["chip"] < 0.7 * calls["coin"]


def test_without_sparse_candidates_coin_flips_stall():
    """With every improving move offered (dense overlaps) and no halving, coin-flip reads rarely
    pick a valid set; the annealed reads still do."""
    fails = {"chip": 0, "coin": 0}
    for s in range(8):
        dist = generate_world(950 + s, n_robots=1, n_targets=10).distance_matrix
        for name, chip in (("chip", EmulatedChip(seed=s)), ("coin", _RandomChip())):
            r = IsingTour(chip=chip, max_overlap=99, max_moves=45).solve(dist, np.random.default_rng(s))
            fails[name] += r.stats["unsolved"]["moves"]
    assert fails["chip"] < fails["coin"]


# ------------------------------------------------------------------ sharing
def test_neighbour_pairs():
    world = generate_world(2, n_robots=4, n_targets=8)
    d = world.distance_matrix
    sets = [[4, 5], [6, 7], [8, 9], [10, 11]]
    assert neighbour_pairs(d, sets, 4, 3) == [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    one = neighbour_pairs(d, sets, 4, 1)
    assert 2 <= len(one) <= 4 and all(k < l for k, l in one)
    assert neighbour_pairs(d, [[2, 3]], 1, 3) == []


def _exact_total(dist, R, assignment):
    return sum(exact_route_cost(dist, [k] + [R + t for t in a]) if a else 0.0 for k, a in enumerate(assignment))


def test_boundary_refinement_only_lowers_the_route_cost():
    better = 0
    for s in range(10):
        world = generate_world(60 + s, n_robots=3, n_targets=10)
        d = world.distance_matrix
        plain = IsingSharing(pair_rounds=0).assign(d, 3, None, np.random.default_rng(s))
        refined = IsingSharing().assign(d, 3, None, np.random.default_rng(s))
        a, b = _exact_total(d, 3, plain.assignment), _exact_total(d, 3, refined.assignment)
        assert sorted(t for g in refined.assignment for t in g) == list(range(10))
        assert b <= a + 1e-9
        better += b < a - 1e-9
        st_ = refined.stats
        assert st_["pair_resplits"] >= 3 and refined.compute.chip_calls > plain.compute.chip_calls
        assert sum(v["wins"] for v in st_["mapping"]["sharing"].values()) == st_["splits"] - st_["trivial_splits"]
    assert better >= 1


def test_bad_pair_options_are_refused():
    with pytest.raises(ValueError, match="pair_rounds"):
        SharingConfig(pair_rounds=-1)
    with pytest.raises(ValueError, match="pair_shifts"):
        SharingConfig(pair_shifts=())
    with pytest.raises(ValueError, match=r"pair_shifts = \(0.5, nan\) must be a non-empty tuple of finite numbers"):
        SharingConfig(pair_shifts=(0.5, float("nan")))
    with pytest.raises(ValueError, match=r"chip_rules = \('linear', 'cubic'\) must be a non-empty tuple of linear"):
        TourConfig(chip_rules=("linear", "cubic"))
    with pytest.raises(ValueError, match=r"chip_rules = \('rank', 'rank'\) names a rule twice"):
        TourConfig(chip_rules=("rank", "rank"))
    with pytest.raises(ValueError, match="max_moves"):
        TourConfig(max_moves=0)


@pytest.mark.parametrize("cls", [PathConfig, TourConfig, SharingConfig, FleetConfig])
def test_ising_configs_are_options_records(cls):
    """One option system: each config an Options record, every option described, an unknown one a ValueError
    naming it and those the record takes (replace, the planner's keywords and the pipeline's layer options)."""
    names = [f.name for f in fields(cls)]
    assert issubclass(cls, Options) and [row[0] for row in cls.describe()] == names
    assert all(row[3] for row in cls.describe())  # a meaning each
    listed = f"{cls.__name__} takes no option 'bogus'; its options: {', '.join(names)}"
    with pytest.raises(ValueError) as err:
        cls().replace(bogus=1)
    assert str(err.value) == listed
    with pytest.raises(ValueError, match=f"config must be a {cls.__name__}, got dict"):
        cls.resolve({})
    assert cls.resolve(None, {}) == cls() and cls().replace() == cls()
    key = "num_reads" if "num_reads" in names else "reads"  # the validator's line: option, value, limit
    with pytest.raises(ValueError, match=f"^{key} = 0 must be an integer >= 1$"):
        cls(**{key: 0})


def test_unknown_planner_options_are_value_errors():
    with pytest.raises(ValueError, match="^PathConfig takes no option 'patchsize'; its options: patch_size, form"):
        IsingPath(patchsize=3)
    with pytest.raises(ValueError, match="tour planner 'ising' takes no option 'startz'; its options: chip, config"):
        make_pipeline("ising", tour="ising", tour_options={"startz": 2})


# ------------------------------------------------------------------ presets
def test_paper_configs_differ_from_the_defaults_only_where_documented():
    assert PathConfig.paper() == PathConfig(target_key="manhattan")
    assert TourConfig.paper() == TourConfig(backend="logical")
    assert SharingConfig.paper() == SharingConfig(pair_rounds=0)
    assert PaperIsingPath().config == PathConfig.paper() and PaperIsingTour().config == TourConfig.paper()
    assert PaperIsingSharing().config == SharingConfig.paper()
    assert PaperIsingTour(n_starts=2).config == TourConfig.paper(n_starts=2)  # options still override
    assert IsingPath().config.target_key == "bfs"


def test_presets_share_one_chip_and_plan_validly():
    world = generate_world(17, n_robots=3, n_targets=10)
    costs = {}
    for preset in ("ising", "ising-paper", "exact", "strong"):
        pipe = make_pipeline(preset)
        plan = pipe.plan(world, seed=0)
        assert plan.success, plan.failure
        validate_plan(world, plan)
        costs[preset] = plan.route_cost
        if preset.startswith("ising"):
            assert pipe.sharing.chip is pipe.tour.chip
            assert getattr(pipe.path, "chip", pipe.tour.chip) is pipe.tour.chip  # ising: legs from the BFS field
            assert type(pipe.tour).__name__ == ("IsingTour" if preset == "ising" else "PaperIsingTour")
    assert costs["exact"] <= min(costs.values())
    assert registry.get_factory("tour", "ising-paper") is PaperIsingTour
