"""PIBT with turning (LoRR's MAPF_T actions): a recursive Python oracle, an independent validity check."""

from __future__ import annotations

import re
import heapq
from collections import deque

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lanes_reference import corridor_cost, lane_cost
from planners.mapf import TURNING_PLANNERS, TurningPlanner, make_turning_planner
from planners.mapf.common import mix

F, R, C, W = 0, 1, 2, 3
DR, DC = (0, 1, 0, -1), (1, 0, -1, 0)  # east, south, west, north
FAR = 1 << 40


def TurningPIBT(grid, seed=0, **options):
    """PIBT with turning (the planner ``pibt``) on ``grid``."""
    return make_turning_planner("pibt", grid, seed=seed, **options)


# ---------------------------------------------------------------- independent rules of the action model

def apply(grid, pos, orient, act):
    """Next (pos, orient) and the first rule broken (None if the joint action is valid)."""
    h, w = grid.shape
    nxt, nor = [], []
    for p, o, a in zip(pos.tolist(), orient.tolist(), act.tolist()):
        if a not in (F, R, C, W):
            return None, None, f"action {a}"
        r, c = divmod(p, w)
        if a == F:
            r, c = r + DR[o], c + DC[o]
            if not (0 <= r < h and 0 <= c < w):
                return None, None, f"off the map from {p} facing {o}"
            if grid[r, c]:
                return None, None, f"into obstacle {(r, c)}"
        nxt.append(r * w + c)
        nor.append((o + (a == R) - (a == C)) % 4)
    if len(set(nxt)) != len(nxt):
        return None, None, "vertex conflict"
    moves = {(p, q) for p, q in zip(pos.tolist(), nxt) if p != q}
    if any((q, p) in moves for p, q in moves):
        return None, None, "swap"
    return np.array(nxt, dtype=np.int64), np.array(nor, dtype=np.int64), None


# ---------------------------------------------------------------- the oracle: recursive PIBT + vacate check

def free_neighbours(grid, p):
    """``(direction, flat cell)`` of each free neighbour of flat cell ``p``."""
    h, w = grid.shape
    r, c = divmod(p, w)
    for d in range(4):
        nr, nc = r + DR[d], c + DC[d]
        if 0 <= nr < h and 0 <= nc < w and not grid[nr, nc]:
            yield d, nr * w + nc


def bfs(grid, goal):
    h, w = grid.shape
    dist = {goal: 0}
    queue = deque([goal])
    while queue:
        p = queue.popleft()
        r, c = divmod(p, w)
        for d in range(4):
            nr, nc = r + DR[d], c + DC[d]
            if 0 <= nr < h and 0 <= nc < w and not grid[nr, nc] and nr * w + nc not in dist:
                dist[nr * w + nc] = dist[p] + 1
                queue.append(nr * w + nc)
    return dist


def guided(grid, goal, weight, corridors=0, crowd=0, occupied=frozenset()):
    """Least lane cost (+ one-way corridor cost, + ``crowd`` into each ``occupied`` cell) from every free cell to
    ``goal`` (Dijkstra, backwards)."""
    h, w = grid.shape
    dist, heap = {goal: 0}, [(0, goal)]
    while heap:
        d, p = heapq.heappop(heap)
        if d > dist[p]:
            continue
        r, c = divmod(p, w)
        for e in range(4):  # q one step in direction e from p moves to p in direction e + 2
            nr, nc = r + DR[e], c + DC[e]
            if 0 <= nr < h and 0 <= nc < w and not grid[nr, nc]:
                q = nr * w + nc
                nd = d + lane_cost(grid, q, (e + 2) % 4, weight) + corridor_cost(grid, q, (e + 2) % 4, corridors) \
                    + (crowd if p in occupied else 0)
                if nd < dist.get(q, FAR):
                    dist[q] = nd
                    heapq.heappush(heap, (nd, q))
    return dist


class Oracle:
    """PIBT with turning as the module docstring states it, written recursively (a step ending in a
    dead end off the goal adds 1 + 10 to the priority); distances by BFS, or by lane cost with
    ``guidance``."""

    def __init__(self, grid, seed, n, guidance=0, commits=False):
        self.guidance, self.commits = guidance, commits
        self.commit = [None] * n  # the cell a robot keeps claiming until it stands on it
        self.grid, self.seed, self.t = grid, seed, 0
        self.elapsed = [0] * n
        self.tie = np.random.default_rng(seed).random(n).tolist()

    def neighbours(self, p):
        return free_neighbours(self.grid, p)

    def distances(self, goals):
        """Robot ``k``'s distances ``{cell: distance}`` (its goal's BFS or lane-cost field)."""
        by_goal = {g: guided(self.grid, g, self.guidance) if self.guidance else bfs(self.grid, g) for g in set(goals)}
        return [by_goal[g] for g in goals]

    def actions(self, pos, orient, goals):
        pos, orient, goals = pos.tolist(), orient.tolist(), goals.tolist()
        n = len(pos)
        dist = self.distances(goals)
        order = sorted(range(n), key=lambda k: (-self.elapsed[k], -self.tie[k]))
        occ_now = {p: k for k, p in enumerate(pos)}
        occ_next, nxt = {}, [None] * n
        for k in range(n):
            if self.commit[k] is not None and self.commit[k] != pos[k]:
                occ_next[self.commit[k]], nxt[k] = k, self.commit[k]

        def cands(a):
            o, f = orient[a], dist[a]
            cells = [(pos[a], 0)] + [(v, 0 if d == o else 2 if d == (o + 2) % 4 else 1)
                                     for d, v in self.neighbours(pos[a])]
            return [v for v, turns in sorted(cells, key=lambda x: (
                f.get(x[0], FAR), x[1], int(mix(self.seed, self.t, a, x[0]))))]

        def pibt(a, b):
            for v in cands(a):
                if v in occ_next or (b is not None and v == pos[b]):
                    continue
                occ_next[v], nxt[a] = a, v
                c = occ_now.get(v)
                if c is not None and nxt[c] is None and not pibt(c, a):
                    continue
                return True
            occ_next[pos[a]], nxt[a] = a, pos[a]
            return False

        for a in order:
            if nxt[a] is None:
                pibt(a, None)
        act = []
        for k in range(n):
            d = next((d for d, v in self.neighbours(pos[k]) if v == nxt[k] and occ_next[v] == k), None)
            o = orient[k]
            act.append(W if d is None else F if d == o else C if d == (o + 3) % 4 else R)
        verdict, visiting = {}, set()

        def moves(k):  # F kept iff the cell ahead is empty now or its robot's F is kept (rotations move)
            if k in verdict:
                return verdict[k]
            if k in visiting:
                return True
            visiting.add(k)
            j = occ_now.get(nxt[k])
            verdict[k] = j is None or (act[j] == F and moves(j))
            return verdict[k]

        for k in range(n):
            if act[k] == F and not moves(k):
                act[k] = W
        moved = [nxt[k] if act[k] == F else pos[k] for k in range(n)]
        if self.commits:
            self.commit = [None if moved[k] == nxt[k] else nxt[k] for k in range(n)]
        dead_end = [len(list(self.neighbours(moved[k]))) == 1 for k in range(n)]
        self.elapsed = [0 if moved[k] == goals[k] else self.elapsed[k] + 1 + 10 * dead_end[k] for k in range(n)]
        self.t += 1
        return act, nxt


# ---------------------------------------------------------------- instances

def random_instance(rng, h, w, density, fill):
    grid = rng.random((h, w)) < density
    grid[0, 0] = False
    free = np.flatnonzero(~grid.reshape(-1))
    n = max(1, min(len(free), int(round(fill * len(free)))))
    pos = rng.choice(free, size=n, replace=False).astype(np.int64)
    orient = rng.integers(0, 4, size=n).astype(np.int64)
    goals = rng.choice(free, size=n).astype(np.int64)
    goals = np.where(rng.random(n) < 0.2, pos, goals)  # some robots have no task
    return grid, free, pos, orient, goals


def drive(ex, grid, free, state, rng, steps, check=None):
    """``ex`` for ``steps`` steps from ``state = (pos, orient, goals)``, every joint action checked valid and reached
    goals re-drawn; ``check(step, pos, orient, act)`` before each action runs.  Returns (robots moved, goals reached)."""
    pos, orient, goals = state
    reached = moved = 0
    for step in range(steps):
        act = ex.actions(pos, orient, goals)
        if check is not None:
            check(step, pos, orient, act)
        pos2, orient, err = apply(grid, pos, orient, act)
        assert err is None, f"step {step}: {err}"
        moved += int((pos2 != pos).sum())
        pos = pos2
        reached += int((pos == goals).sum())
        goals = retarget(rng, free, pos, goals)
    return moved, reached


def retarget(rng, free, pos, goals):
    done = pos == goals
    return np.where(done & (rng.random(len(pos)) < 0.8), rng.choice(free, size=len(pos)), goals)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10**6), h=st.integers(3, 8), w=st.integers(3, 8),
       density=st.floats(0.0, 0.3), fill=st.floats(0.05, 0.9), guidance=st.sampled_from([0, 0, 1, 3]),
       commits=st.booleans())
def test_kernel_equals_recursive_oracle(seed, h, w, density, fill, guidance, commits):
    rng = np.random.default_rng(seed)
    grid, free, pos, orient, goals = random_instance(rng, h, w, density, fill)
    ex = TurningPIBT(grid, seed=seed, guidance=guidance, commits=commits)
    oracle = Oracle(grid, ex.prio.seed, len(pos), guidance, commits)
    for _ in range(12):
        expect, targets = oracle.actions(pos, orient, goals)
        act = ex.actions(pos, orient, goals)
        assert act.tolist() == expect
        assert ex.decider.targets.tolist() == targets
        pos, orient, err = apply(grid, pos, orient, act)
        assert err is None, err
        goals = retarget(rng, free, pos, goals)


@pytest.mark.parametrize("seed", range(6))
def test_dense_crowds_only_get_valid_joint_actions(seed):
    rng = np.random.default_rng(100 + seed)
    h, w = int(rng.integers(10, 21)), int(rng.integers(10, 21))
    grid, free, pos, orient, goals = random_instance(rng, h, w, 0.1 + 0.04 * seed, 0.6)
    budget = {"bfs_budget": 1} if seed % 2 else {}  # odd seeds: one new goal field per call, Manhattan meanwhile
    ex = make_turning_planner("pibt", grid, seed=seed, **budget)
    moved, reached = drive(ex, grid, free, (pos, orient, goals), rng, 150)
    assert moved > 0 and reached > 0


def test_rotation_moves_and_a_robot_behind_a_turn_waits():
    ex = TurningPIBT(np.zeros((2, 2), dtype=bool))  # 0 1 / 2 3: a clockwise rotation, everyone facing along it
    act = ex.actions(np.array([0, 1, 3, 2]), np.array([0, 1, 2, 3]), np.array([1, 3, 2, 0]))
    assert act.tolist() == [F, F, F, F]
    ex = TurningPIBT(np.zeros((2, 3), dtype=bool))  # A at 0 facing east wants 1; B at 1 facing north turns east
    act = ex.actions(np.array([0, 1]), np.array([0, 3]), np.array([1, 2]))
    assert act.tolist() == [W, R]


def test_a_robot_leaving_a_dead_end_overtakes_one_waiting_to_enter():
    grid = np.array([[1, 1, 0, 1, 1], [0, 0, 0, 0, 0]], dtype=bool)  # cell 2 is a dead end above cell 7
    pos, orient, goals = np.array([2, 7]), np.array([1, 3]), np.array([9, 2])  # X out to 9, Y into 2
    ex = TurningPIBT(grid, seed=0, guidance=0)  # X's way east runs against row 1's lane: plain distances here
    ex.prio.order(2)
    ex.prio.elapsed[:] = [0, 50]  # Y first: it cannot push X out (X's only way out is Y's cell)
    for _ in range(20):
        pos, orient, err = apply(grid, pos, orient, ex.actions(pos, orient, goals))
        assert err is None
    assert pos.tolist() == [9, 2]


@pytest.mark.parametrize("bfs_budget", [1 << 24, 1])
def test_robots_reach_their_goals_on_an_open_map(bfs_budget):
    rng = np.random.default_rng(3)
    grid = np.zeros((8, 8), dtype=bool)
    grid[3, 2:6] = True
    free = np.flatnonzero(~grid.reshape(-1))
    cells = rng.choice(free, size=24, replace=False).astype(np.int64)
    pos, goals = cells[:12], cells[12:]
    orient = rng.integers(0, 4, size=12)
    ex = TurningPIBT(grid, seed=5, bfs_budget=bfs_budget)
    for _ in range(120):
        pos, orient, err = apply(grid, pos, orient, ex.actions(pos, orient, goals))
        assert err is None
        if np.array_equal(pos, goals):
            break
    assert np.array_equal(pos, goals)
    assert ex.source.fields.computed == 12 and (ex.source.fields.per_call == 1) == (bfs_budget == 1)


def test_same_seed_same_actions_and_a_small_field_cache_changes_nothing():
    rng = np.random.default_rng(7)
    grid, free, pos0, orient0, goals0 = random_instance(rng, 12, 14, 0.2, 0.4)
    runs = []
    for field_bytes in (1 << 30, 1 << 30, 1):  # the last keeps about one field: recomputed on demand
        ex = TurningPIBT(grid, seed=11, field_bytes=field_bytes)
        r = np.random.default_rng(1)
        pos, orient, goals, seq = pos0, orient0, goals0, []
        for _ in range(40):
            act = ex.actions(pos, orient, goals)
            seq.append(act.tolist())
            pos, orient, _ = apply(grid, pos, orient, act)
            goals = retarget(r, free, pos, goals)
        runs.append(seq)
    assert runs[0] == runs[1] == runs[2]
    assert ex.source.fields.computed > len(np.unique(goals0))  # fields were evicted and recomputed


def test_maps_of_65535_free_cells_or_more_use_uint32_fields():
    grid = np.zeros((256, 256), dtype=bool)
    pos, orient, goals = np.array([0, 300, 65535]), np.array([0, 1, 2]), np.array([5, 300 + 256 * 4, 65535 - 3])
    ex = TurningPIBT(grid, guidance=0)  # plain BFS: a distance may reach the cell count
    assert ex.source.fields.dtype == np.uint32
    for _ in range(12):
        pos, orient, err = apply(grid, pos, orient, ex.actions(pos, orient, goals))
        assert err is None
    assert pos.tolist() == goals.tolist()


def test_bad_input_names_the_value():
    grid = np.zeros((3, 4), dtype=bool)
    grid[1, 1] = True  # cell 5
    ex = TurningPIBT(grid)
    ok = dict(pos=np.array([0, 2]), orient=np.array([0, 1]), goals=np.array([3, 11]))
    cases = [
        (dict(pos=np.array([0])), r"one entry per robot, got lengths 1, 2, 2"),
        (dict(orient=np.array([0, 4])), r"orient\[1\] = 4 is not an orientation 0..3"),
        (dict(orient=np.array([-1, 0])), r"orient\[0\] = -1"),
        (dict(pos=np.array([0, 5])), r"pos\[1\] = 5 \(row 1, col 1\) is a blocked cell"),
        (dict(goals=np.array([5, 1])), r"goals\[0\] = 5 \(row 1, col 1\) is a blocked cell"),
        (dict(pos=np.array([0, 12])), r"pos\[1\] = 12 is off the map \(flat cells 0..11\)"),
        (dict(pos=np.array([2, 2])), r"robots 0 and 1 share cell 2"),
        (dict(pos=np.array([0.5, 2.0])), r"pos must hold integers, got dtype float64"),
    ]
    for change, message in cases:
        with pytest.raises(ValueError, match=message):
            ex.actions(**{**ok, **change})
    for bad in (-1, 17, 2.5, True, "3"):
        with pytest.raises(ValueError, match=rf"guidance = {re.escape(repr(bad))} must be an integer in \[0, 16\]$"):
            TurningPIBT(grid, guidance=bad)
    with pytest.raises(ValueError, match="unknown planner 'cbs'; known: pibt"):
        make_turning_planner("cbs", grid)
    assert TURNING_PLANNERS["pibt"] is ex.kind and isinstance(ex, TurningPlanner) and ex.name == "pibt"


@pytest.mark.parametrize("guidance", [1, 4])
def test_guided_fields_equal_the_lane_cost_oracle(guidance):
    rng = np.random.default_rng(guidance)
    grid = rng.random((7, 9)) < 0.25
    grid[0, 0] = False
    ex = TurningPIBT(grid, guidance=guidance)
    goals = np.arange(len(ex.site.cell_of))
    rows = ex.source.fields.rows(goals, goals)
    for gc, row in zip(goals.tolist(), rows.tolist()):
        want = guided(grid, int(ex.site.cell_of[gc]), guidance)
        got = ex.source.fields.fields[row]
        assert [int(x) for x in got] == [want.get(int(cell), ex.source.fields.far) for cell in ex.site.cell_of]


def test_no_guidance_is_plain_bfs_and_lanes_change_the_route():
    grid = np.zeros((4, 6), dtype=bool)
    plain, lanes = TurningPIBT(grid, guidance=0), TurningPIBT(grid, guidance=3)
    assert plain.source.fields.cost is None and plain.guidance == 0
    # row 1 runs west: going east from (1, 0) to (1, 5) the guided robot leaves its row for row 0 or 2
    pos, orient, goals = np.array([6]), np.array([0]), np.array([11])
    assert plain.actions(pos, orient, goals).tolist() == [F]
    assert lanes.actions(pos, orient, goals).tolist() != [F]


def test_a_one_cell_corridor_has_no_lane_and_big_maps_keep_uint16_guided_fields():
    grid = np.ones((3, 8), dtype=bool)
    grid[1, :] = False  # one corridor, on an odd row (whose lane would run west)
    ex = TurningPIBT(grid, guidance=4)
    assert (ex.source.move_cost[:, [0, 2]] == 1).all()  # east and west alike
    goals = np.array([ex.site.cid[8 + 7]])
    row = ex.source.fields.rows(goals, np.zeros(1, dtype=np.int64))[0]
    assert ex.source.fields.fields[row, ex.site.cid[8]] == 7  # east along the corridor: 7 moves of cost 1
    big = TurningPIBT(np.zeros((300, 300), dtype=bool), guidance=2)
    plain = TurningPIBT(np.zeros((300, 300), dtype=bool), guidance=0)
    assert big.source.fields.dtype == np.uint16 and plain.source.fields.dtype == np.uint32
    row = big.source.fields.rows(np.array([0]), np.zeros(1, dtype=np.int64))[0]
    assert big.source.fields.fields[row].max() < big.source.fields.far  # every cell reached, within the dtype


def shelves(rows=2, bays=5):
    """A warehouse strip: aisles between rows of 3-wide shelves, corridors one cell wide between them, and a
    dead-end pocket (a corridor closed at its south end) on the right."""
    h, w = 3 * rows + 1, 4 * bays + 3
    grid = np.zeros((h, w), dtype=bool)
    for k in range(rows):
        for b in range(bays):
            grid[3 * k + 1:3 * k + 3, 4 * b + 1:4 * b + 4] = True
    grid[1:, w - 2] = True
    grid[h - 1, w - 1] = True
    return grid


@pytest.mark.parametrize("seed", range(6))
def test_one_way_corridors_equal_their_statement(seed):
    from planners.mapf.common import compact_grid
    from planners.mapf.guides.guidance import corridor_costs

    rng = np.random.default_rng(seed)
    grid = shelves(2 + seed % 2, 4 + seed) if seed % 3 == 0 else rng.random((9, 11)) < 0.35
    grid[0, 0] = False
    cid, cell_of, nbr = compact_grid(grid)
    extra = corridor_costs(nbr, cell_of, grid.shape[1], 5)
    want = [[corridor_cost(grid, int(p), d, 5) if nbr[i, d] >= 0 else extra[i, d] for d in range(4)]
            for i, p in enumerate(cell_of)]
    assert extra.tolist() == want
    if seed == 0:  # neighbouring corridors carry opposite ways; the pocket keeps both
        first = [int(cid[1 * grid.shape[1] + 4 * b]) for b in range(1, 4)]
        assert [int(np.argmax(extra[c])) for c in first] == [1, 3, 1]  # runs 1, 2, 3 (column 0 is run 0): an odd
        # run goes north (its south moves cost more), an even one south
        assert (extra[cid[np.flatnonzero(~grid[:, -1]) * grid.shape[1] + grid.shape[1] - 1]] == 0).all()
    assert not corridor_costs(nbr, cell_of, grid.shape[1], 0).any()


@pytest.mark.parametrize("lanes, corridors", [(0, 6), (2, 4)])
def test_corridor_fields_equal_the_dijkstra_oracle_and_robots_keep_the_way(lanes, corridors):
    grid = shelves(2, 5)
    ex = TurningPIBT(grid, guidance=lanes, corridors=corridors)
    goals = np.arange(len(ex.site.cell_of))
    rows = ex.source.fields.rows(goals, goals)
    for gc, row in zip(goals.tolist(), rows.tolist()):
        want = guided(grid, int(ex.site.cell_of[gc]), lanes, corridors)
        f = ex.source.fields
        assert [int(x) for x in f.fields[row]] == [want.get(int(cell), f.far) for cell in ex.site.cell_of]
    for bad in (-1, 17, 1.5, True):
        with pytest.raises(ValueError, match=rf"corridors = {re.escape(repr(bad))} must be an integer in \[0, 16\]$"):
            TurningPIBT(grid, corridors=bad)
