"""The ``ortools`` pipeline: OR-Tools routing solving sharing and tours jointly (real solves, small worlds)."""

import pytest

pytest.importorskip("ortools")

from mrmt_env import generate_world  # noqa: E402
from planners.pipeline import make_pipeline  # noqa: E402
from planners.plan import validate_plan  # noqa: E402

SOLUTIONS = {"solutions": 200, "seconds": None}


def _pipe(**opts):
    return make_pipeline("ortools", sharing_options={**SOLUTIONS, **opts})


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_small_worlds_plan_valid_open_routes_near_the_optimum(seed):
    world = generate_world(seed, n_robots=3, n_targets=10)
    plan = _pipe().plan(world, seed=seed)
    validate_plan(world, plan)
    dist = world.distance_matrix
    total = sum(dist[a, b] for k, route in enumerate(plan.routes)
                for a, b in zip([k] + [3 + t for t in route.targets][:-1], [3 + t for t in route.targets]))
    assert plan.success and total == plan.route_cost == plan.stats["solver"]["cost"]  # open: no way back
    assert plan.route_cost <= 1.05 * make_pipeline("exact").plan(world).route_cost
    assert plan.stats["solver"]["stopped_by"] == "solutions"
    rec = plan.compute.to_record()
    assert rec["chip_calls"] == 0 and rec["accelerator_energy_j"] == 0
    assert rec["host_energy_j"] == pytest.approx(15 * rec["cpu_s"])


def test_same_plan_twice_when_stopped_by_solutions():
    world = generate_world(5, height=20, width=20, n_robots=4, n_targets=30)
    a, b = (_pipe().plan(world, seed=s) for s in (1, 2))  # no seed: the search is deterministic
    assert [r.targets for r in a.routes] == [r.targets for r in b.routes]


def test_time_budget_is_reported_as_the_stop():
    world = generate_world(0, n_robots=2, n_targets=5)
    plan = make_pipeline("ortools", sharing_options={"seconds": 0.05}).plan(world, seed=0)
    assert plan.success and plan.stats["solver"]["stopped_by"] == "time"
