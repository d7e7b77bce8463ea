"""EPIBT (PIBT over multi-action operations): a recursive Python oracle, the joint plan checked at every time."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planners.mapf import TURNING_PLANNERS, make_turning_planner
from planners.mapf.epibt.plans import AUTO_OP_LEN_FILL, DEFAULT_OP_LEN
from planners.mapf.common import mix
from test_mapf_turning import DR, DC, F, R, C, W, apply, bfs, drive, free_neighbours, guided, random_instance, retarget

FAR = 1 << 40


def EPIBT(grid, seed=0, **options):
    """EPIBT (the planner ``epibt``) on ``grid``."""
    return make_turning_planner("epibt", grid, seed=seed, **options)


def walk(grid, p, o, op):
    """Cells of ``op`` from flat ``p`` facing ``o`` (start first) and the final orientation; None off the free cells."""
    h, w = grid.shape
    cells = [p]
    for a in op:
        if a == F:
            r, c = divmod(p, w)
            r, c = r + DR[o], c + DC[o]
            if not (0 <= r < h and 0 <= c < w) or grid[r, c]:
                return None
            p = r * w + c
        elif a in (R, C):
            o = (o + (1 if a == R else 3)) % 4
        cells.append(p)
    return cells, o


def plan_conflicts(grid, pos, orient, plans):
    """Every vertex or swap conflict of the joint plan at any time (independent of the executor)."""
    paths = [walk(grid, p, o, op) for p, o, op in zip(pos.tolist(), orient.tolist(), plans.tolist())]
    assert all(x is not None for x in paths), "a plan leaves the free cells"
    cells = [x[0] for x in paths]
    bad = []
    for t in range(1, len(cells[0])):
        at = [c[t] for c in cells]
        if len(set(at)) != len(at):
            bad.append(("vertex", t))
        moves = {(c[t - 1], c[t]) for c in cells if c[t - 1] != c[t]}
        if any((v, u) in moves for u, v in moves):
            bad.append(("swap", t))
    return bad


def oracle_operations(length):
    ops = []
    for op in itertools.product((F, R, C, W), repeat=length):
        if any({a, b} == {R, C} for a, b in zip(op, op[1:])):
            continue
        if any(op[i] == op[i + 1] == op[i + 2] and op[i] in (R, C) for i in range(length - 2)):
            continue
        ops.append(op)
    return ops


class Oracle:
    """EPIBT as the module docstring states it, recursively: its own priorities, fields and operations."""

    def __init__(self, grid, seed, n, guidance=0, op_len=3, revisits=10, lns=0, group=16, weight_power=0, portfolio=1,
                 anneal=0.0, steady=False):
        self.grid, self.seed, self.guidance, self.revisits, self.anneal = grid, seed, guidance, revisits, anneal
        self.steady = steady
        self.lns, self.group, self.weight_power, self.portfolio = lns, group, weight_power, portfolio
        self.ops = oracle_operations(op_len)
        self.t, self.elapsed = 0, [0] * n
        self.tie = np.random.default_rng(seed).random(n).tolist()
        self.inherited = [(W,) * op_len] * n
        self.expect = None
        h, w = grid.shape
        free = ~grid
        self.dead = {p for p in range(h * w) if free.flat[p] and sum(1 for _ in self.nbrs(p)) == 1}

    def nbrs(self, p):
        return free_neighbours(self.grid, p)

    def to_go(self, dist, goal, c, o):
        if c == goal:
            return 0
        vals = []
        for d, v in self.nbrs(c):
            if v in dist:
                cost = self.lane(c, d) if self.guidance else 1
                vals.append(cost + dist[v] + (0 if d == o else (2 if d == (o + 2) % 4 else 1)))
        return min(vals) if vals else dist.get(c, FAR)

    def lane(self, c, d):
        from lanes_reference import lane_cost
        return lane_cost(self.grid, c, d, self.guidance)

    def options(self, k, p, o, goal, dist, s):
        n = len(self.ops[0])
        ranked = []
        for i, op in enumerate(self.ops):
            got = walk(self.grid, p, o, op)
            if got is None:
                continue
            cells, end = got
            idle = sum(2 * (n - s) + ((a in (R, C)) if self.steady else (a == W)) for s, a in enumerate(op) if a != F)
            ranked.append(((self.to_go(dist, goal, cells[-1], end), idle, int(mix(s, self.t, k, i)) & 0xFFFF, i),
                           tuple(cells), op))
        ranked.sort()
        out, seen = [], set()
        for key, cells, op in ranked:
            if cells not in seen:
                seen.add(cells)
                out.append((cells, op, key[0], len(out)))
        return out

    def actions(self, pos, orient, goals):
        pos, orient, goals = pos.tolist(), orient.tolist(), goals.tolist()
        r = len(pos)
        if self.expect != (pos, orient):
            self.inherited = [(W,) * len(self.ops[0])] * r
        dist = {g: guided(self.grid, g, self.guidance) if self.guidance else bfs(self.grid, g) for g in set(goals)}
        inh = []
        for k in range(r):
            cells, end = walk(self.grid, pos[k], orient[k], self.inherited[k])
            inh.append((tuple(cells), self.inherited[k], self.to_go(dist[goals[k]], goals[k], cells[-1], end), -1))
        prio = [e + t for e, t in zip(self.elapsed, self.tie)]
        order = sorted(range(r), key=lambda k: (-self.elapsed[k], -self.tie[k]))
        weight = [0] * r
        for rank, k in enumerate(order):
            weight[k] = (r + 1 - rank) ** self.weight_power
        best = None
        for j in range(self.portfolio):  # plan j from its own seed; the least weighted cost kept, the first on ties
            s = self.seed if j == 0 else int(mix(self.seed, j, 0x70F7, 0)) & ((1 << 62) - 1)
            opts = [self.options(k, pos[k], orient[k], goals[k], dist[goals[k]], s) for k in range(r)]
            plan = self.one_plan(opts, inh, prio, order, weight, s)
            cost = sum(weight[k] * plan[k][2] for k in range(r))
            if best is None or cost < best[0]:
                best = (cost, plan)
        plan = best[1]
        ops = [plan[k][1] for k in range(r)]
        act = [op[0] for op in ops]
        nxt = [plan[k][0][1] for k in range(r)]
        nor = [(o + (a == R) - (a == C)) % 4 for o, a in zip(orient, act)]
        self.inherited = [tuple(op[1:]) + (W,) for op in ops]
        self.expect = (nxt, nor)
        for k in range(r):
            bonus = 10 if nxt[k] in self.dead else 0
            self.elapsed[k] = 0 if nxt[k] == goals[k] else self.elapsed[k] + 1 + bonus
        self.t += 1
        return act, ops

    def one_plan(self, opts, inh, prio, order, weight, s):
        """One joint plan: the construction with pushes, then the search, on the tie bits of seed ``s``."""
        r = len(inh)
        plan = list(inh)
        visit, hit = [0] * r, [False] * r

        def collide(a, cells):
            found = set()
            for b in range(r):
                if b == a or plan[b] is None:
                    continue
                other = plan[b][0]
                for t in range(1, len(cells)):
                    if other[t] == cells[t] or (cells[t] != cells[t - 1] and other[t - 1] == cells[t]
                                                and other[t] == cells[t - 1]):
                        found.add(b)
                        break
            return found

        def choose(a, p):
            visit[a] += 1
            hit[a] = True
            for entry in opts[a]:
                cells = entry[0]
                hits = collide(a, cells)
                if not hits:
                    plan[a] = entry
                    hit[a] = False
                    return True
                if len(hits) > 1:
                    continue
                (b,) = hits
                if hit[b] or visit[b] >= self.revisits or prio[b] >= p:
                    continue
                old = plan[b]
                plan[b] = None
                plan[a] = entry
                if choose(b, p):
                    hit[a] = False
                    return True
                plan[b] = old
            plan[a] = None
            hit[a] = False
            return False

        for k in order:
            if visit[k]:
                continue
            plan[k] = None
            if not choose(k, prio[k]):
                plan[k] = inh[k]
        self.search(plan, opts, inh, collide, weight, s)
        return plan

    def search(self, plan, opts, inh, collide, weight, seed):
        """Large-neighbourhood search as the module docstring states it (plan entries: cells, op, cost, index;
        costs weighted by ``weight``)."""
        r = len(plan)
        start = int(mix(seed, self.t, r, 0)) % r
        total = best = 0
        at_best, saved = True, None
        for it in range(self.lns):
            k = (start + it) % r
            now = plan[k][3]
            if now == 0 or not opts[k]:
                continue
            members = [k]
            for cells, _, _, _ in opts[k][:now if now > 0 else len(opts[k])]:
                for s in range(1, len(cells)):
                    at = [b for b in range(r) if plan[b][0][s] == cells[s]]
                    swap = [b for b in range(r) if cells[s] != cells[s - 1] and plan[b][0][s - 1] == cells[s]
                            and plan[b][0][s] == cells[s - 1]]
                    for b in at + swap:
                        if b not in members and len(members) < self.group:
                            members.append(b)
            old = [plan[i] for i in members]
            before = sum(weight[i] * plan[i][2] for i in members)
            temp = self.anneal * (1.0 - it / self.lns)
            cutoff = before if not self.anneal else before + int(20.0 * temp * max(before, 1))
            for i in members:
                plan[i] = None
            after, ok = 0, True
            for i in sorted(members, key=lambda i: int(mix(seed, self.t, it, i))):
                pick = next((o for o in opts[i] if not collide(i, o[0])), None)
                if pick is None and not collide(i, inh[i][0]):
                    pick = inh[i]
                if pick is None or after >= cutoff:
                    ok = False
                    break
                plan[i] = pick
                after += weight[i] * pick[2]
            keep = ok and after < before
            if self.anneal and ok and not keep and temp > 0 and after < cutoff:
                u = (int(mix(seed, self.t, it, r + 7)) >> 11) * 2.0 ** -53
                keep = u < math.exp(-(after - before) / (temp * max(before, 1)))
            if keep:
                if after >= before and at_best:  # leaving the best plan met for a worse one: keep a copy of it
                    saved = list(plan)
                    for i, entry in zip(members, old):
                        saved[i] = entry
                    at_best = False
                total += after - before
                if total < best:
                    best, at_best = total, True
                continue
            for i, entry in zip(members, old):
                plan[i] = entry
        if not at_best:
            plan[:] = saved


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10**6), h=st.integers(3, 7), w=st.integers(3, 7),
       density=st.floats(0.0, 0.3), fill=st.floats(0.05, 0.9), guidance=st.sampled_from([0, 0, 2]),
       op_len=st.sampled_from([1, 2, 3, 3]), lns=st.sampled_from([0, 5, 40]), group=st.sampled_from([2, 4, 16]),
       weight_power=st.sampled_from([0, 1, 2]), portfolio=st.sampled_from([1, 1, 2, 3]), threads=st.sampled_from([1, 2]),
       anneal=st.sampled_from([0.0, 0.0, 0.05, 0.5]), steady=st.booleans())
def test_kernel_equals_recursive_oracle(seed, h, w, density, fill, guidance, op_len, lns, group, weight_power,
                                        portfolio, threads, anneal, steady):
    rng = np.random.default_rng(seed)
    grid, free, pos, orient, goals = random_instance(rng, h, w, density, fill)
    ex = EPIBT(grid, seed=seed, guidance=guidance, flow=False, op_len=op_len, lns=lns, group=group,
               weight_power=weight_power, portfolio=portfolio, threads=threads, anneal=anneal, steady=steady)
    oracle = Oracle(grid, ex.prio.seed, len(pos), guidance, op_len, lns=lns, group=group, weight_power=weight_power,
                    portfolio=portfolio, anneal=anneal, steady=steady)
    for _ in range(10):
        expect, ops = oracle.actions(pos, orient, goals)
        act = ex.actions(pos, orient, goals)
        assert act.tolist() == expect
        assert [tuple(op) for op in ex.decider.plans.tolist()] == ops
        pos, orient, err = apply(grid, pos, orient, act)
        assert err is None, err
        goals = retarget(rng, free, pos, goals)


def test_operations_follow_the_pruning_rules():
    from planners.mapf.epibt.plans import operations

    for n in (1, 2, 3, 4):
        assert [tuple(op) for op in operations(n).tolist()] == oracle_operations(n)
    assert len(operations(3)) == 48


@pytest.mark.parametrize("seed", range(6))
def test_dense_crowds_get_conflict_free_plans_at_every_time(seed):
    rng = np.random.default_rng(300 + seed)
    h, w = int(rng.integers(8, 17)), int(rng.integers(8, 17))
    grid, free, pos, orient, goals = random_instance(rng, h, w, 0.1 + 0.03 * seed, 0.5 + 0.07 * seed)
    ex = make_turning_planner("epibt", grid, seed=seed, flow=seed % 2 == 0)

    def check(step, pos, orient, act):
        assert plan_conflicts(grid, pos, orient, ex.decider.plans) == [], f"step {step}"
        assert act.tolist() == ex.decider.plans[:, 0].tolist()

    moved, reached = drive(ex, grid, free, (pos, orient, goals), rng, 120, check)
    assert moved > 0 and reached > 0


def test_a_robot_moved_elsewhere_drops_the_inherited_operations():
    rng = np.random.default_rng(7)
    grid, free, pos, orient, goals = random_instance(rng, 9, 9, 0.15, 0.6)
    ex = EPIBT(grid, seed=1)
    for step in range(30):  # positions that no plan led to: every call starts from waits, still valid
        act = ex.actions(pos, orient, goals)
        assert apply(grid, pos, orient, act)[2] is None
        pos = rng.permutation(free)[:len(pos)].astype(np.int64)
        orient = rng.integers(0, 4, len(pos)).astype(np.int64)


def test_same_seed_same_actions_and_robots_reach_goals():
    rng = np.random.default_rng(3)
    grid, free, pos, orient, goals = random_instance(rng, 12, 12, 0.15, 0.3)
    runs = []
    for _ in range(2):
        ex, p, o, g = EPIBT(grid, seed=5), pos.copy(), orient.copy(), goals.copy()
        r2 = np.random.default_rng(11)
        acts, reached = [], 0
        for _ in range(60):
            a = ex.actions(p, o, g)
            acts.append(a.tolist())
            p, o, err = apply(grid, p, o, a)
            assert err is None
            reached += int((p == g).sum())
            g = retarget(r2, free, p, g)
        runs.append((acts, reached))
    assert runs[0] == runs[1] and runs[0][1] > 0


def test_registered_and_bad_options_name_the_value():
    assert EPIBT(np.zeros((2, 2), dtype=bool)).kind is TURNING_PLANNERS["epibt"]
    grid = np.zeros((4, 4), dtype=bool)
    for opts, word in (({"op_len": 0}, "op_len"), ({"op_len": 6}, "op_len"),
                       ({"op_len": "fast"}, r"op_len = 'fast' must be an integer in \[1, 5\] or 'auto'"),
                       ({"revisits": 0}, "revisits"),
                       ({"flow": "yes"}, "flow"), ({"replans": -1}, "replans"), ({"lns": -1}, r"lns .* -1 .*\[0, "),
                       ({"group": 1}, r"group .* 1 .*\[2, 4096\]"), ({"weight_power": 3}, r"weight_power .* 3 .*\[0, 2\]"),
                       ({"portfolio": 0}, r"portfolio .* 0 .*\[1, 64\]"), ({"portfolio": 65}, r"portfolio .* 65 "),
                       ({"threads": 0}, r"threads .* 0 .*\[1, 64\]"),
                       ({"anneal": 1.5}, r"anneal = 1.5 must be a number in \[0, 1\]$"),
                       ({"anneal": "hot"}, r"anneal = 'hot' must be a number in \[0, 1\]$")):
        with pytest.raises(ValueError, match=word):
            EPIBT(grid, **opts)
    kind = TURNING_PLANNERS["epibt"]
    with pytest.raises(ValueError, match="pibt-flow keeps a field and a path"):
        kind.check_team(np.zeros((100, 100), dtype=bool), 10**6, kind.Options.from_dict({}, "epibt"))
    goal_fields = kind.Options.from_dict({"flow": False}, "epibt")
    kind.check_team(np.zeros((100, 100), dtype=bool), 10**6, goal_fields)  # goal fields: the cache makes room


def test_the_run_command_takes_a_big_team_on_epibts_goal_fields(tmp_path):
    """The memory check of a run asks EPIBT about its own mode: guide paths refused past the bound, goal fields not."""
    from agents.cli import main

    from mrmt_env.lorr.instance import example_instance_path

    base = ["lorr", "run", str(example_instance_path()), "--planner", "epibt", "--steps", "2", "--out", str(tmp_path),
            "--planner-option", "field_bytes=1000"]
    assert main(base) == 2
    assert main(base + ["--planner-option", "flow=false"]) == 0


@pytest.mark.parametrize("robots, op_len", [(8, 4), (16, 4), (17, 3), (30, 3)])
def test_auto_op_len_follows_the_teams_share_of_free_cells(robots, op_len):
    grid = np.zeros((6, 6), dtype=bool)
    grid[0, :4] = True  # 32 free cells: 4 actions up to 16 robots, 3 beyond
    assert AUTO_OP_LEN_FILL == 0.5
    free = np.flatnonzero(~grid.reshape(-1))
    pos, goals = free[:robots], free[::-1][:robots].copy()
    auto, fixed = EPIBT(grid, seed=3, op_len="auto"), EPIBT(grid, seed=3, op_len=op_len)
    orient = np.zeros(robots, np.int64)
    assert auto.decider.ops.shape[1] == DEFAULT_OP_LEN  # chosen on the first call, from its team
    assert auto.actions(pos, orient, goals).tolist() == fixed.actions(pos, orient, goals).tolist()
    assert auto.decider.ops.shape[1] == op_len and np.array_equal(auto.decider.plans, fixed.decider.plans)


@pytest.mark.parametrize("seed", range(3))
def test_a_portfolio_keeps_its_cheapest_plan_on_any_number_of_threads(seed):
    rng = np.random.default_rng(900 + seed)
    grid, free, pos, orient, goals = random_instance(rng, 14, 14, 0.15, 0.7)
    runs = []
    for threads in (1, 2, 4):
        ex = EPIBT(grid, seed=seed, portfolio=4, threads=threads, weight_power=2, lns=50)

        def check(step, pos, orient, act, ex=ex):
            costs = ex.decider.portfolio_costs
            assert costs.shape == (4,) and int(np.argmin(costs)) == ex.decider.kept
            assert plan_conflicts(grid, pos, orient, ex.decider.plans) == [], f"step {step}"

        acts = []
        drive(ex, grid, free, (pos, orient, goals), np.random.default_rng(seed),
              25, lambda step, p, o, a, check=check: (check(step, p, o, a), acts.append(a.tolist())))
        runs.append(acts)
    assert runs[0] == runs[1] == runs[2]
    single, four = EPIBT(grid, seed=seed, weight_power=2, lns=50), EPIBT(grid, seed=seed, portfolio=4, weight_power=2, lns=50)
    single.actions(pos, orient, goals)
    four.actions(pos, orient, goals)  # the same first call: plan 0 is the single plan, the kept one costs no more
    assert four.decider.portfolio_costs[0] == single.decider.portfolio_costs[0] >= four.decider.portfolio_costs.min()


def test_no_robots_no_actions():
    grid = np.zeros((4, 4), dtype=bool)
    for ex in (EPIBT(grid, lns=10), EPIBT(grid, flow=False)):
        assert ex.actions(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64)).tolist() == []


@pytest.mark.parametrize("anneal", [0.05, 0.5])
def test_annealing_leaves_the_best_plan_it_met_conflict_free(anneal):
    """Annealing accepts worse neighbourhoods on the way, yet the plan it leaves is the best it met: never costlier
    than the construction's (lns=0), conflict-free at every time."""
    from planners.mapf.epibt.plans import plan_cost

    rng = np.random.default_rng(7)
    grid, free, pos, orient, goals = random_instance(rng, 10, 10, 0.15, 0.7)
    costs = {}
    for lns in (0, 400):
        ex = EPIBT(grid, seed=3, flow=False, lns=lns, weight_power=2, anneal=anneal)
        captured = []

        class Capture:  # a machine step's hook: the kept plan's state before its first actions are taken
            def improve(self, step, state, deadline):
                captured.append(state)

        ex.decider.machine_step = Capture()
        ex.actions(pos, orient, goals)
        costs[lns] = plan_cost(captured[0])
        assert plan_conflicts(grid, pos, orient, ex.decider.plans) == []
    assert costs[400] <= costs[0]
