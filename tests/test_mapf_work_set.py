"""``epibt-chain-work`` (planners/mapf/chip/work_set.py): who of the robots at work stays, decided on a machine or by
the host rule; the meeting pairs and the programs against brute force, the twin against ``epibt-chain``, the
decisions against the goals they change, the charges against the machine's ledger, and the audit."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from ising_backend import CallLedger, EmulatedChip
from planners.mapf import TURNING_EXECUTORS, ChainEPIBT, WorkChainEPIBT
from planners.mapf.chip.work_set import conflict_pairs, keep_values, pack_programs
from planners.mapf.common import compact_grid
from test_mapf_epibt_chain_ising import audited_twice
from test_mapf_turning import apply, random_instance, retarget

DENSE = {"active": 0.8, "lns": 300}


def world(seed, size=10, fill=0.8):
    rng = np.random.default_rng(seed)
    return rng, random_instance(rng, size, size, 0.1, fill)


def pairs_by_brute_force(nbr, pc, down, head_on, shared):
    """The meeting pairs, one pair of robots at a time."""
    out = {}
    for i, j in itertools.combinations(range(len(pc)), 2):
        wi = {nbr[pc[i], d] for d in range(4) if down[i, d] and nbr[pc[i], d] >= 0}
        wj = {nbr[pc[j], d] for d in range(4) if down[j, d] and nbr[pc[j], d] >= 0}
        w = head_on * (pc[j] in wi and pc[i] in wj) + shared * len(wi & wj)
        if w:
            out[(i, j)] = w
    return out


@pytest.mark.parametrize("seed", range(6))
def test_meeting_pairs_equal_brute_force(seed):
    rng = np.random.default_rng(seed)
    grid = rng.random((7, 8)) < 0.15
    _, _, nbr = compact_grid(grid)
    m = min(20, nbr.shape[0])
    pc = rng.choice(nbr.shape[0], size=m, replace=False).astype(np.int64)
    down = rng.random((m, 4)) < 0.5
    for head_on, shared in ((8, 4), (3, 0), (0, 5)):
        a, b, c = conflict_pairs(nbr, pc, down, head_on, shared)
        assert dict(zip(zip(a.tolist(), b.tolist()), c.tolist())) == pairs_by_brute_force(nbr, pc, down, head_on,
                                                                                            shared)
        assert list(zip(a.tolist(), b.tolist())) == sorted(zip(a.tolist(), b.tolist()))


@pytest.mark.parametrize("spins", [2, 3, 5, 45])
def test_programs_hold_each_paired_robot_once_within_the_spins(spins):
    rng = np.random.default_rng(spins)
    m = 30
    e = {tuple(sorted(rng.choice(m, 2, replace=False).tolist())) for _ in range(25)}
    a = np.array([x for x, _ in sorted(e)], dtype=np.int64)
    b = np.array([y for _, y in sorted(e)], dtype=np.int64)
    programs, cut = pack_programs(m, a, b, spins)
    placed = [k for p in programs for k in p]
    assert sorted(placed) == sorted(set(a.tolist()) | set(b.tolist()))  # each paired robot once, no other
    assert all(1 <= len(p) <= spins for p in programs)
    where = {k: g for g, p in enumerate(programs) for k in p}
    assert cut == sum(where[x] != where[y] for x, y in zip(a.tolist(), b.tolist()))
    if spins == 45:
        assert cut == 0 and len(programs) == 1


def test_a_component_that_fits_is_never_split():
    a = np.array([0, 1, 4, 6], dtype=np.int64)
    b = np.array([1, 2, 5, 7], dtype=np.int64)
    programs, cut = pack_programs(8, a, b, 4)
    assert cut == 0
    assert programs == [[0, 1, 2], [4, 5, 6, 7]]


def _optimum(u, a, b, c):
    best = None
    for bits in itertools.product((0, 1), repeat=len(u)):
        x = np.array(bits)
        e = -(u * x).sum() + sum(w * x[i] * x[j] for i, j, w in zip(a, b, c))
        if best is None or e < best[0]:
            best = (e, bits)
    return best[1]


@pytest.mark.parametrize("seed", range(8))
def test_the_keep_values_bound_leaves_the_optimum_as_it_is(seed):
    rng = np.random.default_rng(seed)
    m = 7
    way = rng.integers(0, 40, m)
    e = sorted({tuple(sorted(rng.choice(m, 2, replace=False).tolist())) for _ in range(6)})
    a, b = np.array([x for x, _ in e]), np.array([y for _, y in e])
    c = rng.integers(1, 12, len(e))
    u = keep_values(way, a, b, c)
    assert (u >= 1).all()
    raw = 1 + way.max() - way
    assert _optimum(u, a, b, c) == _optimum(raw, a, b, c)


def test_the_host_twin_plans_as_epibt_chain():
    """``decider="host"`` keeps the host rule's robots at work: step for step the actions of ``epibt-chain`` with the
    same options, and no machine built."""
    rng, (grid, free, pos, orient, goals) = world(5)
    twin = WorkChainEPIBT(grid, seed=2, decider="host", **DENSE)
    base = ChainEPIBT(grid, seed=2, **DENSE)
    assert twin.machine is None
    for step in range(12):
        act = twin.actions(pos, orient, goals)
        assert np.array_equal(act, base.actions(pos, orient, goals)), f"step {step}"
        pos, orient, err = apply(grid, pos, orient, act)
        assert err is None
        goals = retarget(rng, free, pos, goals)
    assert twin.stats["pairs"] > 0 and twin.stats["decisions"] == twin.stats["taken_off"] == 0


def test_robots_taken_off_are_counted_charged_and_kept_off_their_goals():
    """The robots the machine takes off are exactly those the host rule kept at work and the chip's steer sends to
    their own cells (counted apart), every call is in the machine's ledger, and each program costs its reads."""
    rng, (grid, free, pos, orient, goals) = world(6, fill=0.85)
    chip = EmulatedChip(seed=3)
    ex = TURNING_EXECUTORS["epibt-chain-work"](grid, seed=2, machine=chip, num_reads=8, **DENSE)
    host = WorkChainEPIBT(grid, seed=2, decider="host", **DENSE)
    off = decisions = 0
    for step in range(15):
        before = (chip.ledger.physical_calls, ex.stats["decisions"])
        mine, theirs = ex.steer(pos, goals), host.steer(pos, goals)
        off += int(((mine == pos) & (theirs != pos)).sum())
        assert ((mine != pos) <= (theirs != pos)).all()  # nobody put to work the host rule left off
        assert ex.last_compute.chip_calls == chip.ledger.physical_calls - before[0]
        assert ex.last_compute.chip_calls == 8 * (ex.stats["decisions"] - before[1])
        decisions += ex.stats["decisions"] - before[1]
        act = ex.actions(pos, orient, goals)
        pos, orient, err = apply(grid, pos, orient, act)
        assert err is None
        goals = retarget(rng, free, pos, goals)
    assert off == ex.stats["taken_off"] // 2 > 0  # steer ran twice a step: once here, once in actions
    assert ex.ledger.physical_calls == chip.ledger.physical_calls == 8 * ex.stats["decisions"] > 0


def test_a_head_on_pair_loses_the_robot_nearer_the_host_rules_last():
    """Two robots at work facing each other in a corridor, the rest none: the machine takes off the one of longer
    way (keeping it is worth less than the pair costs), the other keeps its goal."""
    grid = np.ones((3, 9), dtype=bool)
    grid[1, :] = False
    w = 9
    pos = np.array([w + 3, w + 4], dtype=np.int64)
    goals = np.array([w + 8, w + 1], dtype=np.int64)  # robot 0 heads east 5 cells, robot 1 west 3
    ex = WorkChainEPIBT(grid, seed=1, machine=EmulatedChip(seed=2), head_on=20, shared=0, guidance=0)
    out = ex.steer(pos, goals)
    assert out.tolist() == [pos[0], goals[1]]
    assert ex.stats["taken_off"] == 1 and ex.stats["decisions"] == 1 and ex.stats["pairs"] == 1


def test_host_rule_flag_is_the_twin_without_a_call():
    from ising_backend.audit.host_rule import HostRule

    rng, (grid, free, pos, orient, goals) = world(8)
    twin = WorkChainEPIBT(grid, seed=2, decider="host", **DENSE)
    chip = EmulatedChip(seed=3)
    flagged = WorkChainEPIBT(grid, seed=2, machine=chip, **DENSE)
    for _ in range(8):
        a1 = twin.actions(pos, orient, goals)
        with HostRule("work_set"):
            a2 = flagged.actions(pos, orient, goals)
        assert np.array_equal(a1, a2)
        pos, orient, err = apply(grid, pos, orient, a1)
        assert err is None
        goals = retarget(rng, free, pos, goals)
    assert flagged.stats["pairs"] == twin.stats["pairs"] > 0
    assert chip.ledger.physical_calls == flagged.ledger.physical_calls == 0 and twin.ledger == CallLedger()


def test_the_audit_records_every_program_and_changes_no_action(tmp_path):
    audited_twice(lambda grid: WorkChainEPIBT(grid, seed=3, **DENSE), world(4, fill=0.85)[1], tmp_path / "audit",
                  "work_set")


def test_same_seed_same_plans_and_bad_options_are_named():
    rng, (grid, free, pos, orient, goals) = world(9, size=8)
    runs = [WorkChainEPIBT(grid, seed=1, **DENSE).actions(pos, orient, goals).tolist() for _ in range(2)]
    assert runs[0] == runs[1]
    for opts, word in (({"decider": "gpu"}, "decider"), ({"head_on": -1}, "head_on"), ({"shared": 1001}, "shared"),
                       ({"num_reads": 0}, "num_reads")):
        with pytest.raises(ValueError, match=word):
            WorkChainEPIBT(grid, **opts)
