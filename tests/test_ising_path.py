"""Patch-sliding Ising pathfinding (planners/ising_path.py, paper 5.1 / Algorithm 1)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from planners.ising_path import (
    DEFAULT_WEIGHTS,
    build_patch_qubo,
    component_of,
    cut_loops,
    decode_paths,
    patch_frame,
)

FRAME = patch_frame(5)
CENTRE = FRAME.n // 2


def _cell(r, c, size=5):
    return r * size + c


def _direct_energy(frame, allowed, start, goal, sel, form, w):
    """Reference energy of a selection (set of frame cells incl. pins), straight from the formulas."""
    x = np.zeros(frame.n)
    x[list(sel)] = 1.0
    A = frame.adj4 & allowed[:, None] & allowed[None, :]
    deg = A.astype(float) @ x
    e_end = (deg[start] - 1) ** 2 + (deg[goal] - 1) ** 2
    free = [i for i in range(frame.n) if allowed[i] and i not in (start, goal)]
    if form == "pair":
        iu = np.triu_indices(frame.n, 1)
        D = frame.diag & allowed[:, None] & allowed[None, :]
        pairs_adj = sum(x[i] * x[j] for i, j in zip(*iu) if A[i, j])
        pairs_diag = sum(x[i] * x[j] for i, j in zip(*iu) if D[i, j])
        return (-w["C"] * pairs_adj + w["Dg"] * pairs_diag + w["B"] * sum(x[i] for i in free)
                + w["A_end"] * e_end)
    conn = sum((deg[i] - 2 * x[i]) ** 2 for i in free)
    return w["A_end"] * e_end + w["A"] * conn + w["B"] * sum(x[i] for i in free)


@pytest.mark.parametrize("form", ["pair", "degree"])
def test_patch_qubo_matches_formula_on_every_assignment(form):
    rng = np.random.default_rng(3)
    for _ in range(3):
        allowed = rng.random(FRAME.n) > 0.35
        allowed[CENTRE] = True
        comp = component_of(FRAME, allowed, CENTRE)
        goals = np.flatnonzero(comp & FRAME.ring)
        if len(goals) == 0:
            continue
        goal = int(goals[0])
        # keep the brute force small: restrict to a few cells
        keep = np.zeros(FRAME.n, dtype=bool)
        keep[np.flatnonzero(comp)[:10]] = True
        keep[[CENTRE, goal]] = True
        pr = build_patch_qubo(FRAME, keep, CENTRE, goal, form)
        assert CENTRE not in pr.cells and goal not in pr.cells  # pinned = substituted
        w = DEFAULT_WEIGHTS[form]
        for bits in itertools.product((0, 1), repeat=pr.n):
            sel = {CENTRE, goal} | {int(c) for c, b in zip(pr.cells, bits) if b}
            ref = _direct_energy(FRAME, keep, CENTRE, goal, sel, form, w)
            assert pr.energy(np.array(bits)) == pytest.approx(ref, abs=1e-9)


def test_pair_form_ground_state_is_the_straight_corridor():
    allowed = np.zeros(FRAME.n, dtype=bool)
    allowed[[_cell(2, c) for c in range(5)]] = True  # the centre row
    allowed[[_cell(1, c) for c in range(5)]] = True  # a parallel free row
    goal = _cell(2, 4)
    pr = build_patch_qubo(FRAME, allowed, CENTRE, goal, "pair")
    bits = np.array(list(itertools.product((0, 1), repeat=pr.n)))
    best = bits[np.argmin(pr.energy(bits))]
    path = decode_paths(FRAME, pr, best[None])[0]
    assert path == [CENTRE, _cell(2, 3), goal]


def test_decode_accepts_only_simple_connected_paths():
    allowed = np.ones(FRAME.n, dtype=bool)
    goal = _cell(0, 2)
    pr = build_patch_qubo(FRAME, allowed, CENTRE, goal, "pair")
    pos = {int(c): k for k, c in enumerate(pr.cells)}

    def x_of(cells):
        x = np.zeros(pr.n, dtype=np.int8)
        x[[pos[c] for c in cells]] = 1
        return x

    good = x_of([_cell(1, 2)])
    bent = x_of([_cell(2, 3), _cell(1, 3), _cell(0, 3)])
    empty = x_of([])
    dangling = x_of([_cell(1, 2), _cell(1, 1)])  # a branch
    island = x_of([_cell(1, 2), _cell(4, 4)])  # an extra disconnected cell
    blob = x_of([_cell(1, 2), _cell(1, 3), _cell(0, 3)])  # a 2x2 block (cycle)
    out = decode_paths(FRAME, pr, np.stack([good, bent, empty, dangling, island, blob]))
    assert out[0] == [CENTRE, _cell(1, 2), goal]
    assert out[1] == [CENTRE, _cell(2, 3), _cell(1, 3), _cell(0, 3), goal]
    assert out[2:] == [None, None, None, None]


def test_decode_rejects_path_plus_disjoint_cycle():
    # every selected cell has the right degree, but a chordless cycle around an
    # obstacle floats beside the path: connectivity must reject it
    fr = patch_frame(7)
    centre = fr.n // 2  # (3, 3)
    allowed = np.ones(fr.n, dtype=bool)
    allowed[_cell(1, 1, 7)] = False
    goal = _cell(3, 4, 7)
    pr = build_patch_qubo(fr, allowed, centre, goal, "pair")
    pos = {int(c): k for k, c in enumerate(pr.cells)}
    cycle = [(0, 0), (0, 1), (0, 2), (1, 2), (2, 2), (2, 1), (2, 0), (1, 0)]
    x = np.zeros(pr.n, dtype=np.int8)
    x[[pos[_cell(r, c, 7)] for r, c in cycle]] = 1
    assert decode_paths(fr, pr, np.zeros((1, pr.n)))[0] == [centre, goal]
    assert decode_paths(fr, pr, x[None])[0] is None


def test_adjacent_endpoints_need_no_variables_when_alone():
    allowed = np.zeros(FRAME.n, dtype=bool)
    allowed[[CENTRE, _cell(2, 3)]] = True
    pr = build_patch_qubo(FRAME, allowed, CENTRE, _cell(2, 3), "pair")
    assert pr.n == 0
    assert decode_paths(FRAME, pr, np.zeros((1, 0)))[0] == [CENTRE, _cell(2, 3)]


def test_bad_formulation_arguments_are_named():
    allowed = np.ones(FRAME.n, dtype=bool)
    with pytest.raises(ValueError, match="form"):
        build_patch_qubo(FRAME, allowed, CENTRE, 0, "edge")
    with pytest.raises(ValueError, match="unknown weights"):
        build_patch_qubo(FRAME, allowed, CENTRE, 0, "pair", {"Z": 1.0})
    with pytest.raises(ValueError, match="patch_size"):
        patch_frame(4)


def test_cut_loops_removes_revisits_only():
    walk = [(0, 0), (0, 1), (1, 1), (1, 2), (1, 1), (2, 1), (2, 2)]
    assert cut_loops(walk) == [(0, 0), (0, 1), (1, 1), (2, 1), (2, 2)]
    simple = [(0, 0), (1, 0), (1, 1)]
    assert cut_loops(simple) == simple
    back_and_forth = [(0, 0), (0, 1), (0, 2), (0, 1), (0, 0), (1, 0)]
    assert cut_loops(back_and_forth) == [(0, 0), (1, 0)]
