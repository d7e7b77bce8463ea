"""EPIBT's neighbourhood groups decided jointly (``epibt-ising``): groups, QUBO, host rule and decoding against
brute force, plans conflict-free at every time, charges against the machine's ledger."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from ising_backend import CallLedger, EmulatedChip
from planners.mapf import make_turning_planner
from planners.mapf.common import GroupBatch, mix
from ising_backend import integer_program
from planners.mapf.chip.group_kernels import (NO_CHOICE, GroupShape, decode_choices, group_programs, group_qubo, host_choices,
                                              select_groups)
from test_mapf_epibt import plan_conflicts
from test_mapf_turning import apply, random_instance, retarget


def EPIBT(grid, seed=0, **options):
    """EPIBT (the planner ``epibt``) on ``grid``."""
    return make_turning_planner("epibt", grid, seed=seed, **options)


def EPIBTIsing(grid, seed=0, machine=None, **options):
    """``epibt-ising`` on ``grid`` (``machine`` default: the paper's emulated chip)."""
    return make_turning_planner("epibt-ising", grid, seed=seed, machine=machine, **options)


class Capture:
    """A machine step that keeps a copy of each call's plan state and reservation table (and changes nothing)."""

    def improve(self, decider, state, deadline):
        self.captured = (type(state)(*(a.copy() for a in state)), decider.res.copy())


def collide(p, q):
    return any(p[t] == q[t] or (p[t] != p[t - 1] and p[t] == q[t - 1] and q[t] == p[t - 1]) for t in range(1, len(p)))


def captured_states(seed, steps=8):
    rng = np.random.default_rng(seed)
    grid, free, pos, orient, goals = random_instance(rng, 9, 9, 0.12, 0.7)
    ex = EPIBT(grid, seed=seed, lns=0)
    capture = ex.decider.machine_step = Capture()
    for _ in range(steps):
        act = ex.actions(pos, orient, goals)
        yield capture.captured
        pos, orient, _ = apply(grid, pos, orient, act)
        goals = retarget(rng, free, pos, goals)


def groups_of(state, res, seed=0, t=0, limits=(8, 6, 4, 45)):
    r = len(state.ncand)
    members, gstart = np.empty(r, np.int64), np.empty(limits[0] + 1, np.int64)
    ostart, opt = np.empty(r + 1, np.int64), np.empty(r * limits[2], np.int64)
    ng = select_groups(state, res, GroupShape(*limits), (seed, t), np.zeros(r, np.int8),
                       GroupBatch(0, gstart, members, ostart, opt), np.ones(r, np.int8))
    return ng, members, gstart, ostart, opt


def path(state, q, c):
    return tuple(state.cells[q, c]) if c >= 0 else tuple(state.inh[q])


def cost(state, q, c):
    return int(state.costs[q, c]) if c >= 0 else int(state.inh_cost[q])


@pytest.mark.parametrize("seed", range(4))
def test_groups_are_disjoint_and_their_options_collide_with_no_outsider(seed):
    seen = 0
    for state, res in captured_states(seed):
        res0 = res.copy()
        ng, members, gstart, ostart, opt = groups_of(state, res, seed)
        assert np.array_equal(res, res0)  # the table is left as found
        cur, src = state.cur, state.src
        r = len(src)
        inside = members[:gstart[ng]]
        assert len(set(inside.tolist())) == len(inside)
        for g in range(ng):
            a, b = gstart[g], gstart[g + 1]
            assert 2 <= b - a <= 6 and ostart[b] - ostart[a] - (b - a) <= 45  # a spin per option besides option 0
            group = set(members[a:b].tolist())
            assert src[members[a]] != 0  # the seed robot is not on its best operation
            for i in range(a, b):
                q = members[i]
                assert opt[ostart[i]] == src[q] and 1 <= ostart[i + 1] - ostart[i] <= 4
                for c in opt[ostart[i] + 1:ostart[i + 1]]:
                    assert not any(collide(path(state, q, c), tuple(cur[o])) for o in range(r) if o not in group)
            seen += 1
    assert seen > 0


def brute(state, members, a, b, ostart, opt):
    """Least cost over every collision-free choice of the group (None when there is none)."""
    best = None
    sizes = [range(ostart[i + 1] - ostart[i]) for i in range(a, b)]
    for choice in itertools.product(*sizes):
        paths = [path(state, members[a + i], opt[ostart[a + i] + c]) for i, c in enumerate(choice)]
        if any(collide(p, q) for p, q in itertools.combinations(paths, 2)):
            continue
        total = sum(cost(state, members[a + i], opt[ostart[a + i] + c]) for i, c in enumerate(choice))
        best = total if best is None else min(best, total)
    return best


@pytest.mark.parametrize("sign", [1, -1])  # -1: costs below zero, as the push chains' are (their gains' negatives)
@pytest.mark.parametrize("seed", range(3))
def test_qubo_ranks_choices_by_cost_host_rule_and_decoding_match_python(seed, sign):
    checked = 0
    for t, (state, res) in enumerate(captured_states(seed, steps=5)):
        state = state._replace(costs=sign * state.costs, inh_cost=sign * state.inh_cost)
        ng, members, gstart, ostart, opt = groups_of(state, res, seed, t, limits=(4, 4, 3, 45))
        batch = GroupBatch(ng, gstart, members, ostart, opt)
        host_choice, host_cost = np.zeros(gstart[ng], np.int64), np.empty(ng, np.int64)
        host_choices(state, batch, (seed, t), host_choice, host_cost)
        for g in range(ng):
            a, b = gstart[g], gstart[g + 1]
            n = ostart[b] - ostart[a] - (b - a)  # a spin per option besides the operation now
            if n > 12:
                continue
            weight = 1 + (g % 2)
            q = np.empty((n, n), np.int64)
            assert group_qubo(state, members, a, b, ostart, opt, q, weight) == n
            # every choice with at most one spin up per robot (option 0, the operation now: none up): energy = its
            # cost above the plan now + a penalty per colliding pair (half the at-most-one penalty, which is
            # weight x (1 + the widest gap of one option's cost to its robot's operation now); the decoder rejects
            # colliding reads, so the ranking need only hold among collision-free ones)
            now = [cost(state, members[i], opt[ostart[i]]) for i in range(a, b)]
            amo = weight * (1 + max(abs(cost(state, members[i], opt[x]) - now[i - a]) for i in range(a, b)
                                    for x in range(ostart[i] + 1, ostart[i + 1])))
            pen = (amo + 1) // 2
            costs = {}
            first = [ostart[i] - ostart[a] - (i - a) for i in range(a, b)]  # robot slot's first spin
            for choice in itertools.product(*[range(ostart[i + 1] - ostart[i]) for i in range(a, b)]):
                x = np.zeros(n, np.int64)
                for i, c in zip(range(a, b), choice):
                    if c:
                        x[first[i - a] + c - 1] = 1
                paths = [path(state, members[i], opt[ostart[i] + c]) for i, c in zip(range(a, b), choice)]
                clashes = sum(collide(p, r) for p, r in itertools.combinations(paths, 2))
                total = sum(cost(state, members[i], opt[ostart[i] + c]) for i, c in zip(range(a, b), choice))
                assert int(x @ np.triu(q) @ x) == total - sum(now) + pen * clashes
                if not clashes:
                    costs[choice] = total
                # two spins of one robot up costs the at-most-one penalty on top (their pair's coupling)
                for i, c in zip(range(a, b), choice):
                    if c and c + 1 < ostart[i + 1] - ostart[i]:
                        assert q[first[i - a] + c - 1, first[i - a] + c] == amo
            assert min(costs.values()) == brute(state, members, a, b, ostart, opt)
            # the host rule: a seeded order, each robot its cheapest option colliding with none placed before
            order = sorted(range(b - a), key=lambda i: int(mix(seed, t, g, members[a + i])))
            placed, total = {}, 0
            for i in order:
                q_ = members[a + i]
                ok = [x for x in range(ostart[a + i], ostart[a + i + 1])
                      if not any(collide(path(state, q_, opt[x]), path(state, members[a + j], opt[ostart[a + j] + c]))
                                 for j, c in placed.items())]
                if not ok:
                    total = NO_CHOICE
                    break
                x = min(ok, key=lambda x: (cost(state, q_, opt[x]), x))
                placed[i] = x - ostart[a + i]
                total += cost(state, q_, opt[x])
            assert host_cost[g] == total
            if total != NO_CHOICE:
                assert all(host_choice[a + i] == c for i, c in placed.items())
            # decoding: the cheapest collision-free read, a robot with no spin up or more than one on its plan now
            rng = np.random.default_rng(g)
            spins = np.where(rng.random((6, n)) < 0.3, 1, -1).astype(np.int8)
            spins[0] = -1  # the plan now: always a valid read

            def read_choice(s):
                out = []
                for i in range(a, b):
                    up = np.flatnonzero(s[first[i - a]:first[i - a] + ostart[i + 1] - ostart[i] - 1] > 0)
                    out.append(int(up[0]) + 1 if len(up) == 1 else 0)
                return tuple(out)

            reads = [read_choice(s) for s in spins]
            want = min(costs.get(r, 1 << 62) for r in reads)
            one = GroupBatch(1, gstart[g:g + 2], members, ostart, opt)  # group g alone
            chosen, got = np.zeros(b, np.int64), np.empty(1, np.int64)
            decode_choices(state, one, spins[None], chosen, got)
            assert got[0] == want and costs[tuple(chosen[a:b].tolist())] == want
            none_up = np.zeros(b, np.int64) - 1  # a read with no spin up decodes to the plan now
            plan_now = sum(cost(state, members[i], opt[ostart[i]]) for i in range(a, b))
            decode_choices(state, one, np.full((1, 1, n), -1, np.int8), none_up, got)
            assert got[0] == plan_now and (none_up[a:b] == 0).all()
            checked += 1
    assert checked > 0


@pytest.mark.parametrize("seed", range(2))
def test_a_rounds_programs_in_one_call_are_each_groups_program(seed):
    for t, (state, res) in enumerate(captured_states(seed, steps=4)):
        ng, members, gstart, ostart, opt = groups_of(state, res, seed, t)
        if ng == 0:
            continue
        n = int(max(ostart[gstart[g + 1]] - ostart[gstart[g]] - (gstart[g + 1] - gstart[g]) for g in range(ng)))
        H, J = np.full((ng, n), 99, np.int64), np.full((ng, n, n), 99, np.int64)
        group_programs(state, GroupBatch(ng, gstart, members, ostart, opt), 2, (7, 7), H, J)
        for g in range(ng):
            a, b = gstart[g], gstart[g + 1]
            q, h1, J1 = np.empty((n, n), np.int64), np.zeros(n, np.int64), np.zeros((n, n), np.int64)
            k = group_qubo(state, members, a, b, ostart, opt, q, 2)
            integer_program(q, k, h1[:k], J1[:k, :k], (7, 7))
            assert np.array_equal(H[g], h1) and np.array_equal(J[g], J1)  # zero past the group's spins


@pytest.mark.parametrize("decider", ["chip", "host"])
def test_plans_stay_conflict_free_and_charges_equal_the_ledger(decider):
    rng = np.random.default_rng(5)
    grid, free, pos, orient, goals = random_instance(rng, 10, 10, 0.12, 0.6)
    chip = EmulatedChip(seed=3)
    ex = make_turning_planner("epibt-ising", grid, seed=2, machine=chip, decider=decider, lns=0, groups=8)
    calls = 0
    for step in range(40):
        before = chip.ledger.physical_calls if decider == "chip" else 0
        act = ex.actions(pos, orient, goals)
        assert plan_conflicts(grid, pos, orient, ex.decider.plans) == [], f"step {step}"
        if decider == "chip":
            assert ex.last_compute.chip_calls == chip.ledger.physical_calls - before
            calls += ex.last_compute.chip_calls
        pos, orient, err = apply(grid, pos, orient, act)
        assert err is None
        goals = retarget(rng, free, pos, goals)
    assert ex.machine_step.stats["decisions"] > 0
    if decider == "chip":
        assert calls == ex.machine_step.ledger.physical_calls == chip.ledger.physical_calls > 0
    else:
        assert ex.machine is None and ex.machine_step.ledger == CallLedger()


@pytest.mark.parametrize("name", ["epibt-ising", "pibt-ising"])
@pytest.mark.parametrize("limit", [3, 15])
def test_programs_take_the_machines_own_coefficient_range(name, limit):
    """The mapping scales each program to the machine's ``spec.coefficient_limits`` (a chip of 3 levels is not
    sent the paper chip's 7; a chip of 15 gets its 15)."""
    from ising_backend import ChipSpec

    tops = []

    class Recording(EmulatedChip):
        def anneal_batch(self, h, J, num_reads=1, seed=None):
            tops.append((int(np.abs(h).max()), int(np.abs(J).max())))
            return super().anneal_batch(h, J, num_reads=num_reads, seed=seed)

    rng = np.random.default_rng(5)
    grid, free, pos, orient, goals = random_instance(rng, 10, 10, 0.12, 0.6)
    chip = Recording(spec=ChipSpec(h_range=(-limit, limit), j_range=(-limit, limit)), seed=3)
    opts = {"lns": 0, "groups": 8} if name == "epibt-ising" else {}
    ex = make_turning_planner(name, grid, seed=2, machine=chip, **opts)
    for _ in range(15):
        act = ex.actions(pos, orient, goals)
        pos, orient, err = apply(grid, pos, orient, act)
        assert err is None
        goals = retarget(rng, free, pos, goals)
    assert tops and all(max(t) == limit for t in tops)


@pytest.mark.parametrize("decider", ["chip", "host"])
def test_min_gain_holds_back_small_gains(decider):
    """A group takes its choice only when it saves at least ``min_gain``: with a gain no group reaches the plans are
    EPIBT's own; with the default some groups apply and every applied one saved at least 1."""
    rng = np.random.default_rng(5)
    grid, free, pos, orient, goals = random_instance(rng, 10, 10, 0.12, 0.6)
    plain = EPIBT(grid, seed=2, lns=0)
    held = EPIBTIsing(grid, seed=2, lns=0, decider=decider, groups=8, min_gain=1000)
    free_ = EPIBTIsing(grid, seed=2, lns=0, decider=decider, groups=8)
    for _ in range(20):
        act = plain.actions(pos, orient, goals)
        assert np.array_equal(held.actions(pos, orient, goals), act)
        free_.actions(pos, orient, goals)
        pos, orient, err = apply(grid, pos, orient, act)
        assert err is None
        goals = retarget(rng, free, pos, goals)
    held_stats = held.machine_step.stats
    assert held_stats["decisions"] > 0 and held_stats["applied"] == 0 and free_.machine_step.stats["applied"] > 0


def test_same_seed_same_plans_and_bad_options():
    rng = np.random.default_rng(9)
    grid, free, pos, orient, goals = random_instance(rng, 8, 8, 0.1, 0.6)
    runs = [[EPIBTIsing(grid, seed=1, lns=0).actions(pos, orient, goals).tolist() for _ in range(1)] for _ in range(2)]
    assert runs[0] == runs[1]
    for opts, word in (({"decider": "gpu"}, "decider"), ({"max_robots": 1}, "max_robots"),
                       ({"max_options": 9}, "max_options"), ({"num_reads": 0}, "num_reads"), ({"groups": -1}, "groups"),
                       ({"penalty": 0}, "penalty"), ({"min_gain": 0}, "min_gain")):
        with pytest.raises(ValueError, match=word):
            EPIBTIsing(grid, **opts)


def test_the_audit_records_every_decision_and_changes_no_action(tmp_path):
    from ising_backend.audit.record import Audit, read_records
    from ising_backend.audit.judge import judge

    rng = np.random.default_rng(4)
    grid, free, pos, orient, goals = random_instance(rng, 10, 10, 0.12, 0.6)
    runs = []
    for audit in (None, tmp_path / "audit"):
        ex = EPIBTIsing(grid, seed=3, lns=0, groups=6)
        p, o, g, acts = pos.copy(), orient.copy(), goals.copy(), []
        r2 = np.random.default_rng(1)
        ctx = Audit(audit) if audit else None
        if ctx:
            ctx.__enter__()
        try:
            for _ in range(15):
                a = ex.actions(p, o, g)
                acts.append(a.tolist())
                p, o, _ = apply(grid, p, o, a)
                g = retarget(r2, free, p, g)
        finally:
            if ctx:
                ctx.__exit__(None, None, None)
        runs.append((acts, ex.machine_step.stats["decisions"], ex.machine_step.ledger.physical_calls))
    assert runs[0] == runs[1]
    records = read_records(tmp_path / "audit")
    assert {r["class"] for r in records} == {"lns_groups"}
    assert len(records) == runs[1][1] > 0  # one program per decision
    assert sum(r["calls"] for r in records) == runs[1][2]  # charges summed = the ledger
    rows = judge(records)
    assert len(rows) == len(records) and all(r["host_rule"] == "greedy" for r in rows)


def test_host_rule_flag_takes_the_searchs_greedy_without_a_chip_call():
    from ising_backend.audit.host_rule import HostRule

    rng = np.random.default_rng(8)
    grid, free, pos, orient, goals = random_instance(rng, 10, 10, 0.12, 0.6)
    host = EPIBTIsing(grid, seed=2, decider="host", lns=0, groups=8)
    chip = EmulatedChip(seed=3)
    flagged = EPIBTIsing(grid, seed=2, machine=chip, lns=0, groups=8)
    for _ in range(15):
        a1 = host.actions(pos, orient, goals)
        with HostRule("all"):
            a2 = flagged.actions(pos, orient, goals)
        assert np.array_equal(a1, a2)
        pos, orient, err = apply(grid, pos, orient, a1)
        assert err is None
        goals = retarget(rng, free, pos, goals)
    assert flagged.machine_step.stats["decisions"] == host.machine_step.stats["decisions"] > 0
    assert flagged.machine_step.stats["applied"] == host.machine_step.stats["applied"] > 0
    assert chip.ledger.physical_calls == flagged.machine_step.ledger.physical_calls == 0


@pytest.mark.parametrize("decider", ["chip", "host"])
def test_rounds_pose_fresh_groups_on_the_plan_the_rounds_before_left(decider, monkeypatch):
    """``rounds=k``: the first round is the single round's (same groups, same plan when no later round applies);
    a later round's groups are not the ones the first round's seed would pose on the same plan; the chip's calls
    equal the ledger's over every round; the plans stay conflict-free; the cost-to-go of the joint plan never
    rises from one round to the next."""
    import planners.mapf.chip.group_rounds as mod

    rng = np.random.default_rng(5)
    grid, free, pos, orient, goals = random_instance(rng, 10, 10, 0.12, 0.6)
    chip = EmulatedChip(seed=3)
    costs = []
    posed = []
    real = mod.select_groups

    def recording(state, res, limits, stamp, taken, out, seeds):
        ng = real(state, res, limits, stamp, taken, out, seeds)
        posed.append(out.members[:out.gstart[ng]].tolist())
        return ng

    monkeypatch.setattr(mod, "select_groups", recording)
    fresh = []

    one = EPIBTIsing(grid, seed=2, machine=EmulatedChip(seed=3), decider=decider, lns=0, groups=4)
    many = EPIBTIsing(grid, seed=2, machine=chip, decider=decider, lns=0, groups=4, rounds=6)
    rounds = many.machine_step.rounds_
    inner = rounds.round

    def costed(state, res, when, seeds):
        k = when[1]
        if k > 0:
            lim = rounds.limits
            same = groups_of(state, res.copy(), seed=many.prio.seed, t=many.prio.t,
                             limits=(lim.groups, lim.max_robots, lim.max_options, lim.max_spins))
            n = len(posed)
        call = inner(state, res, when, seeds)
        if k > 0:
            fresh.append(posed[n] != same[1][:same[2][same[0]]].tolist())
        costs.append((k, sum(cost(state, q, c) for q, c in enumerate(state.src.tolist()))))
        return call

    rounds.round = costed
    for step in range(25):
        first = one.actions(pos, orient, goals)
        before = chip.ledger.physical_calls
        act = many.actions(pos, orient, goals)
        assert plan_conflicts(grid, pos, orient, many.decider.plans) == [], f"step {step}"
        if decider == "chip":
            assert many.last_compute.chip_calls == chip.ledger.physical_calls - before
        if step == 0:
            assert costs[0][0] == 0 and many.machine_step.stats["decisions"] >= one.machine_step.stats["decisions"]
        pos, orient, err = apply(grid, pos, orient, first)
        assert err is None
        goals = retarget(rng, free, pos, goals)
        many.decider.inherited[:] = 3  # both start each step from the same state: the single round's walk
        many.decider._expect = (np.zeros(0, np.int64), np.zeros(0, np.int64))
        one.decider._expect = many.decider._expect
    run = [c for k, c in costs]
    ks = [k for k, c in costs]
    assert many.machine_step.stats["rounds"] == len(costs) > 25 and max(ks) == 5
    for i in range(1, len(costs)):
        if ks[i] > 0:
            assert run[i] <= run[i - 1], (i, run[i - 1], run[i])
    assert many.machine_step.stats["applied"] > one.machine_step.stats["applied"] and any(fresh)
    if decider == "chip":
        assert many.machine_step.ledger.physical_calls == chip.ledger.physical_calls \
            > one.machine_step.ledger.physical_calls


def test_rounds_stop_at_the_deadline_and_bad_rounds_are_named():
    import time

    rng = np.random.default_rng(5)
    grid, free, pos, orient, goals = random_instance(rng, 10, 10, 0.12, 0.6)
    ex = EPIBTIsing(grid, seed=2, lns=0, groups=4, rounds=50, decider="host")
    ex.actions(pos, orient, goals, deadline=time.perf_counter() - 1.0)
    assert ex.machine_step.stats["rounds"] == 1  # the first round always runs
    ex.actions(pos, orient, goals)
    assert ex.machine_step.stats["rounds"] > 2
    for bad in (0, 4097, 1.5, True):
        with pytest.raises(ValueError, match=f"rounds .*{bad!r}"):
            EPIBTIsing(grid, rounds=bad)
