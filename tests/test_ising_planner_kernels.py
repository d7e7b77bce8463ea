"""Compiled host kernels of the Ising planners against their slow reference implementations.

Every kernel of ``planners/ising/*/kernels.py`` (and the numeric helper) is checked on random
inputs (hypothesis) against the numpy / Python code it replaced, bit for bit where the
kernel promises numpy's bits; edge cases: empty patch problems, one spin, one item, saturated
ranges, groups of two nodes.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ising_backend import CallLedger, QuboModel, branch
from ising_backend.mapping.branching import branch_stack
from ising_backend.mapping.numeric import ising_of_qubo, pairwise_sum
from mapping_reference import branch_ref
from planners.ising.path.config import DEFAULT_WEIGHTS
from planners.ising.path.kernels import extract_path, neighbour_table, rank_local_targets, score_patch_samples
from path_reference import build_patch_qubo_reference, component_of, cut_loops
from planners.ising.path.qubo import build_patch_qubo, patch_frame
from planners.ising.sharing.split_problem import score_split_reads, split_model
from sharing_search_reference import SplitProblem, build_split_qubo, choose_anchors, cut_value, decode_split
from planners.ising.tour.kernels import (
    best_onehot, dist_flags, expand_branches, maxcut_ising, onehot_ising, route_cost,
)
from tour_qubo_reference import decode_onehot_batch, maxcut_qubo, onehot_penalty, open_path_qubo
from planners.tours_classical import BruteTour, exact_route_cost

SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
FRAME = patch_frame(5)
NBR = neighbour_table(FRAME)


# ----------------------------------------------------------------------------- references
def ranked_reference(frame, padded, pos, goal, excluded, interior, merged):
    """The ranking IsingPath used before it was compiled (component, then lexsort)."""
    rad = frame.radius
    allowed = ~padded[pos[0]:pos[0] + frame.size, pos[1]:pos[1] + frame.size].reshape(-1)
    comp = component_of(frame, allowed, frame.n // 2)
    idx = np.flatnonzero(comp)
    idx = idx[idx != frame.n // 2]
    cells = frame.offsets[idx] + np.asarray(pos)
    keep = np.array([not excluded[r + rad, c + rad] for r, c in cells], dtype=bool)
    idx, cells = idx[keep], cells[keep]
    if len(idx) == 0:
        return comp, []
    is_goal = (cells == np.asarray(goal)).all(axis=1)
    cls = np.where(is_goal, 0, np.where(frame.ring[idx], 1, 2))
    if not interior:
        sel = cls < 2
        idx, cells, cls = idx[sel], cells[sel], cls[sel]
    to_goal = np.abs(cells - np.asarray(goal)).sum(axis=1)
    from_pos = np.abs(frame.offsets[idx]).sum(axis=1)
    if merged:
        order = np.lexsort((idx, from_pos, cls, to_goal, cls != 0))
    else:
        order = np.lexsort((idx, from_pos, to_goal, cls))
    return comp, [int(idx[k]) for k in order]


def decode_reference(frame, problem, x):
    """The numpy decode of patch samples IsingPath used before it was compiled."""
    x = np.asarray(x).astype(bool).reshape(-1, problem.n)
    sel = np.zeros((x.shape[0], frame.n), dtype=bool)
    sel[:, problem.cells] = x
    sel[:, [problem.start, problem.goal]] = True
    deg = (sel.astype(np.int16) @ frame.adj4.astype(np.int16)) * sel
    want = np.where(sel, 2, 0)
    want[:, [problem.start, problem.goal]] = 1
    ok = (deg == want).all(axis=1)
    out = [None] * x.shape[0]
    for s in np.flatnonzero(ok):
        row = sel[s]
        path, prev, cur = [problem.start], -1, problem.start
        while cur != problem.goal:
            nxt = next((j for j in frame.neighbours[cur] if row[j] and j != prev), -1)
            if nxt < 0:
                break
            prev, cur = cur, nxt
            path.append(cur)
        if cur == problem.goal and len(path) == int(row.sum()):
            out[s] = path
    return out


def patch_case(seed, density):
    rng = np.random.default_rng(seed)
    allowed = rng.random(25) >= density
    allowed[12] = True
    cand = [i for i in np.flatnonzero(allowed) if i != 12]
    if not cand:
        allowed[13] = True
        cand = [13]
    return allowed, int(rng.choice(cand)), rng


# ----------------------------------------------------------------------------- numeric
@SETTINGS
@given(st.lists(st.floats(-1e6, 1e6, allow_nan=False), min_size=0, max_size=400))
def test_pairwise_sum_is_numpys_sum(values):
    a = np.array(values, dtype=np.float64)
    assert pairwise_sum(a, 0, len(a)) == a.sum()


@SETTINGS
@given(st.integers(0, 10**6), st.integers(1, 40), st.integers(0, 8))
def test_compiled_qubo_to_ising_is_the_hosts_bit_for_bit(seed, n, pad):
    """``ising_of_qubo`` gives ``ising_from_qubo``'s bits, also on a padded stack's sliced views."""
    from ising_backend import ising_from_qubo

    rng = np.random.default_rng(seed)
    q = rng.normal(size=n) * 10 ** rng.uniform(-3, 3)
    Q = np.triu(rng.normal(size=(n, n)) * 10 ** rng.uniform(-3, 3), k=1)
    ref = ising_from_qubo(q, Q, 1.5)
    stack_q, stack_Q = np.zeros((2, n + pad)), np.zeros((2, n + pad, n + pad))
    stack_q[1, :n], stack_Q[1, :n, :n] = q, Q
    for args in ((q, Q), (stack_q[1, :n], stack_Q[1, :n, :n])):
        h, J, offset = ising_of_qubo(*args, 1.5)
        assert np.array_equal(h, ref.h) and np.array_equal(J, ref.J) and offset == ref.offset


# ----------------------------------------------------------------------------- path
@SETTINGS
@given(st.integers(0, 10**6), st.floats(0.0, 0.6), st.sampled_from(["pair", "degree"]), st.booleans())
def test_patch_qubo_kernel_is_the_numpy_reference(seed, density, form, custom):
    allowed, goal, rng = patch_case(seed, density)
    weights = {k: float(rng.uniform(0.1, 3.0)) for k in DEFAULT_WEIGHTS[form]} if custom else None
    a = build_patch_qubo(FRAME, allowed, 12, goal, form, weights)
    b = build_patch_qubo_reference(FRAME, allowed, 12, goal, form, weights)
    assert np.array_equal(a.cells, b.cells) and np.array_equal(a.q, b.q) and np.array_equal(a.Q, b.Q)
    assert a.offset == b.offset


@SETTINGS
@given(st.integers(0, 10**6), st.floats(0.0, 0.7), st.booleans(), st.booleans(), st.floats(0.0, 0.5))
def test_rank_local_targets_matches_the_reference(seed, density, interior, merged, excl_density):
    rng = np.random.default_rng(seed)
    h, w = int(rng.integers(1, 12)), int(rng.integers(1, 12))
    grid = rng.random((h, w)) < density
    pos = (int(rng.integers(h)), int(rng.integers(w)))
    goal = (int(rng.integers(h)), int(rng.integers(w)))
    grid[pos] = False
    padded = np.pad(grid, 2, constant_values=True)
    excluded = np.pad(rng.random((h, w)) < excl_density, 2, constant_values=False)
    comp, ranked = rank_local_targets(padded, pos[0], pos[1], goal[0], goal[1], 5, NBR, FRAME.ring, excluded,
                                      interior, merged, np.zeros((0, 0), dtype=np.int64))
    ref_comp, ref_ranked = ranked_reference(FRAME, padded, pos, goal, excluded, interior, merged)
    assert np.array_equal(comp, ref_comp)
    assert ranked.tolist() == ref_ranked
    # a Manhattan field given explicitly ranks exactly as the built-in Manhattan key
    rr, cc = np.indices(padded.shape)
    manhattan = (np.abs(rr - 2 - goal[0]) + np.abs(cc - 2 - goal[1])).astype(np.int64)
    comp2, ranked2 = rank_local_targets(padded, pos[0], pos[1], goal[0], goal[1], 5, NBR, FRAME.ring, excluded,
                                        interior, merged, manhattan)
    assert np.array_equal(comp2, comp) and ranked2.tolist() == ranked.tolist()


@SETTINGS
@given(st.integers(0, 10**6), st.floats(0.0, 0.5), st.integers(1, 6))
def test_patch_scoring_matches_reference_decode_and_energy(seed, density, reads):
    allowed, goal, rng = patch_case(seed, density)
    pr = build_patch_qubo(FRAME, allowed, 12, goal)
    model = QuboModel(pr.q, pr.Q, pr.offset).to_ising()
    n = pr.n
    # two unmerged "programs" (identity copy layout) plus one with every spin copied once
    P = 3
    W = max(2 * n, 1)
    spins = rng.choice(np.array([-1, 1], dtype=np.int8), size=(P, reads, W))
    # bias some reads towards valid paths: the decoded reference path of a BFS-like choice
    ptr = np.zeros((P, n + 1), dtype=np.int64)
    idx = np.zeros((P, W), dtype=np.int64)
    for p in range(2):
        ptr[p] = np.arange(n + 1)
        idx[p, :n] = np.arange(n)
    ptr[2] = 2 * np.arange(n + 1)
    for i in range(n):
        idx[2, 2 * i], idx[2, 2 * i + 1] = i, n + i
    n_valid, best, energy, logical = score_patch_samples(spins, ptr, idx, n, pr.cells, pr.start, pr.goal, NBR,
                                                         model.h, model.J, model.offset)
    for p in range(P):
        lg = []
        for r in range(reads):
            s = spins[p, r].astype(np.int64)
            x = np.empty(n, dtype=np.int64)
            for i in range(n):
                c = idx[p, ptr[p, i]:ptr[p, i + 1]]
                tot = s[c].sum()
                x[i] = 1 if tot > 0 else (-1 if tot < 0 else s[c[0]])
            lg.append(x)
        lg = np.array(lg).reshape(reads, n)
        assert np.array_equal(logical[p], lg)
        paths = decode_reference(FRAME, pr, lg > 0)
        ok = [q is not None for q in paths]
        assert n_valid[p] == sum(ok)
        if any(ok):
            e = [model.energy(lg[r]) if ok[r] else np.inf for r in range(reads)]
            assert best[p] == int(np.argmin(e)) and energy[p] == pytest.approx(min(e), abs=1e-9)
            got = extract_path(lg[best[p]] > 0, pr.cells, pr.start, pr.goal, NBR)
            assert got.tolist() == paths[best[p]]
        else:
            assert best[p] == -1 and energy[p] == np.inf
        for r in range(reads):
            got = extract_path(lg[r] > 0, pr.cells, pr.start, pr.goal, NBR)
            assert (got.tolist() if len(got) else None) == paths[r]


def test_empty_patch_problem_and_one_variable():
    allowed = np.zeros(25, dtype=bool)
    allowed[[12, 13]] = True  # the target is the robot's only neighbour: no variable
    pr = build_patch_qubo(FRAME, allowed, 12, 13)
    assert pr.n == 0
    assert extract_path(np.zeros(0, dtype=bool), pr.cells, 12, 13, NBR).tolist() == [12, 13]
    allowed[14] = True  # one variable between robot and target
    pr = build_patch_qubo(FRAME, allowed, 12, 14)
    assert pr.n == 1 and extract_path(np.ones(1, dtype=bool), pr.cells, 12, 14, NBR).tolist() == [12, 13, 14]
    assert len(extract_path(np.zeros(1, dtype=bool), pr.cells, 12, 14, NBR)) == 0


# ----------------------------------------------------------------------------- tour
def _ising_of(q, Q, off):
    return QuboModel(q, Q, off).to_ising()


@SETTINGS
@given(st.integers(0, 10**6), st.integers(1, 7))
def test_onehot_and_maxcut_ising_are_the_qubo_conversions(seed, s):
    rng = np.random.default_rng(seed)
    d = rng.integers(0, 20, size=(s, s)).astype(float)
    np.fill_diagonal(d, 0)
    entry = rng.integers(0, 20, size=s).astype(float)
    ex = rng.integers(0, 20, size=s).astype(float)
    q, Q, off, A = open_path_qubo(d, entry, ex)
    ref = _ising_of(q, Q, off)
    h, J, o = onehot_ising(d, entry, ex, onehot_penalty(d, entry, ex), 1.0)
    assert A == onehot_penalty(d, entry, ex)
    assert np.array_equal(h, ref.h) and np.array_equal(J, ref.J) and o == ref.offset
    w = d + d.T
    ref = _ising_of(*maxcut_qubo(w))
    h, J, o = maxcut_ising(w)
    assert np.array_equal(h, ref.h) and np.array_equal(J, ref.J) and o == ref.offset


@SETTINGS
@given(st.integers(0, 10**6), st.integers(3, 7), st.integers(0, 4))
def test_branch_stack_is_ising_backend_branch(seed, s, k):
    rng = np.random.default_rng(seed)
    d = rng.integers(0, 9, size=(s, s)).astype(float)
    entry = rng.integers(0, 9, size=s).astype(float)
    h, J, o = onehot_ising(d, entry, entry[::-1].copy(), onehot_penalty(d, entry, entry), 1.0)
    model = _ising_of(*open_path_qubo(d, entry, entry[::-1].copy())[:3])
    budget = s * s - k
    branches = branch_ref(model, budget)  # numpy, tests/mapping_reference.py
    frozen = branches[0][2]
    free, hb, Jb, offs = branch_stack(h, J, o, np.asarray(frozen, dtype=np.int64))
    assert len(branches) == len(hb) == 2 ** len(frozen)
    for m, (ref_model, ref_free, _frozen, _values) in enumerate(branches):
        assert np.array_equal(free, ref_free)
        assert np.allclose(hb[m], ref_model.h) and np.array_equal(Jb, ref_model.J)
        assert offs[m] == pytest.approx(ref_model.offset)
    pub = branch(model, budget, max_frozen=4)  # the public branching: the same kernels
    assert [b.frozen.tolist() for b in pub] == [frozen.tolist()] * len(pub)
    assert all(np.allclose(b.model.h, r[0].h) and b.model.offset == pytest.approx(r[0].offset)
               for b, r in zip(pub, branches))
    spins = rng.choice(np.array([-1, 1], dtype=np.int8), size=(len(hb), 2, len(free)))
    bits = expand_branches(spins, free, np.asarray(frozen, dtype=np.int64), s * s)
    ref = np.concatenate([(br.decode(spins[m]).astype(np.int64) + 1) // 2 for m, br in enumerate(pub)])
    assert np.array_equal(bits, ref)


@SETTINGS
@given(st.integers(0, 10**6), st.integers(1, 6), st.integers(1, 30), st.floats(0.0, 1.0))
def test_best_onehot_matches_batch_decode_and_cost(seed, s, m, perm_share):
    rng = np.random.default_rng(seed)
    bits = (rng.random((m, s * s)) < 1.0 / s).astype(np.uint8)
    for r in range(m):  # some rows are permutations
        if rng.random() < perm_share:
            bits[r] = 0
            bits[r, np.arange(s) * s + rng.permutation(s)] = 1
    d = rng.integers(0, 20, size=(s, s)).astype(float)
    entry = rng.integers(0, 20, size=s).astype(float)
    ex = rng.integers(0, 20, size=s).astype(float)
    valid, best, orders = best_onehot(bits, s, d, entry, ex)
    ref_orders, ref_valid = decode_onehot_batch(bits, s)
    assert np.array_equal(valid, ref_valid)
    assert np.array_equal(orders[valid], ref_orders[ref_valid])
    if ref_valid.any():
        cand = ref_orders[ref_valid]
        costs = entry[cand[:, 0]] + ex[cand[:, -1]] + d[cand[:, :-1], cand[:, 1:]].sum(axis=1)
        assert best == int(np.flatnonzero(ref_valid)[int(np.argmin(costs))])
    else:
        assert best == -1


# ----------------------------------------------------------------------------- sharing
@SETTINGS
@given(st.integers(0, 10**6), st.integers(2, 16), st.integers(1, 4), st.booleans())
def test_split_model_matches_anchors_and_split_qubo(seed, m, R, shifted):
    rng = np.random.default_rng(seed)
    pts = rng.integers(0, 10, size=(R + 16, 2))
    dist = np.abs(pts[:, None] - pts[None]).sum(-1).astype(float)
    if shifted:  # the planner's split weights: d - 0.5 mean (non-integer)
        dist = dist - 0.5 * dist[np.triu_indices(len(dist), 1)].mean()
        np.fill_diagonal(dist, 0.0)
    nodes = np.sort(rng.choice(R + 16, size=m, replace=False)).astype(np.int64)
    if int((nodes < R).sum()) == 1 and len(nodes) == 1:
        return
    a, b, free, q, Q, off = split_model(dist, nodes, R)
    ra, rb = choose_anchors(dist, nodes, R)
    rfree = np.array([v for v in nodes if v != ra and v != rb], dtype=np.int64)
    rq, rQ, roff = build_split_qubo(dist, rfree, ra, rb, R)
    assert (a, b) == (ra, rb) and np.array_equal(free, rfree)
    assert np.array_equal(q, rq) and np.array_equal(Q, rQ) and off == roff
    reads = rng.choice(np.array([-1, 1], dtype=np.int8), size=(8, len(free)))
    reads[5] = reads[1]
    for reject in (False, True):
        valid, cut, first = score_split_reads(reads, free, a, b, dist, R, reject)
        p = SplitProblem(nodes, a, b, free, q, Q, off, "robots")
        for r in range(8):
            side0, side1 = decode_split(p, reads[r])
            ok = not (reject and any((sd < R).any() and not (sd >= R).any() for sd in (side0, side1)))
            assert valid[r] == ok
            if ok:
                assert cut[r] == cut_value(dist, side0, side1)
            assert reads[first[r]].tobytes() == reads[r].tobytes() and first[r] <= r
        assert first[5] == first[1]


# ----------------------------------------------------------------------------- classical pricing
@SETTINGS
@given(st.integers(0, 10**6), st.integers(0, 9))
def test_exact_route_cost_is_brute_tour_cost(seed, n):
    rng = np.random.default_rng(seed)
    pts = rng.integers(0, 10, size=(n + 4, 2))
    dist = np.abs(pts[:, None] - pts[None]).sum(-1).astype(float)
    nodes = [int(v) for v in rng.permutation(n + 4)[: n + 1]]
    ref = BruteTour().solve(dist[np.ix_(nodes, nodes)]).cost
    assert exact_route_cost(dist, nodes) == ref


def test_exact_route_cost_refuses_too_many_targets():
    with pytest.raises(ValueError, match="MAX_BRUTE_TARGETS"):
        exact_route_cost(np.zeros((20, 20)), list(range(16)))


# ----------------------------------------------------------------------------- compiled path loop
@pytest.mark.parametrize("options, spec", [
    ({}, {}), ({"form": "degree"}, {}), ({"target_order": "merged", "num_reads": 2}, {}),
    ({"interior_targets": False, "backtrack": False}, {}), ({"max_attempts": 3}, {}),
    ({"target_key": "bfs"}, {}), ({"target_key": "bfs", "target_order": "merged"}, {}),
    ({"targets_per_call": 3}, {}), ({"targets_per_call": 2, "max_chip_calls": 40}, {}),
    ({"pack": True, "styles": ("overload", "balanced", "max_coeff")}, {}),
    ({"pack": True, "targets_per_call": 2}, {}),
    # a chip just large enough for a 5x5 patch: some styles do not fit some programs
    ({"patch_size": 5, "scale": 24.0}, {"n_spins": 25}),
    ({"patch_size": 5, "scale": 24.0, "targets_per_call": 2, "pack": True}, {"n_spins": 28}),
])
def test_compiled_path_loop_makes_the_reference_loops_decisions(options, spec):
    """The compiled search loop (planners.ising.path.engine) against the Python loop of
    tests/path_reference.py: the same paths, failures, statistics, chip charges and rng state on
    random worlds, for every option the loop takes (batched targets, packing, unmappable styles)."""
    from ising_backend import ChipSpec, EmulatedChip
    from mrmt_env.generation import generate_world
    from path_reference import reference_find_path
    from planners.ising.path import IsingPath

    fast, ref = IsingPath(EmulatedChip(ChipSpec(**spec)), **options), IsingPath(EmulatedChip(ChipSpec(**spec)), **options)
    outcomes = set()
    for s in range(8):
        w = generate_world(s, height=8 + s % 5, width=9 + s % 4, n_robots=2, n_targets=3,
                           obstacle_density=0.1 + 0.05 * (s % 4))
        for t in list(w.targets) + [w.robots[1]]:
            r1, r2 = np.random.default_rng(s), np.random.default_rng(s)
            a = fast.find_path(w, w.robots[0], t, r1)
            b = reference_find_path(ref, w, w.robots[0], t, r2)
            assert a.failure == b.failure
            assert (a.path is None and b.path is None) or np.array_equal(a.path, b.path)
            assert a.stats == b.stats and a.compute == b.compute
            assert r1.integers(1 << 62) == r2.integers(1 << 62)  # the same draws were made
            outcomes.add(a.failure is None)
    assert True in outcomes


def test_unmappable_styles_are_counted_and_named():
    """A style that cannot map a patch program is skipped and counted; when none maps, the query
    fails naming the merge kernel's error (no other code path runs)."""
    from ising_backend import ChipSpec, EmulatedChip
    from mrmt_env.generation import generate_world
    from planners.ising.path import IsingPath

    w = generate_world(3, obstacle_density=0.0)
    some = IsingPath(EmulatedChip(ChipSpec(n_spins=25)), patch_size=5, scale=24.0)
    errors = programs = 0
    for s in range(6):
        w = generate_world(s)
        m = some.find_path(w, w.robots[0], w.targets[0], np.random.default_rng(0)).stats["mapping"]["path"]
        errors += m["high_degree"]["map_errors"] - m["overload"]["map_errors"]  # styles fail on different programs
        programs += m["overload"]["programs"]
    assert errors > 0 and programs > 0
    w = generate_world(3, obstacle_density=0.0)
    none = IsingPath(EmulatedChip(ChipSpec(n_spins=23)), patch_size=5, scale=40.0, styles=("overload",),
                     fallback="never")
    res = none.find_path(w, w.robots[0], w.targets[0], np.random.default_rng(0))
    assert res.path is None and res.compute.chip_calls == 0
    assert "no patch program could be mapped onto the chip" in res.failure and "overload: " in res.failure


def test_chip_subclass_that_overrides_annealing_runs_the_compiled_loop_through_its_anneal_batch():
    from ising_backend import EmulatedChip
    from mrmt_env.generation import generate_world
    from planners.ising.path import IsingPath

    class Counting(EmulatedChip):
        submissions = 0

        def anneal_batch(self, h, J, num_reads=1, seed=None):
            self.submissions += 1
            return super().anneal_batch(h, J, num_reads=num_reads, seed=seed)

    chip = Counting()
    planner = IsingPath(chip)
    assert not planner.chip.session(CallLedger()).direct
    world = generate_world(2)
    a = planner.find_path(world, world.robots[0], world.targets[0], np.random.default_rng(0))
    b = IsingPath(EmulatedChip()).find_path(world, world.robots[0], world.targets[0], np.random.default_rng(0))
    # the same kernel behind the callback: the same path, statistics and charges as the emulator's own loop
    assert np.array_equal(a.path, b.path) and a.stats == b.stats
    assert a.compute.replace(emulation_s=0.0) == b.compute.replace(emulation_s=0.0)
    assert chip.submissions == a.stats["anneal_calls"] > 0 and chip.ledger.physical_calls == a.compute.chip_calls


@SETTINGS
@given(st.integers(0, 10**6), st.integers(1, 9), st.sampled_from(["min", "mean", "medoid"]))
def test_cluster_distances_match_the_numpy_reference(seed, K, mode):
    from planners.ising.tour import PaperIsingTour as IsingTour  # the logical construction

    rng = np.random.default_rng(seed)
    n = K + int(rng.integers(0, 12))
    pts = rng.normal(size=(n + 1, 2)) * 5
    dist = np.sqrt(((pts[:, None] - pts[None]) ** 2).sum(-1))
    cut = np.sort(rng.choice(np.arange(1, n), size=K - 1, replace=False)) if K > 1 else np.array([], dtype=int)
    clusters = [list(map(int, c)) for c in np.split(rng.permutation(np.arange(1, n + 1)), cut)]
    tour = IsingTour(cluster_distance=mode)
    from tour_reference import cluster_dist_reference

    assert np.array_equal(tour.clusters.cluster_dist(dist, clusters), cluster_dist_reference(dist, clusters, mode))


@pytest.mark.parametrize("options, spec", [
    ({}, {}), ({"n_starts": 2, "num_reads": 2}, {}), ({"max_retries": 0, "patch_size": 4}, {}),
    ({"local_limit": 7, "max_branch_bits": 6}, {}),  # 49-spin local TSPs: spin-budget branching
    ({"backend": "chip-onehot", "local_limit": 4, "patch_size": 4, "max_clusters": 5}, {}),  # quantized, on the chip
    ({}, {"readout_flip_prob": 0.05}),  # a faulty chip's logical solver: the callback
])
def test_compiled_tour_subproblems_make_the_reference_decisions(options, spec):
    """planners.ising.tour.engine.solve_order against the Python calls of tests/tour_reference.py:
    the same tours, statistics, charges and rng state (logical solver, branching, physical chip)."""
    from ising_backend import ChipSpec, EmulatedChip
    from mrmt_env.generation import generate_world
    from planners.ising.tour import PaperIsingTour as IsingTour  # the logical construction
    from tour_reference import reference_solve_path

    fast, ref = IsingTour(EmulatedChip(ChipSpec(**spec)), **options), IsingTour(EmulatedChip(ChipSpec(**spec)), **options)
    ref.onehot.solve_path = lambda *a: reference_solve_path(ref, *a)
    solved = 0
    for s in range(10):
        dist = generate_world(s, n_robots=1, n_targets=3 + s % 9).distance_matrix
        r1, r2 = np.random.default_rng(s), np.random.default_rng(s)
        a, b = fast.solve(dist, r1), ref.solve(dist, r2)
        assert a.order == b.order and a.cost == b.cost and a.failure == b.failure
        assert a.stats == b.stats and a.compute == b.compute
        assert r1.integers(1 << 62) == r2.integers(1 << 62)
        solved += a.failure is None
    assert solved > 0


def test_the_subproblem_backend_is_chosen_at_compile_time():
    """The one-hot solve gets the unused machine record as None, so the logical solve is compiled without
    the chip's submission (and the chip's without the logical solver): numba could not type either call
    with None, so a None in the signature means that branch was pruned before typing (cold start)."""
    from numba import types

    from mrmt_env.generation import generate_world
    from planners.ising.tour import PaperIsingTour
    from planners.ising.tour.engine import solve_order

    dist = generate_world(3, n_robots=1, n_targets=6).distance_matrix
    for options in ({}, {"backend": "chip-onehot", "local_limit": 4, "patch_size": 4}):
        c = PaperIsingTour(**options).solve(dist, np.random.default_rng(0)).compute
        assert c.logical_calls + c.chip_calls > 0  # the compiled solve ran (a quantized one may find no order)
    none_at = {tuple(i for i, t in enumerate(sig) if isinstance(t, types.NoneType)) for sig in solve_order.signatures}
    assert {(5,), (6,)} <= none_at  # (rng, d, entry, ex, options, solver, machine): one None each


def test_a_user_solver_with_solve_many_runs_the_compiled_subproblem_solve():
    """A logical solver that only offers ``solve_many`` (no kernel, no ``solve_stack``) is reached
    through the machine link's callback: the same tours as the built-in solver it wraps."""
    from ising_backend import LogicalIsingSolver
    from mrmt_env.generation import generate_world
    from planners.ising.tour import PaperIsingTour

    class Wrapped:
        def __init__(self):
            self.inner = LogicalIsingSolver()
            self.ledger = self.inner.ledger
            self.calls = 0

        def solve_many(self, models, num_reads=1, seed=None):
            self.calls += 1
            return self.inner.solve_many(models, num_reads=num_reads, seed=seed)

    solver = Wrapped()
    dist = generate_world(4, n_robots=1, n_targets=8).distance_matrix
    a = PaperIsingTour(solver=solver).solve(dist, np.random.default_rng(0))
    b = PaperIsingTour().solve(dist, np.random.default_rng(0))
    assert solver.calls > 0 and a.order == b.order and a.stats == b.stats
    assert a.compute.logical_calls == b.compute.logical_calls > 0


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(1, 12), min_size=1, max_size=12), st.integers(12, 45), st.integers(0, 2**31))
def test_fill_packs_places_programs_as_the_python_loop(sizes, capacity, seed):
    from ising_backend import fill_packs
    from mapping_reference import plan_packs_ref as plan_packs

    rng = np.random.default_rng(seed)
    sizes = np.array(sizes, dtype=np.int64)
    f = int(sizes.max())
    qh = rng.integers(-7, 8, (len(sizes), f)).astype(float)
    qJ = np.triu(rng.integers(-7, 8, (len(sizes), f, f)), k=1).astype(float)
    packs = plan_packs(sizes.tolist(), capacity)
    width = max(int(sizes[pk].sum()) for pk in packs)
    h_ref, J_ref = np.zeros((len(packs), width)), np.zeros((len(packs), width, width))
    where_ref = np.zeros((len(sizes), 2), dtype=np.int64)
    for b, pk in enumerate(packs):
        s0 = 0
        for j in pk:
            n = int(sizes[j])
            h_ref[b, s0:s0 + n] = qh[j, :n]
            J_ref[b, s0:s0 + n, s0:s0 + n] = qJ[j, :n, :n]
            where_ref[j] = (b, s0)
            s0 += n
    pack_of = np.empty(len(sizes), dtype=np.int64)
    for b, pk in enumerate(packs):
        pack_of[pk] = b
    order = np.array([j for pk in packs for j in pk], dtype=np.int64)
    h, J, where = fill_packs(qh, qJ, sizes, order, pack_of, len(packs), width)
    assert np.array_equal(h, h_ref) and np.array_equal(J, J_ref) and np.array_equal(where, where_ref)


@settings(max_examples=80, deadline=None)
@given(st.lists(st.integers(0, 45), min_size=1, max_size=24), st.integers(45, 90))
def test_pack_layout_is_plan_packs(sizes, capacity):
    """The compiled first-fit-decreasing layout against the Python loop of tests/mapping_reference.py (empty
    programs, one program, programs that fill a pack exactly), and ising_backend.plan_packs's lists of it."""
    from ising_backend import pack_layout, plan_packs
    from mapping_reference import plan_packs_ref

    packs = plan_packs_ref(sizes, capacity)
    assert plan_packs(sizes, capacity) == packs
    pack_of, order, n_packs, width = pack_layout(np.array(sizes, dtype=np.int64), capacity)
    assert n_packs == len(packs)
    assert order.tolist() == [j for pk in packs for j in pk]
    assert all(pack_of[j] == b for b, pk in enumerate(packs) for j in pk)
    assert width == max(sum(sizes[j] for j in pk) for pk in packs)


@SETTINGS
@given(st.integers(0, 10**6), st.integers(1, 40), st.booleans(), st.booleans())
def test_cut_walk_is_the_checked_path(seed, steps, cut, corrupt):
    """The compiled loop cut and path check (kernels.cut_walk) against the Python loop cut and a
    step-by-step check: random walks with loops, walks through obstacles, broken steps and wrong ends."""
    from planners.ising.path.kernels import cut_walk

    rng = np.random.default_rng(seed)
    grid = rng.random((6, 7)) < 0.15
    r, c = int(rng.integers(6)), int(rng.integers(7))
    walk = [(r, c)]
    for _ in range(steps):
        dr, dc = [(0, 1), (1, 0), (0, -1), (-1, 0)][int(rng.integers(4))]
        r, c = min(max(r + dr, 0), 5), min(max(c + dc, 0), 6)
        walk.append((r, c))
    if corrupt and len(walk) > 2:
        walk[int(rng.integers(1, len(walk)))] = (int(rng.integers(6)), int(rng.integers(7)))
    s, g = walk[0], walk[-1] if rng.random() < 0.9 else (int(rng.integers(6)), int(rng.integers(7)))
    cells = cut_loops(walk) if cut else walk
    ref_ok = (cells[0] == s and cells[-1] == g and not any(grid[rc] for rc in cells)
              and all(abs(a[0] - b[0]) + abs(a[1] - b[1]) == 1 for a, b in zip(cells, cells[1:])))
    ok, path = cut_walk(np.array(walk, dtype=np.int64), grid, s[0], s[1], g[0], g[1], cut)
    assert ok == ref_ok
    if ok:
        assert path.tolist() == [list(rc) for rc in cells]


@pytest.mark.parametrize("spec, options", [
    ({}, {}), ({"n_spins": 16}, {}), ({"n_spins": 24, "h_range": (-3, 3), "j_range": (-3, 3)}, {}),
    ({}, {"reject_empty_robot_side": True}),  # the validity rule's other branch
])
def test_compiled_stage_submission_makes_the_reference_decisions(spec, options):
    """The compiled sharing (each stage one submission, planners.ising.sharing.stage_steps.submit_stage)
    against the Python search with every stage submitted through anneal_batch: the same assignments,
    statistics, chip charges and rng state."""
    from ising_backend import ChipSpec, EmulatedChip
    from mrmt_env.generation import generate_world
    from planners.ising.sharing import IsingSharing
    from planners.tours_classical import ThreeOptTour

    from sharing_reference import reference_solve_packed
    from sharing_search_reference import reference_assign

    fast = IsingSharing(EmulatedChip(ChipSpec(**spec)), **options)
    ref = IsingSharing(EmulatedChip(ChipSpec(**spec)), **options)
    for s in range(10):
        w = generate_world(s, n_robots=2 + s % 3, n_targets=6 + s, placement="centre" if s % 2 else "uniform")
        r1, r2 = np.random.default_rng(s), np.random.default_rng(s)
        a = fast.assign(w.distance_matrix, w.n_robots, ThreeOptTour(), r1)
        # the Python search with each stage submitted through anneal_batch
        b = reference_assign(ref, w.distance_matrix, w.n_robots, ThreeOptTour(), r2, solve_packed=reference_solve_packed)
        assert a.assignment == b.assignment and a.failure == b.failure and a.stats == b.stats
        assert (a.compute.chip_calls, a.compute.chip_batches) == (b.compute.chip_calls, b.compute.chip_batches)
        assert a.compute.accelerator_energy_j == pytest.approx(b.compute.accelerator_energy_j)
        assert r1.integers(1 << 62) == r2.integers(1 << 62)


def test_compiled_stage_submission_refuses_what_the_chip_would_refuse():
    """submit_stage anneals nothing (a non-zero status, no calls) for a non-finite split model or
    programs the chip's check refuses; the sharing names the refusal."""
    from ising_backend import QUANTIZE_RULE_IDS, STACK_NONFINITE, STACK_OK, STACK_UNFIT, AnnealArgs, EmulatedChip
    from planners.ising.sharing.split_problem import SplitProblems
    from planners.ising.sharing.stage_steps import StageProgram, submit_stage

    chip = EmulatedChip()
    rules = np.array([QUANTIZE_RULE_IDS["linear"]], dtype=np.int64)
    dist = np.abs(np.arange(6)[:, None] - np.arange(6)[None]).astype(float)
    free = np.array([[2, 3, 4, 5]], dtype=np.int64)
    anchors = np.array([[0, 1]], dtype=np.int64)
    sizes = np.array([4], dtype=np.int64)
    q = np.array([[1.0, -2.0, 0.5, 3.0]])
    Q = np.triu(np.ones((1, 4, 4)), k=1)

    def run(q, Lh=7.0, Lj=7.0):
        problems = SplitProblems(q, Q, free, sizes, anchors, np.zeros(1, dtype=np.bool_), np.zeros(1, dtype=np.int64),
                                 np.zeros((1, 4), dtype=np.int8))
        program = StageProgram(rules=rules, Lh=Lh, Lj=Lj, capacity=45, num_reads=2, n_spins=45, retries=0)
        return submit_stage(problems, program, np.uint64(5), AnnealArgs(-1, *chip.kernel_args()), dist, 2)

    good = run(q)
    assert good.status == STACK_OK and good.calls == 2 and good.scores.n_valid.sum() <= 2
    bad = q.copy()
    bad[0, 1] = np.nan
    out = run(bad)
    assert out.status == STACK_NONFINITE and out.calls == 0 and len(out.scores.split) == 0
    assert run(q, Lh=7.5).status == STACK_UNFIT  # a non-integer limit: the quantized fields are not the chip's integers


def test_sharing_on_distances_too_large_to_add_fails_naming_the_refused_stage():
    """Split weights that overflow give a non-finite stage program: the sharing stops before anything is
    annealed and fails naming it (no second code path, no rng rewind)."""
    from ising_backend import EmulatedChip
    from planners.ising.sharing import IsingSharing
    from planners.tours_classical import ThreeOptTour

    pts = np.random.default_rng(1).random((9, 2))
    dist = np.abs(pts[:, None] - pts[None]).sum(-1) * 1e308
    sharing = IsingSharing(EmulatedChip(), fallback="never")
    res = sharing.assign(dist, 3, ThreeOptTour(), np.random.default_rng(0))
    assert res.failure is not None and "could not be quantized" in res.failure
    assert res.compute.chip_calls == 0


# ----------------------------------------------------------------------------- tour solve helpers
@SETTINGS
@given(st.integers(1, 40), st.integers(0, 2**32 - 1), st.booleans())
def test_route_cost_is_numpy_sum(n, seed, integral):
    """The compiled route cost has the bits of ``dist[nodes[:-1], nodes[1:]].sum()`` (pairwise
    summation above 8 legs)."""
    rng = np.random.default_rng(seed)
    d = rng.integers(0, 30, (n + 1, n + 1)).astype(float) if integral else rng.random((n + 1, n + 1)) * 1e3
    order = rng.permutation(np.arange(1, n + 1))
    nodes = np.concatenate([[0], order])
    assert route_cost(d, order) == d[nodes[:-1], nodes[1:]].sum()


@SETTINGS
@given(st.integers(1, 6), st.integers(0, 2**32 - 1), st.floats(0.0, 0.3), st.floats(0.0, 0.3), st.floats(0.0, 0.3))
def test_dist_flags_is_the_numpy_checks(n, seed, p_nan, p_neg, p_inf):
    """Code 1 iff an entry is NaN or negative, else 2 with the first infinite entry (row-major) iff
    one is infinite, else 0."""
    rng = np.random.default_rng(seed)
    d = rng.random((n, n)) * 10
    d[rng.random((n, n)) < p_inf] = np.inf
    d[rng.random((n, n)) < p_nan] = np.nan
    d[rng.random((n, n)) < p_neg] = -1.0
    code, r, c = dist_flags(d)
    if np.isnan(d).any() or (d < 0).any():
        assert code == 1
    elif not np.isfinite(d).all():
        assert code == 2 and (r, c) == tuple(np.argwhere(~np.isfinite(d))[0])
    else:
        assert (code, r, c) == (0, -1, -1)


def _same_runs(out, runs):
    """Two tour runs that must agree: their results, statistics, charges and generators' next draw."""
    assert out[0] == out[1]
    a, b = runs
    assert a.stats == b.stats
    assert (a.charged.physical_calls, a.charged.batches) == (b.charged.physical_calls, b.charged.batches)
    assert a.rng.integers(1 << 62) == b.rng.integers(1 << 62)
    return a, b


@pytest.mark.parametrize("options, spec", [
    ({}, {}), ({"num_reads": 3, "max_retries": 0}, {}), ({"chip_rules": ("rank",), "max_moves": 6}, {}),
    ({"max_segment": 2, "max_overlap": 0}, {"n_spins": 12}),
    ({}, {"readout_flip_prob": 0.05, "stuck_spins": 2}),  # a faulty chip: the same loop through its anneal_batch
])
def test_compiled_move_selection_makes_the_reference_decisions(options, spec):
    """planners.ising.moves.search.move_search (one start of the chip tour) against the
    Python loop of tests/tour_reference.py: the same routes, failures, statistics, charges and rng
    state from nearest-neighbour and random starts."""
    from ising_backend import ChipSpec, EmulatedChip
    from mrmt_env.generation import generate_world
    from planners.ising.tour import IsingTour, TourFailure
    from planners.ising.tour.cluster import _Run
    from tour_reference import nearest_neighbour_route, reference_select_moves

    fast = IsingTour(EmulatedChip(ChipSpec(**spec)), backend="chip", **options)
    ref = IsingTour(EmulatedChip(ChipSpec(**spec)), backend="chip", **options)

    def select(dist, route, run):  # one start on its own session, charged as MoveSearch.starts charges
        from planners.ising.tour.selection import settle

        charges = []
        with fast.chip.session(run.charged, decision="tour_moves") as link:
            try:
                return fast.moves.select(np.ascontiguousarray(dist, dtype=np.float64), route, run, link, charges)
            finally:
                settle(link, charges)

    moved = 0
    for s in range(10):
        dist = generate_world(s, n_robots=1, n_targets=4 + 2 * s).distance_matrix
        start = nearest_neighbour_route(dist) if s % 2 else np.concatenate(
            [[0], 1 + np.random.default_rng(s).permutation(len(dist) - 1)]).astype(np.int64)
        runs = [_Run(np.random.default_rng(s), t._empty_stats(), t) for t in (fast, ref)]
        out = []
        for tour, run, step in ((fast, runs[0], select), (ref, runs[1], None)):
            try:
                got = step(dist, start, run) if step else reference_select_moves(tour, dist, start, run)
                out.append(got.tolist())
            except TourFailure as exc:
                out.append(str(exc))
        a, b = _same_runs(out, runs)
        moved += a.stats["moves_applied"] * a.charged.physical_calls
    assert moved > 0


def _starts_one_at_a_time(tour, dist, run):
    """The chip tour's starts as a loop over :meth:`MoveSearch.select`, one start a call (the order of
    ``MoveSearch.starts``: nearest neighbour, then random orders or kicks of the best route drawn here)."""
    from planners.ising.tour import TourFailure
    from planners.ising.tour.selection import KICK_ABOVE, double_bridge, nearest_neighbour_kernel, settle

    cfg = tour.config
    n = dist.shape[0] - 1
    kicks = cfg.chip_restart == "kick" or (cfg.chip_restart == "auto" and n > KICK_ABOVE)
    best, best_cost, failure, charges = None, np.inf, None, []
    with tour.chip.session(run.charged, decision="tour_moves") as link:
        try:
            for s in range(1 if n <= 3 else cfg.n_starts):
                if s == 0:
                    route = nearest_neighbour_kernel(dist)
                elif kicks and best is not None and n >= 4:
                    route = double_bridge(best, run.rng)
                else:
                    route = np.concatenate([[0], 1 + run.rng.permutation(n)]).astype(np.int64)
                try:
                    route = tour.moves.select(dist, route, run, link, charges)
                except TourFailure as exc:
                    failure = exc
                    run.stats["failed_starts"] += 1
                    continue
                cost = float(dist[route[:-1], route[1:]].sum())
                run.stats["start_costs"].append(cost)
                if cost < best_cost - 1e-9:
                    best, best_cost = route, cost
        finally:
            settle(link, charges)
    if best is None:
        raise failure
    return [int(t) for t in best[1:]]


@pytest.mark.parametrize("options, spec", [
    ({"chip_restart": "random"}, {}), ({"chip_restart": "kick", "n_starts": 5}, {}),
    ({"chip_restart": "random", "num_reads": 2, "max_retries": 0}, {"readout_flip_prob": 0.2}),
    ({"chip_restart": "kick", "num_reads": 2, "max_retries": 0}, {"readout_flip_prob": 0.2}),
])
def test_compiled_starts_make_the_start_by_start_loop(options, spec):
    """MoveSearch.starts (every start in one compiled call, planners.ising.tour.selection.search_starts, or one
    call a kick) against the loop of one start at a time with the random orders and kicks drawn in Python: the
    same route or failure, start costs, failed starts, statistics, charges and rng state."""
    from ising_backend import ChipSpec, EmulatedChip
    from mrmt_env.generation import generate_world
    from planners.ising.tour import IsingTour, TourFailure
    from planners.ising.tour.cluster import _Run

    tours = [IsingTour(EmulatedChip(ChipSpec(seed=3, **spec)), backend="chip", **options) for _ in range(2)]
    failed = 0
    for s in range(8):
        dist = np.ascontiguousarray(generate_world(s, n_robots=1, n_targets=3 + 3 * s).distance_matrix,
                                    dtype=np.float64)
        runs = [_Run(np.random.default_rng(s), t._empty_stats(), t) for t in tours]
        out = []
        for tour, run, step in ((tours[0], runs[0], lambda t, d, r: t.moves.starts(d, r)),
                                (tours[1], runs[1], _starts_one_at_a_time)):
            try:
                out.append(step(tour, dist, run))
            except TourFailure as exc:
                out.append(str(exc))
        a, b = _same_runs(out, runs)
        failed += a.stats["failed_starts"]
    if spec:
        assert failed > 0  # the faulty chip makes starts fail: the failure path is compared too


@pytest.mark.parametrize("restart", ["random", "kick"])
def test_a_move_selection_program_the_quantizer_refuses_fails_the_tour_naming_it(restart):
    """Distances so large that move gains overflow give a non-finite selection program: the chip
    tour fails naming it at the first start, nothing annealed (no second code path runs), with random
    restarts and with kicks alike."""
    from planners.ising.tour import IsingTour

    pts = np.random.default_rng(0).random((8, 2))
    dist = np.abs(pts[:, None] - pts[None]).sum(-1) * 1e308
    assert np.isfinite(dist).all()
    res = IsingTour(backend="chip", fallback="never", chip_restart=restart).solve(dist, np.random.default_rng(0))
    assert res.stats["failed_starts"] == 0  # the refusal ends the search: no later start runs
    assert res.order is None or not len(res.order)
    assert "refused a move-selection program: a coefficient is not finite" in res.failure
    assert res.compute.chip_calls == 0


@SETTINGS
@given(st.integers(0, 10**6), st.integers(2, 30), st.integers(0, 8))
def test_frozen_spins_is_freeze_order(seed, n, k):
    """The compiled freezing order (every spin-budget branching) against the numpy one of
    tests/mapping_reference.py, ties included (integer coefficients)."""
    from ising_backend import IsingModel, freeze_order
    from ising_backend.mapping.branching import frozen_spins
    from mapping_reference import freeze_order_ref

    rng = np.random.default_rng(seed)
    k = min(k, n)
    h = rng.integers(-3, 4, n).astype(float)
    J = np.triu(rng.integers(-3, 4, (n, n)), k=1).astype(float)
    ref = np.sort(freeze_order_ref(IsingModel.trusted(h, J, 0.0))[:k])
    assert frozen_spins(h, J, k).tolist() == ref.tolist()
    assert np.sort(freeze_order(IsingModel.trusted(h, J, 0.0))[:k]).tolist() == ref.tolist()
