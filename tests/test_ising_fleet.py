"""Fleet routing with chip-selected moves between robots (planners/ising/fleet)."""

import numpy as np
import pytest

from ising_backend import ChipSpec, EmulatedChip
from mrmt_env import generate_world
from planners.ising.fleet import FleetConfig, IsingFleetSharing
from planners.ising.moves.granular import granular_moves as candidate_moves
from planners.ising.moves.kinds import MOVE_KINDS, apply_move
from planners.ising.moves.routes import route_cost, walk
from planners.ising.moves.selection import conflicts
from planners.ising.fleet.recreate import ruin_recreate
from planners.pipeline import make_pipeline
from planners.plan import validate_plan
from planners.sharing_classical import SSASharing


def _lists(groups, r, m):
    nxt, prv = np.full(m, -1, dtype=np.int64), np.full(m, -1, dtype=np.int64)
    for k, g in enumerate(groups):
        x = k
        for t in g:
            nxt[x], prv[r + t] = r + t, x
            x = r + t
    return nxt, prv


def _routes(nxt, r):
    out = []
    for k in range(r):
        g, x = [], nxt[k]
        while x >= 0:
            g.append(int(x))
            x = nxt[x]
        out.append(g)
    return out


def _cost_reference(d, routes, r):
    """The oracle: open route costs summed in Python."""
    return sum(sum(d[a, b] for a, b in zip([k] + g[:-1], g)) for k, g in enumerate(routes))


def _state(seed, r=4, n=24):
    world = generate_world(seed, height=14, width=14, n_robots=r, n_targets=n)
    d = np.ascontiguousarray(world.distance_matrix)
    rng = np.random.default_rng(seed)
    groups = [list(g) for g in np.array_split(rng.permutation(n), r)]  # random routes: many moves
    nxt, prv = _lists(groups, r, d.shape[0])
    order = np.argsort(d[r:], axis=1, kind="stable")
    neigh = np.vstack([np.full((r, 8), -1), order[:, 1:9]]).astype(np.int64)
    return d, r, nxt, prv, neigh


@pytest.mark.parametrize("seed", range(4))
def test_every_gain_is_the_exact_cost_change_and_disjoint_moves_add(seed):
    d, r, nxt, prv, neigh = _state(seed)
    owner, pos, length = walk(nxt, r)
    moves, spans, gains = candidate_moves(d, nxt, prv, owner, pos, length, neigh, r)
    kinds = {MOVE_KINDS[k] for k in moves[:, 0].tolist()}
    assert len(gains) > 20 and kinds == {"or-opt", "swap", "2-opt*", "2-opt"}  # the fleet's four kinds occur
    relocations = moves[moves[:, 0] == MOVE_KINDS.index("or-opt")]
    assert np.array_equal(relocations[:, 1], relocations[:, 2])  # a one-node or-opt
    before = _cost_reference(d, _routes(nxt, r), r)
    for i in range(len(gains)):
        a, b = nxt.copy(), prv.copy()
        apply_move(a, b, *moves[i])
        routes = _routes(a, r)
        assert sorted(sum(routes, [])) == list(range(r, d.shape[0]))  # still every target once
        assert before - _cost_reference(d, routes, r) == pytest.approx(gains[i])
        assert all(b[y] == x for x in range(d.shape[0]) for y in [a[x]] if y >= 0)  # links agree
    clash = conflicts(spans, np.arange(len(gains)))
    rng = np.random.default_rng(seed)
    pairs = [(i, j) for i in range(len(gains)) for j in range(i) if not clash[i, j]]
    for i, j in (pairs[k] for k in rng.choice(len(pairs), size=min(200, len(pairs)), replace=False)):
        a, b = nxt.copy(), prv.copy()
        apply_move(a, b, *moves[i])
        apply_move(a, b, *moves[j])
        assert before - route_cost(d, a, r) == pytest.approx(gains[i] + gains[j])


def test_ruin_recreate_keeps_every_target_once():
    d, r, nxt, prv, _ = _state(7)
    order = np.argsort(d[r:], axis=1, kind="stable")
    for seed_target in range(r, d.shape[0], 5):
        a, b = nxt.copy(), prv.copy()
        ruin_recreate(d, a, b, r, seed_target, order[seed_target - r, 1:], 6, np.arange(6)[::-1].copy())
        routes = _routes(a, r)
        assert sorted(sum(routes, [])) == list(range(r, d.shape[0]))
        assert route_cost(d, a, r) == pytest.approx(_cost_reference(d, routes, r))


def test_plans_are_valid_deterministic_and_decided_on_the_chip():
    world = generate_world(3, height=24, width=24, n_robots=4, n_targets=40)
    pipe = make_pipeline("ising-fleet", sharing_options={"kicks": 60})
    a, b = pipe.plan(world, seed=5), make_pipeline("ising-fleet", sharing_options={"kicks": 60}).plan(world, seed=5)
    validate_plan(world, a)
    assert [r.targets for r in a.routes] == [r.targets for r in b.routes]
    assert a.compute.replace(cpu_s=0.0) == b.compute.replace(cpu_s=0.0)
    fleet = a.stats["fleet"]
    assert a.compute.chip_calls == fleet["reads"] == pipe.sharing.chip.ledger.physical_calls > 0
    assert a.compute.accelerator_energy_j == pytest.approx(pipe.sharing.chip.ledger.energy_j)
    assert a.compute.accelerator_energy_j > 0
    assert fleet["moves_applied"] > 0 and fleet["contested_rounds"] > 0
    assert a.route_cost == fleet["cost"] <= fleet["ssa_cost"]  # field legs: the plan costs what the search priced
    assert a.stats["layers"]["path"].chip_calls == 0


def test_one_robot_and_options():
    world = generate_world(1, n_robots=1, n_targets=10)
    plan = make_pipeline("ising-fleet").plan(world, seed=0)
    assert plan.success and plan.route_cost == make_pipeline("exact").plan(world).route_cost
    with pytest.raises(ValueError, match="kicks = -1"):
        FleetConfig(kicks=-1)
    with pytest.raises(ValueError, match="ruin = 1"):
        IsingFleetSharing(ruin=1)


def test_a_dead_chip_keeps_the_routes_found_so_far_flagged():
    from ising_backend import ChipSpec, EmulatedChip

    world = generate_world(3, height=24, width=24, n_robots=4, n_targets=40)
    plan = make_pipeline("ising-fleet", chip=EmulatedChip(ChipSpec(dead_cores=8)), kicks=20).plan(world, seed=0)
    assert plan.success and plan.stats["fallback"] == {"sharing": 1} and plan.compute.fallbacks == 1
    assert "every core is quarantined" in plan.stats["fallback_reasons"][0]
    assert plan.route_cost == plan.stats["fleet"]["ssa_cost"] and plan.stats["fleet"]["moves_applied"] == 0
    never = make_pipeline("ising-fleet", chip=EmulatedChip(ChipSpec(dead_cores=8)), fallback="never", kicks=20)
    failed = never.plan(world, seed=0)
    assert not failed.success and "the chip could not answer" in failed.failure


def test_preset_ising_hands_worlds_above_the_crossover_to_the_fleet_search_on_its_own_chip():
    from ising_backend import ChipSpec, EmulatedChip
    from planners.pipeline import FLEET_ABOVE

    big = generate_world(4, height=24, width=24, n_robots=4, n_targets=FLEET_ABOVE + 1)
    chip = EmulatedChip(ChipSpec())
    plan = make_pipeline("ising", chip=chip).plan(big, seed=3)
    fleet = make_pipeline("ising-fleet").plan(big, seed=3)
    assert plan.stats["planned_by"] == "ising-fleet" and "fleet" in plan.stats
    assert [r.targets for r in plan.routes] == [r.targets for r in fleet.routes]
    assert plan.compute.chip_calls == chip.ledger.physical_calls > 0  # charged to the preset's chip
    # at the crossover and below, and with layer options at any size: the paper-derived layers
    small = generate_world(4, height=24, width=24, n_robots=4, n_targets=FLEET_ABOVE)
    assert "planned_by" not in make_pipeline("ising").plan(small, seed=3).stats
    optioned = make_pipeline("ising", tour_options={"num_reads": 1}).plan(big, seed=3)
    assert "planned_by" not in optioned.stats and "fleet" not in optioned.stats


def test_small_worlds_are_not_under_searched():
    """Ruins of up to two routes' worth (at least 5) and at least 3 N kicks on small worlds: on 60
    paper worlds the fleet search finds the exact optimum on all 60 (with 2-target ruins and
    5 N kicks, an old default: 50)."""
    worlds = [generate_world(2000 + s, n_robots=3, n_targets=10) for s in range(60)]
    exact = [make_pipeline("exact").plan(w).route_cost for w in worlds]
    pipe = make_pipeline("ising-fleet")
    hits = sum(pipe.plan(w, seed=s).route_cost == e for s, (w, e) in enumerate(zip(worlds, exact)))
    assert hits >= 58


def _open_routes_cost(d, r, assignment):
    """The oracle of a sharing result that orders its groups: robot ``k`` visits its group's targets in
    the order listed (open routes), summed in Python from the distance matrix."""
    total = 0.0
    for k, group in enumerate(assignment):
        nodes = [k] + [r + int(t) for t in group]
        total += sum(float(d[a, b]) for a, b in zip(nodes, nodes[1:]))
    return total


def _fleet_cases():
    """Two world distance matrices (integer BFS costs) and two Euclidean ones (real costs)."""
    cases = []
    for s in range(2):
        w = generate_world(300 + s, height=16, width=16, n_robots=3, n_targets=18)
        cases.append((np.ascontiguousarray(w.distance_matrix), 3))
    for s in range(2):
        pts = np.random.default_rng(40 + s).random((4 + 20, 2)) * 30.0
        cases.append((np.sqrt(((pts[:, None] - pts[None]) ** 2).sum(-1)), 4))
    return cases


def test_the_search_returns_the_cheapest_routes_it_visited():
    """The search keeps the cheapest solution it has visited (pins the best-update and acceptance
    comparisons of the iterated local search).

    Under one seed a run of ``K`` kicks visits a prefix of a run of ``K + 1`` kicks (the first local
    search, then one kick after another, same draws), so the costs returned for ``K = 0, 1, 2, ...``
    are the search's best-so-far trace: never rising, at or below the SSA routes it starts from.
    Each returned cost is recomputed here from the routes and the distance matrix.  A slack of 5 %
    makes the record-to-record travel accept worse solutions, so the current routes often differ from
    the best ones."""
    ssa_gain = kick_gain = 0
    for case, (d, r) in enumerate(_fleet_cases()):
        exact = bool(np.all(d == np.round(d)))  # integer costs: every sum is exact
        start = SSASharing().assign(d, r)
        ssa_cost = _open_routes_cost(d, r, start.assignment)
        trace = []
        for kicks in range(0, 21):
            res = IsingFleetSharing(EmulatedChip(ChipSpec()), kicks=kicks, slack=0.05).assign(
                d, r, rng=np.random.default_rng(case))
            assert res.success and sorted(t for g in res.assignment for t in g) == list(range(d.shape[0] - r))
            cost = _open_routes_cost(d, r, res.assignment)
            fleet = res.stats["fleet"]
            if exact:
                assert cost == fleet["cost"] and fleet["ssa_cost"] == ssa_cost
            else:
                assert cost == pytest.approx(fleet["cost"], rel=1e-12, abs=0)
                assert fleet["ssa_cost"] == pytest.approx(ssa_cost, rel=1e-12, abs=0)
            assert cost <= ssa_cost + 1e-9, f"case {case}, {kicks} kicks: worse than the SSA start"
            if kicks == 0 and fleet["moves_applied"] > 0:  # every applied move has a positive gain
                assert cost < ssa_cost - 1e-9, f"case {case}: the local search's improvement was not kept"
            trace.append(cost)
        assert all(b <= a + 1e-9 for a, b in zip(trace, trace[1:])), f"case {case}: best-so-far rose: {trace}"
        ssa_gain += trace[0] < ssa_cost - 1e-9
        kick_gain += trace[-1] < trace[0] - 1e-9
    assert ssa_gain >= 1 and kick_gain >= 1  # the local search and the kicks both found better routes


@pytest.mark.parametrize("seed,selection_rules", [(0, ("linear", "rank")), (1, ("linear",)), (2, ("rank", "sqrt"))])
def test_the_compiled_search_makes_the_python_references_decisions(seed, selection_rules):
    """The compiled iterated search against the plain Python loop of tests/fleet_reference.py: the same routes,
    the same chip calls and rounds (its own candidate listing, pick, QUBO and scoring; the same draws)."""
    from fleet_reference import reference_fleet

    world = generate_world(seed, height=14, width=14, n_robots=3, n_targets=18)
    d = world.distance_matrix
    cfg = FleetConfig(kicks=12, chip_rules=selection_rules, neighbours=6)
    chip, ref_chip = EmulatedChip(ChipSpec()), EmulatedChip(ChipSpec())
    got = IsingFleetSharing(chip, cfg).assign(d, 3, rng=np.random.default_rng(seed))
    want, stats = reference_fleet(d, 3, cfg, ref_chip, np.random.default_rng(seed))
    assert list(got.assignment) == want
    assert got.stats["fleet"]["rounds"] == stats["rounds"] > 0
    assert chip.ledger.physical_calls == ref_chip.ledger.physical_calls == got.compute.chip_calls > 0
