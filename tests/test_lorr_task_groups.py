"""``lorr-ising``: the chip's group decisions on the winner's matching, checked against plain Python oracles."""

from __future__ import annotations

import itertools
from contextlib import nullcontext

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from agents.lorr.schedulers import make_scheduler
from agents.lorr.task_groups import (GroupLimits, decode_task_groups, group_cost, select_task_groups, task_programs,
                                    task_qubo)
from ising_backend import integer_program
from agents.lorr.weighted import Crowd, Matched, weighted_matching
from ising_backend.audit.host_rule import HostRule
from mrmt_env.lorr.instance import example_instance_path, read_instance
from mrmt_env.lorr.loop import StepLoop
from mrmt_env.lorr.sim import LoRRSimulator
from planners.mapf.common import GroupBatch, mix
from planners.mapf import make_turning_planner

NONE = 1 << 50


def _matching(seed: int, n: int = 12, cells: int = 7, jam: int = 2) -> Matched:
    """A random matching: ways, cells of 1-3 tasks (legs sorted), blocks and loads, matched greedily."""
    rng = np.random.default_rng(seed)
    way = rng.integers(0, 30, size=(n, cells)).astype(np.int32)
    way[rng.random((n, cells)) < 0.1] = -1
    counts = rng.integers(1, 4, size=cells)
    cell_start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    length = np.concatenate([np.sort(rng.integers(1, 20, size=k)) for k in counts]).astype(np.int64)
    crowd = Crowd(rng.integers(0, 3, size=cells).astype(np.int64), rng.integers(0, 4, size=3).astype(np.int64), jam)
    out = np.empty(n, dtype=np.int64)
    weighted_matching(way, cell_start, length, 1 + seed % 2, out, crowd)
    return Matched(np.arange(n), np.arange(len(length)) + 100, way, cell_start, length, 1 + seed % 2, crowd, out)


def _derived(m: Matched):
    cell_of = np.repeat(np.arange(len(m.cell_start) - 1), np.diff(m.cell_start)).astype(np.int64)
    owner = -np.ones(len(m.ids), dtype=np.int64)
    owner[m.out[m.out >= 0]] = np.flatnonzero(m.out >= 0)
    head = m.cell_start[:-1] + np.bincount(cell_of[m.out[m.out >= 0]], minlength=len(m.cell_start) - 1)
    return cell_of, owner, head


def _cost(m, cell_of, load, i, s):
    c = cell_of[s]
    if m.way[i, c] < 0:
        return NONE
    return m.weight * int(m.way[i, c]) + int(m.length[s]) + m.crowd.weight * int(load[m.crowd.block[c]])


def _select_oracle(m: Matched, limits: GroupLimits, seed: int, t: int):
    """The module docstring's groups, written plainly: ``[(members, [options per member])]``."""
    cell_of, owner, head = _derived(m)
    load, n, ncell = m.crowd.load, len(m.out), len(m.cell_start) - 1
    taken_r, taken_s, groups = set(), set(), []
    first = int(mix(seed, t, n, 0x7A5)) % n
    for k in [(first + j) % n for j in range(n)]:
        if len(groups) == limits.groups:
            break
        if k in taken_r or m.out[k] < 0:
            continue
        cur = _cost(m, cell_of, load, k, m.out[k])
        members, pool = [k], []

        def add(s):
            if s >= 0 and s not in taken_s and s not in pool:
                pool.append(s)

        for c in range(ncell):
            if len(members) == limits.max_robots:
                break
            for s in range(m.cell_start[c], head[c]):
                if _cost(m, cell_of, load, k, s) >= cur or len(members) == limits.max_robots:
                    break
                r = owner[s]
                if r < 0 or r == k or r in taken_r or s in taken_s:
                    continue
                members.append(r)
                add(s)
                add(head[c] if head[c] < m.cell_start[c + 1] else -1)
        if len(members) < 2:
            continue
        for r in members:
            add(m.out[r])
            c = cell_of[m.out[r]]
            add(head[c] if head[c] < m.cell_start[c + 1] else -1)
            free = [(_cost(m, cell_of, load, r, head[c2]), c2) for c2 in range(ncell)
                    if head[c2] < m.cell_start[c2 + 1] and head[c2] not in taken_s]
            best = min(free, default=(NONE, -1))
            add(head[best[1]] if best[0] < NONE else -1)
        per = min(limits.max_options, limits.max_spins // len(members) + 1)
        options = []
        for r in members:
            top = _cost(m, cell_of, load, r, m.out[r]) + limits.max_gap
            ranked = sorted(range(len(pool)), key=lambda x: (_cost(m, cell_of, load, r, pool[x]), x))
            mine = [m.out[r]] + [pool[x] for x in ranked if _cost(m, cell_of, load, r, pool[x]) <= top
                                 and pool[x] != m.out[r]]
            options.append(mine[:per])
        taken_r.update(members)
        taken_s.update(pool)
        groups.append((members, options))
    return groups


def _select(m: Matched, limits: GroupLimits, seed: int = 0, t: int = 0):
    cell_of, owner, head = _derived(m)
    n = len(m.out)
    batch = GroupBatch(0, np.empty(limits.groups + 1, np.int64), np.empty(n, np.int64), np.empty(n + 1, np.int64),
                       np.empty(n * limits.max_options, np.int64))
    ng = select_task_groups(m, cell_of, owner, head, limits, seed, t, np.zeros(n, np.int8),
                            np.zeros(len(m.ids), np.int8), batch)
    return cell_of, batch, ng


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 8), st.sampled_from([2, 3, 5, 12]), st.sampled_from([2, 3, 4]),
       st.sampled_from([0, 5, 64]))
def test_groups_equal_the_oracle(seed, groups, robots, options, gap):
    m = _matching(seed)
    limits = GroupLimits(groups, robots, options, 45 if seed % 3 else 5, gap)
    _, batch, ng = _select(m, limits, seed, 3)
    got = []
    for g in range(ng):
        mem = batch.members[batch.gstart[g]:batch.gstart[g + 1]].tolist()
        got.append((mem, [batch.opt[batch.ostart[i]:batch.ostart[i + 1]].tolist()
                          for i in range(batch.gstart[g], batch.gstart[g + 1])]))
    assert got == _select_oracle(m, limits, seed, 3)


def test_groups_hold_each_robot_and_task_once_and_fit_the_machine():
    for seed in range(30):
        m = _matching(seed, n=20, cells=9)
        limits = GroupLimits(8, 4, 3, 9, 64)
        cell_of, batch, ng = _select(m, limits, seed)
        robots, free = [], []
        for g in range(ng):
            a, b = batch.gstart[g], batch.gstart[g + 1]
            mem = batch.members[a:b]
            assert 2 <= b - a <= limits.max_robots
            assert batch.ostart[b] - batch.ostart[a] - (b - a) <= limits.max_spins
            robots += mem.tolist()
            group_slots = {int(m.out[r]) for r in mem}
            for i in range(a, b):
                opts = batch.opt[batch.ostart[i]:batch.ostart[i + 1]]
                assert opts[0] == m.out[batch.members[i]] and len(set(opts.tolist())) == len(opts)
                for s in opts.tolist():  # a group's own task or a free one, never another robot's
                    assert s in group_slots or s not in set(m.out.tolist())
                free += [s for s in opts.tolist() if s not in group_slots]
            free = list(dict.fromkeys(free))
        assert len(robots) == len(set(robots))


@pytest.mark.parametrize("seed", range(12))
def test_program_energy_is_the_group_cost_above_the_task_now(seed):
    """On every assignment that gives no task twice, the reduced program's energy equals the group's cost less its
    cost now; an assignment giving a task twice costs more than that."""
    m = _matching(seed, jam=3)
    cell_of, batch, ng = _select(m, GroupLimits(4, 3, 3, 45, 64), seed)
    assert ng > 0 or seed % 5 == 4  # most random matchings have a contested group
    for g in range(ng):
        a, b = batch.gstart[g], batch.gstart[g + 1]
        q = np.zeros((45, 45), np.int64)
        k = task_qubo(m, cell_of, batch.members, a, b, batch.ostart, batch.opt, q)
        starts = batch.ostart[a:b + 1] - batch.ostart[a]
        now = group_cost(m, cell_of, batch.members, a, b, batch.ostart, batch.opt, np.zeros(b - a, np.int64))
        for choice in itertools.product(*[range(starts[i + 1] - starts[i]) for i in range(b - a)]):
            y = np.zeros(k, np.int64)
            for i, x in enumerate(choice):
                if x:
                    y[starts[i] + x - i - 1] = 1
            energy = int(y @ np.triu(q[:k, :k]) @ y)
            cost = group_cost(m, cell_of, batch.members, a, b, batch.ostart, batch.opt, np.array(choice))
            if cost >= 0:
                assert energy == cost - now
            else:
                slots = [batch.opt[batch.ostart[a + i] + x] for i, x in enumerate(choice)]
                assert len(set(slots)) < len(slots)


def test_decode_takes_the_cheapest_read_and_keeps_a_robot_with_two_spins_up():
    m = _matching(7, jam=3)
    cell_of, batch, ng = _select(m, GroupLimits(4, 3, 3, 45, 64), 7)
    a, b = batch.gstart[0], batch.gstart[1]
    k = int(batch.ostart[b] - batch.ostart[a] - (b - a))
    reads = -np.ones((3, k), np.int8)
    reads[1, :] = 1  # every spin up: each robot keeps its task
    reads[2, 0] = 1  # robot 0 on its second option
    choice, cost, now_ = np.zeros(b, np.int64), np.empty(1, np.int64), np.empty(1, np.int64)
    decode_task_groups(m, cell_of, batch._replace(ng=1), reads[None], choice, cost, now_)  # the first group alone
    now = group_cost(m, cell_of, batch.members, a, b, batch.ostart, batch.opt, np.zeros(b - a, np.int64))
    moved = np.zeros(b - a, np.int64)
    moved[0] = 1
    other = group_cost(m, cell_of, batch.members, a, b, batch.ostart, batch.opt, moved)
    assert now_[0] == now and cost[0] == min(now, other if other >= 0 else now)
    assert choice[a:b].tolist() == (moved.tolist() if 0 <= other < now else [0] * (b - a))


@pytest.mark.parametrize("seed", range(4))
def test_a_steps_programs_in_one_call_are_each_groups_program(seed):
    m = _matching(seed, jam=3)
    cell_of, batch, ng = _select(m, GroupLimits(4, 3, 3, 45, 64), seed)
    if ng == 0:
        return
    batch = batch._replace(ng=ng)
    n = int(max(batch.ostart[batch.gstart[g + 1]] - batch.ostart[batch.gstart[g]]
                - (batch.gstart[g + 1] - batch.gstart[g]) for g in range(ng)))
    H, J = np.full((ng, n), 99, np.int64), np.full((ng, n, n), 99, np.int64)
    task_programs(m, cell_of, batch, 2, (7, 7), H, J)
    for g in range(ng):
        q, h1, J1 = np.empty((n, n), np.int64), np.zeros(n, np.int64), np.zeros((n, n), np.int64)
        k = task_qubo(m, cell_of, batch.members, batch.gstart[g], batch.gstart[g + 1], batch.ostart, batch.opt, q, 2)
        integer_program(q, k, h1[:k], J1[:k, :k], (7, 7))
        assert np.array_equal(H[g], h1) and np.array_equal(J[g], J1)


def _steps(scheduler, steps: int = 40):
    inst = read_instance(example_instance_path())
    sim = LoRRSimulator(inst)
    loop = StepLoop(sim, scheduler)
    planner = make_turning_planner("pibt", inst.grid, seed=0)
    proposals = []
    while sim.t < steps:
        loop.propose(None)
        proposals.append(sim.tasks.assigned.copy())
        loop.advance(planner.actions(sim.pos, sim.orient, loop.goal_cells()), 0, steps)
    return proposals, sim


def test_host_rule_twin_is_the_weighted_matching_and_the_chip_decides():
    """Under ``--host-rule task_groups`` the groups are posed and the matching kept: step for step the proposals of
    ``lorr-weighted``.  With the chip each read of each program is one machine call and a group it moves lowers its cost."""
    weighted, _ = _steps(make_scheduler("lorr-weighted", jam=2))
    twin = make_scheduler("lorr-ising", jam=2)
    with HostRule("task_groups"):
        hosted, _ = _steps(twin)
    assert all((a == b).all() for a, b in zip(weighted, hosted))
    assert twin.stats["decisions"] > 0 and twin.stats["applied"] == 0 and twin.ledger.physical_calls == 0
    chip = make_scheduler("lorr-ising", jam=2)
    _, sim = _steps(chip)
    reads = chip.options.num_reads  # each read is one anneal of the chip
    assert chip.ledger.physical_calls == chip.stats["decisions"] * reads > 0
    assert chip.stats["applied"] > 0 and chip.stats["gain"] >= chip.stats["applied"]
    assert len(sim.tasks.schedule_errors) == 0 and len(sim.errors) == 0


def test_runs_are_deterministic_and_the_machine_is_named_by_chip():
    from ising_backend import ChipSpec, build_machine

    a = _steps(make_scheduler("lorr-ising", seed=3))[0]
    b = _steps(make_scheduler("lorr-ising", seed=3))[0]
    assert all((x == y).all() for x, y in zip(a, b))
    spec = ChipSpec.from_options([("n_spins", 16)])
    small = make_scheduler("lorr-ising", chip=spec, max_robots=4)
    assert small.limits.max_spins == int(build_machine(spec, 0).usable_spins) == 16


@pytest.mark.parametrize("options, words", [({"max_robots": 1}, ["max_robots", "1"]),
                                            ({"max_options": 40}, ["max_options", "40"]),
                                            ({"rounds": 2}, ["rounds"])])
def test_bad_options_name_the_value_and_the_limit(options, words):
    with pytest.raises(ValueError) as err:
        make_scheduler("lorr-ising", **options)
    assert all(w in str(err.value) for w in words)


def test_a_machine_too_small_for_the_group_is_refused():
    from ising_backend import ChipSpec

    with pytest.raises(ValueError, match="max_robots = 8 needs 8 spins"):
        make_scheduler("lorr-ising", chip=ChipSpec.from_options([("n_spins", 4)]), max_robots=8)


def test_cli_runs_lorr_ising_and_its_twin(tmp_path, capsys):
    from agents.cli import main

    path = str(example_instance_path())
    for extra in ([], ["--host-rule", "task_groups"]):
        with nullcontext():
            code = main(["lorr", "run", path, "--scheduler", "lorr-ising", "--steps", "20", "--no-progress",
                         "--json", *extra])
        assert code in (0, None)
    assert capsys.readouterr().out.count('"scheduler": "lorr-ising"') == 2


def test_audit_records_every_program_with_the_matching_as_its_host_rule(tmp_path):
    """An open audit changes no proposal, records one program per group posed (class ``task_groups``) and its
    host rule, the matching kept, as every spin down."""
    from ising_backend.audit.record import Audit, read_records

    plain = _steps(make_scheduler("lorr-ising", jam=2), steps=20)[0]
    chip = make_scheduler("lorr-ising", jam=2)
    with Audit(tmp_path):
        audited = _steps(chip, steps=20)[0]
    assert all((a == b).all() for a, b in zip(plain, audited))
    rows = read_records(tmp_path)
    assert len(rows) == chip.stats["decisions"] > 0 and {r["class"] for r in rows} == {"task_groups"}
    assert all(r["host_rule"] == "greedy matching" for r in rows)
