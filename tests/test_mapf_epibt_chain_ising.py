"""``epibt-chain-ising`` (planners/mapf/chip/chain_ising.py): the chain plan's groups decided on a machine or by the
host rule; plans conflict-free, scores recounted, charges against the machine's ledger, the twin and the audit."""

from __future__ import annotations

import numpy as np
import pytest

from ising_backend import CallLedger, EmulatedChip
from planners.mapf import make_turning_planner
from test_mapf_epibt import plan_conflicts
from test_mapf_turning import apply, random_instance, retarget


def ChainEPIBT(grid, seed=0, **options):
    """EPIBT by push chains (the planner ``epibt-chain``) on ``grid``."""
    return make_turning_planner("epibt-chain", grid, seed=seed, **options)


def ChainEPIBTIsing(grid, seed=0, machine=None, **options):
    """``epibt-chain-ising`` on ``grid`` (``machine`` default: the paper's emulated chip)."""
    return make_turning_planner("epibt-chain-ising", grid, seed=seed, machine=machine, **options)


def world(seed, size=10, fill=0.75):
    rng = np.random.default_rng(seed)
    return rng, random_instance(rng, size, size, 0.1, fill)


@pytest.mark.parametrize("decider", ["chip", "host"])
def test_rounds_raise_the_chain_plan_conflict_free_and_charges_equal_the_ledger(decider):
    """From the same construction (``lns=0``) the rounds never lower the plan's score, taken groups raise it, the
    plans stay conflict-free at all five times, and every machine call is in the ledger."""
    rng, (grid, free, pos, orient, goals) = world(5)
    chip = EmulatedChip(seed=3)
    base = ChainEPIBT(grid, seed=2, lns=0)
    ex = make_turning_planner("epibt-chain-ising", grid, seed=2, machine=chip, decider=decider, groups=8, rounds=4)
    calls = 0
    rose = 0
    for step in range(25):
        before = chip.ledger.physical_calls
        act = ex.actions(pos, orient, goals)
        base.actions(pos, orient, goals)
        assert plan_conflicts(grid, pos, orient, ex.decider.plans) == [], f"step {step}"
        assert ex.decider.portfolio_scores.tolist() == base.decider.portfolio_scores.tolist()  # the same construction
        assert ex.decider.plan_score >= base.decider.plan_score
        rose += ex.decider.plan_score > base.decider.plan_score
        calls += ex.last_compute.chip_calls
        assert ex.last_compute.chip_calls == chip.ledger.physical_calls - before
        pos, orient, err = apply(grid, pos, orient, act)
        assert err is None
        goals = retarget(rng, free, pos, goals)
    assert ex.machine_step.stats["decisions"] > 0 and ex.machine_step.stats["applied"] > 0 and rose > 0
    if decider == "chip":
        assert calls == ex.machine_step.ledger.physical_calls == chip.ledger.physical_calls > 0
    else:
        assert ex.machine is None and ex.machine_step.ledger == CallLedger() and chip.ledger.physical_calls == 0


def test_the_score_is_the_recount_of_the_choices():
    """The score the planner reports equals the score recounted from its plan's operations: the sum over robots of
    power x (value of waiting - value), read from a plain construction's candidates."""
    rng, (grid, free, pos, orient, goals) = world(7, fill=0.8)
    ex = ChainEPIBTIsing(grid, seed=4, decider="host", groups=16, rounds=8)
    seen = []

    rounds = ex.machine_step.improve

    def recount(decider, plan, ranked, deadline):
        rounds(decider, plan, ranked, deadline)
        cand, gain = ranked.cand, ranked.gain
        ops = np.where(plan.choice >= 0, cand.op[np.arange(len(plan.choice)), np.maximum(plan.choice, 0)], -1)
        seen.append((int(plan.score[0]), int(sum(gain[k, c] for k, c in enumerate(plan.choice) if c >= 0)),
                     ops.tolist()))

    ex.machine_step.improve = recount
    for _ in range(6):
        act = ex.actions(pos, orient, goals)
        score, counted, ops = seen[-1]
        assert score == counted == ex.decider.plan_score
        d = ex.decider
        assert [tuple(d.ops[o]) if o >= 0 else (3,) * 5 for o in ops] == [tuple(p) for p in d.plans.tolist()]
        pos, orient, err = apply(grid, pos, orient, act)
        assert err is None
        goals = retarget(rng, free, pos, goals)


def test_host_rule_flag_is_the_host_twin_without_a_chip_call():
    from ising_backend.audit.host_rule import HostRule

    rng, (grid, free, pos, orient, goals) = world(8)
    host = ChainEPIBTIsing(grid, seed=2, decider="host", groups=8, rounds=3)
    chip = EmulatedChip(seed=3)
    flagged = ChainEPIBTIsing(grid, seed=2, machine=chip, groups=8, rounds=3)
    for _ in range(12):
        a1 = host.actions(pos, orient, goals)
        with HostRule("lns_groups"):
            a2 = flagged.actions(pos, orient, goals)
        assert np.array_equal(a1, a2)
        pos, orient, err = apply(grid, pos, orient, a1)
        assert err is None
        goals = retarget(rng, free, pos, goals)
    assert flagged.machine_step.stats["decisions"] == host.machine_step.stats["decisions"] > 0
    assert flagged.machine_step.stats["applied"] == host.machine_step.stats["applied"]
    assert chip.ledger.physical_calls == flagged.machine_step.ledger.physical_calls == 0


def test_only_robots_with_a_goal_start_groups(monkeypatch):
    import planners.mapf.chip.group_rounds as mod

    rng, (grid, free, pos, orient, goals) = world(3, fill=0.8)
    goals = goals.copy()
    goals[::2] = pos[::2]  # every other robot has no goal
    starters = []
    real = mod.select_groups

    def recording(state, res, limits, stamp, taken, out, seeds):
        ng = real(state, res, limits, stamp, taken, out, seeds)
        starters.extend(out.members[out.gstart[:ng]].tolist())
        return ng

    monkeypatch.setattr(mod, "select_groups", recording)
    ex = ChainEPIBTIsing(grid, seed=1, decider="host", groups=16, rounds=2)
    ex.actions(pos, orient, goals)
    assert starters and all(pos[k] != goals[k] for k in starters)


def audited_twice(make, instance, audit_dir, decision: str, steps: int = 8) -> None:
    """A planner built by ``make(grid)`` run ``steps`` steps on ``instance`` without and with a decision audit in
    ``audit_dir``: the same actions, decisions and calls, and one record of class ``decision`` per decision whose
    calls sum to the machine's."""
    from contextlib import nullcontext

    from ising_backend.audit.record import Audit, read_records

    grid, free, pos, orient, goals = instance
    runs = []
    for audit in (None, audit_dir):
        ex = make(grid)
        p, o, g, acts = pos.copy(), orient.copy(), goals.copy(), []
        r2 = np.random.default_rng(1)
        with Audit(audit) if audit else nullcontext():
            for _ in range(steps):
                a = ex.actions(p, o, g)
                acts.append(a.tolist())
                p, o, _ = apply(grid, p, o, a)
                g = retarget(r2, free, p, g)
        runs.append((acts, ex.machine_step.stats["decisions"], ex.machine_step.ledger.physical_calls))
    assert runs[0] == runs[1]
    records = read_records(audit_dir)
    assert {r["class"] for r in records} == {decision}
    assert len(records) == runs[1][1] > 0
    assert sum(r["calls"] for r in records) == runs[1][2]


def test_the_audit_records_every_decision_and_changes_no_action(tmp_path):
    audited_twice(lambda grid: ChainEPIBTIsing(grid, seed=3, groups=6, rounds=2), world(4)[1], tmp_path / "audit",
                  "lns_groups")


def test_same_seed_same_plans_and_bad_options_are_named():
    rng, (grid, free, pos, orient, goals) = world(9, size=8)
    runs = [ChainEPIBTIsing(grid, seed=1, rounds=3).actions(pos, orient, goals).tolist() for _ in range(2)]
    assert runs[0] == runs[1]
    for opts, word in (({"decider": "gpu"}, "decider"), ({"host_share": 1.5}, "host_share"), ({"rounds": 0}, "rounds"),
                       ({"max_robots": 1}, "max_robots"), ({"lns": -1}, "lns")):
        with pytest.raises(ValueError, match=word):
            ChainEPIBTIsing(grid, **opts)
