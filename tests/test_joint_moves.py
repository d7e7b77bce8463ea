"""Joint next moves as a chip decision: QUBO = objective, exact = brute force, decoded answers valid, determinism."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ising_backend import integer_program
from planners.mapf import TURNING_PLANNERS, make_turning_planner
from planners.mapf.chip.joint_executor import JointMovesStep
from planners.mapf.chip.joint_moves import CELL, COST, DEP, FWD, UNREAL, build_qubo, decode_reads, objective, \
    solve_exact

F, R, C, W = 0, 1, 2, 3
DR, DC = (0, 1, 0, -1), (1, 0, -1, 0)


def JointMovesPIBT(grid, seed=0, machine=None, **options):
    """``pibt-ising`` (PIBT + the chip's joint next moves) on ``grid`` (``machine`` default: the emulated chip)."""
    return make_turning_planner("pibt-ising", grid, seed=seed, machine=machine, **options)


def crowd(seed, size=10, fill=0.6, obstacles=0.15):
    rng = np.random.default_rng(seed)
    grid = rng.random((size, size)) < obstacles
    free = np.flatnonzero(~grid.reshape(-1))
    n = int(fill * len(free))
    pos = rng.choice(free, n, replace=False)
    return grid, pos, rng.integers(0, 4, n), rng.choice(free, n)


def check_valid(grid, pos, orient, act):
    """Independent rules: the next state, or an AssertionError naming the broken rule."""
    h, w = grid.shape
    nxt, nor = [], []
    for p, o, a in zip(pos.tolist(), orient.tolist(), act.tolist()):
        r, c = divmod(p, w)
        if a == F:
            r, c = r + DR[o], c + DC[o]
            assert 0 <= r < h and 0 <= c < w and not grid[r, c], "forward off the map or into an obstacle"
        nxt.append(r * w + c)
        nor.append((o + (a == R) - (a == C)) % 4)
    assert len(set(nxt)) == len(nxt), "vertex conflict"
    moves = {(p, q) for p, q in zip(pos.tolist(), nxt) if p != q}
    assert not any((q, p) in moves for p, q in moves), "swap"
    return np.array(nxt), np.array(nor)


def sampled_groups(seeds=range(4), steps=6, **options):
    """Groups posed on crowded random maps (the host rule's trajectory)."""
    out = []
    for s in seeds:
        grid, pos, orient, goals = crowd(s)
        ex = JointMovesPIBT(grid, seed=s, accept="host", **options)
        ex.machine_step.sample = []
        for _ in range(steps):
            act = ex.actions(pos, orient, goals)
            pos, orient = check_valid(grid, pos, orient, act)
        out += ex.machine_step.sample
    return out


def brute(pos, ostart, opt):
    """Every feasible joint choice and its objective (claims distinct, no swap; a forward claim into a
    member's cell costs UNREAL unless that member claims forward too) -- plain Python."""
    size = len(pos)
    ranges = [range(ostart[t + 1] - ostart[t]) for t in range(size)]
    for choice in itertools.product(*ranges):
        rows = [opt[ostart[t] + choice[t]] for t in range(size)]
        cells = [int(r[CELL]) for r in rows]
        if len(set(cells)) < size:
            continue
        if any(cells[i] == pos[j] and cells[j] == pos[i] for i in range(size) for j in range(i + 1, size)):
            continue
        value = 0
        for r in rows:
            d = int(r[DEP])
            value += int(r[COST]) if d < 0 or rows[d][FWD] else int(r[UNREAL])
        yield choice, value


@pytest.mark.parametrize("push", [0, 1, 2])
def test_qubo_energy_equals_objective_and_exact_equals_brute_force(push):
    groups = [g for g in sampled_groups(max_robots=5, push=push) if np.prod(np.diff(g[1])) <= 4000]
    assert len(groups) >= 20
    assert any((g[2][:, DEP] >= 0).any() for g in groups)  # forward claims into a member's cell are tested
    for pos, ostart, opt, host in groups:
        size = len(pos)
        mem = np.arange(size)
        n = int(ostart[-1])
        q = np.empty((n, n), dtype=np.int64)
        pen = 9
        build_qubo(pos, mem, 0, size, ostart, opt, pen, pen, q)
        best = None
        for choice, value in brute(pos, ostart, opt):
            x = np.zeros(n, dtype=np.int64)
            x[ostart[:-1] + np.array(choice)] = 1
            assert x @ np.triu(q) @ x + pen * size == value  # q is upper triangular with the diagonal
            assert objective(0, size, ostart, opt, np.array(choice)) == value
            best = value if best is None else min(best, value)
        got = np.empty(size, dtype=np.int64)
        assert solve_exact(pos, mem, 0, size, ostart, opt, got) == best
        assert objective(0, size, ostart, opt, got) == best
        assert objective(0, size, ostart, opt, host) >= best  # the host rule's answer is feasible


def test_mapping_fits_the_chip_and_keeps_signs():
    for pos, ostart, opt, host in sampled_groups(seeds=range(2)):
        size, n = len(pos), int(ostart[-1])
        q = np.empty((n, n), dtype=np.int64)
        build_qubo(pos, np.arange(size), 0, size, ostart, opt, 7, 7, q)
        h, J = np.empty(n, dtype=np.int64), np.empty((n, n), dtype=np.int64)
        integer_program(q, n, h, J, (7, 7))
        assert np.abs(h).max() <= 7 and np.abs(J).max() <= 7 and n <= 45


def integer_program_reference(q, n, limits):
    """The group programs' mapping rule in integers (the oracle): the Ising model of ``q`` times 4, scaled so
    that max |h| reaches limits[0] or max |J| limits[1] (each at least 1), rounded half away from zero."""
    q = np.asarray(q[:n, :n], dtype=np.int64)
    h4 = 2 * np.diag(q).copy()
    for i in range(n):
        for j in range(i + 1, n):
            h4[i] += q[i, j]
            h4[j] += q[i, j]
    top_h = max(1, int(np.abs(h4).max(initial=0)))
    top_j = max(1, int(np.abs(np.triu(q, 1)).max(initial=0)))
    s = min(limits[0] / top_h, limits[1] / top_j)
    half_away = lambda x: np.sign(x) * np.floor(np.abs(x) * s + 0.5)
    return half_away(h4).astype(np.int64), np.triu(half_away(q), 1).astype(np.int64)


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 45), st.sampled_from([(7, 7), (15, 15), (7, 3), (1, 1)]),
       st.integers(1, 6))
def test_integer_program_is_the_integer_rule_bit_for_bit(seed, n, limits, digits):
    """ising_backend.integer_program (the one QUBO-to-Ising, then scaled and rounded) gives the integer
    rule's bits: no double rounding on the way through the float model."""
    rng = np.random.default_rng(seed)
    q = np.triu(rng.integers(-10**digits, 10**digits, (n + 2, n + 2)))
    h, J = np.full(n + 2, 99, dtype=np.int64), np.full((n + 2, n + 2), 99, dtype=np.int64)
    integer_program(q, n, h[:n], J[:n, :n], limits)
    rh, rJ = integer_program_reference(q, n, limits)
    assert np.array_equal(h[:n], rh) and np.array_equal(J[:n, :n], rJ)


def test_decode_always_gives_feasible_choices_even_from_random_spins():
    rng = np.random.default_rng(0)
    for pos, ostart, opt, host in sampled_groups(seeds=range(2)):
        size, n = len(pos), int(ostart[-1])
        spins = rng.choice(np.array([-1, 1], dtype=np.int8), (16, n))
        choice = np.empty(size, dtype=np.int64)
        stats = np.zeros(2, dtype=np.int64)
        e = decode_reads(pos, np.arange(size), 0, size, ostart, opt, host, spins, choice, stats)
        feasible = dict(brute(pos, ostart, opt)) if np.prod(np.diff(ostart)) <= 4000 else None
        cells = opt[ostart[:-1] + choice, CELL]
        assert len(set(cells.tolist())) == size
        assert e <= objective(0, size, ostart, opt, host)
        if feasible is not None:
            assert feasible[tuple(choice.tolist())] == e


class RandomMachine:
    """Any sampler in the chip's place: random spins (checks the decode and repair, not the anneal)."""

    def __init__(self):
        from ising_backend import ChipSpec, CallLedger

        self.spec, self.ledger, self.last_call, self.usable_spins = ChipSpec(), CallLedger(), CallLedger(), 45
        self.rng = np.random.default_rng(1)

    def anneal_batch(self, h, J, num_reads=1, seed=None):
        assert h.shape[1] <= 45 and np.abs(h).max() <= 7 and np.abs(J).max() <= 7
        s = self.rng.choice(np.array([-1, 1], dtype=np.int8), (h.shape[0], num_reads, h.shape[1]))
        return s, np.zeros(s.shape[:2])


@pytest.mark.parametrize("machine", ["chip", "random"])
def test_executor_joint_actions_always_valid(machine):
    for s in range(3):
        grid, pos, orient, goals = crowd(10 + s, fill=0.7)
        m = RandomMachine() if machine == "random" else None
        ex = JointMovesPIBT(grid, seed=s, machine=m, accept="chip")
        for _ in range(25):
            act = ex.actions(pos, orient, goals)
            pos, orient = check_valid(grid, pos, orient, act)
        assert ex.machine_step.decisions > 0


def test_deterministic_and_charged():
    runs = []
    for _ in range(2):
        grid, pos, orient, goals = crowd(3, fill=0.7)
        ex = make_turning_planner("pibt-ising", grid, seed=5)
        acts = []
        for _ in range(15):
            act = ex.actions(pos, orient, goals)
            acts.append(act)
            pos, orient = check_valid(grid, pos, orient, act)
        runs.append(np.array(acts))
        assert ex.machine_step.ledger.physical_calls == ex.machine.ledger.physical_calls > 0
        assert ex.last_compute.chip_calls in (0, ex.machine.last_call.physical_calls)
    assert np.array_equal(runs[0], runs[1])
    assert ex.kind is TURNING_PLANNERS["pibt-ising"] and isinstance(ex.machine_step, JointMovesStep)


@pytest.mark.parametrize("kw, word", [({"max_robots": 0}, "max_robots"), ({"levels": 9}, "levels"),
                                      ({"num_reads": 0}, "num_reads"), ({"accept": "maybe"}, "accept"),
                                      ({"max_spins": 46}, "max_spins"), ({"penalty": 0}, "penalty"), ({"push": 3}, "push"),
                                      ({"machine": object()}, "anneal_batch")])
def test_bad_options_named(kw, word):
    with pytest.raises(ValueError, match=word):
        JointMovesPIBT(np.zeros((4, 4), dtype=bool), **kw)


def test_host_rule_flag_keeps_pibts_answer_without_a_chip_call():
    from ising_backend.audit.host_rule import HostRule

    grid, pos, orient, goals = crowd(6, fill=0.7)
    host = JointMovesPIBT(grid, seed=2, accept="host")  # the chip runs, PIBT's answer is kept
    flagged = JointMovesPIBT(grid, seed=2)
    p2, o2 = pos.copy(), orient.copy()
    for _ in range(12):
        a1 = host.actions(pos, orient, goals)
        with HostRule("joint_moves"):
            a2 = flagged.actions(p2, o2, goals)
        assert np.array_equal(a1, a2)
        pos, orient = check_valid(grid, pos, orient, a1)
        p2, o2 = check_valid(grid, p2, o2, a2)
    assert host.machine_step.ledger.physical_calls > 0 and host.machine_step.decisions > 0
    step = flagged.machine_step
    assert flagged.machine.ledger.physical_calls == step.ledger.physical_calls == step.decisions == 0
