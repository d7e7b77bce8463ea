"""The ``pyvrp`` pipeline: PyVRP solving sharing and tours jointly (real solves, small worlds)."""

import json

import numpy as np
import pytest

pytest.importorskip("pyvrp")

from agents.cli import main  # noqa: E402
from agents.controllers import make_controller  # noqa: E402
from mrmt_env import generate_world  # noqa: E402
from mrmt_env.io import write_worlds  # noqa: E402
from planners.joint_routing import KeepOrderTour  # noqa: E402
from planners.peers.pyvrp_routing import routing_data  # noqa: E402
from planners.pipeline import make_pipeline  # noqa: E402
from planners.plan import validate_plan  # noqa: E402

ITERS = {"iterations": 300, "seconds": None}


def _pipe(**opts):
    return make_pipeline("pyvrp", sharing_options={**ITERS, **opts})


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_small_worlds_reach_the_exact_optimum(seed):
    world = generate_world(seed, n_robots=3, n_targets=10)
    plan = _pipe().plan(world, seed=seed)
    validate_plan(world, plan)
    assert plan.success and plan.route_cost == make_pipeline("exact").plan(world).route_cost
    solver = plan.stats["solver"]
    assert solver == {"name": "pyvrp", "stopped_by": "iterations", "iterations": 300, "cost": plan.route_cost}
    # classical accounting: no accelerator, host seconds x 15 W
    rec = plan.compute.to_record()
    assert rec["chip_calls"] == 0 and rec["accelerator_energy_j"] == 0 and rec["cpu_s"] > 0
    assert rec["host_energy_j"] == pytest.approx(15 * rec["cpu_s"])
    assert plan.stats["layers"]["tour"].cpu_s < plan.stats["layers"]["sharing"].cpu_s


def test_same_seed_same_plan_when_stopped_by_iterations():
    world = generate_world(5, height=20, width=20, n_robots=4, n_targets=30)
    a, b = (_pipe().plan(world, seed=9) for _ in range(2))
    assert [r.targets for r in a.routes] == [r.targets for r in b.routes]
    assert all(np.array_equal(x.path, y.path) for x, y in zip(a.routes, b.routes))


def test_routes_are_pyvrps_order_and_open():
    world = generate_world(3, height=16, width=16, n_robots=3, n_targets=20)
    plan = _pipe().plan(world, seed=0)
    dist = world.distance_matrix
    total = 0
    for k, route in enumerate(plan.routes):
        nodes = [k] + [world.n_robots + t for t in route.targets]
        total += sum(dist[a, b] for a, b in zip(nodes[:-1], nodes[1:]))  # open: no way back
    assert total == plan.route_cost == plan.stats["solver"]["cost"]


def test_one_robot_is_routed_by_pyvrp_not_by_index_order():
    world = generate_world(4, n_robots=1, n_targets=10)
    plan = _pipe().plan(world, seed=0)
    assert "solver" in plan.stats
    assert plan.route_cost == make_pipeline("exact").plan(world).route_cost


def test_time_budget_is_reported_as_the_stop():
    world = generate_world(0, n_robots=2, n_targets=5)
    plan = make_pipeline("pyvrp", sharing_options={"seconds": 0.02}).plan(world, seed=0)
    assert plan.success and plan.stats["solver"]["stopped_by"] == "time"
    both = make_pipeline("pyvrp", sharing_options={"seconds": 60, "iterations": 50}).plan(world, seed=0)
    assert both.stats["solver"]["stopped_by"] == "iterations" and both.stats["solver"]["iterations"] == 50


def test_model_forbids_arcs_into_start_and_out_of_the_dummy():
    dist = generate_world(0, n_robots=2, n_targets=3).distance_matrix
    m = routing_data(dist, 2).distance_matrix(0)
    big = m.max()
    assert (m[:, 2] == 0).all()  # every location -> dummy end depot: free
    assert (m[2, [0, 1, 3, 4, 5]] == big).all() and m[3, 0] == big and m[0, 1] == big
    assert m[0, 3] == dist[0, 2] and m[4, 5] == dist[3, 4]


def test_keep_tour_keeps_the_order():
    d = np.array([[0, 5, 1], [5, 0, 4], [1, 4, 0]], dtype=float)
    res = KeepOrderTour().solve(d)
    assert res.order == (1, 2) and res.cost == 9


def test_cli_plan_writes_the_solver_record(tmp_path, capsys):
    src = tmp_path / "w.jsonl"
    write_worlds([generate_world(s, n_robots=2, n_targets=6) for s in range(2)], src)
    argv = ["plan", str(src), "--pipeline", "pyvrp", "--option", "sharing.iterations=100",
            "--option", "sharing.seconds=null"]
    assert main(argv) == 0
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert [d["solver"]["stopped_by"] for d in lines] == ["iterations"] * 2
    assert all(d["success"] and d["compute"]["chip_calls"] == 0 for d in lines)
    assert main(argv[:-2] + ["--option", "sharing.seconds=-1"]) == 2
    assert "seconds must be a number" in capsys.readouterr().err


def test_controller_runs_in_the_env():
    import gymnasium as gym

    import mrmt_env  # noqa: F401

    env = gym.make("mrmt_env/MRMT-v0")
    obs, _ = env.reset(seed=0)
    policy = make_controller("pyvrp", seed=0, env_id="mrmt_env/MRMT-v0")
    done = False
    while not done:
        action, _ = policy.predict(obs)
        obs, _, term, trunc, info = env.step(action)
        done = term or trunc
    assert info["is_success"]
