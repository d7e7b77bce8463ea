"""What the two peer routing layers (PyVRP, OR-Tools) share: components, unreachable targets,
budgets, and the one-line error without the extra (real solves, small worlds)."""

import importlib
import subprocess
import sys

import numpy as np
import pytest

from mrmt_env import generate_world
from mrmt_env.io import write_worlds
from mrmt_env.world import World
from planners.joint_routing import KeepOrderTour
from planners.pipeline import make_pipeline
from planners.plan import validate_plan

#: preset -> (package, layer class path, a deterministic budget, its count option)
PEERS = {"pyvrp": ("pyvrp", "planners.peers.pyvrp_routing:PyVRPSharing", {"iterations": 300, "seconds": None},
                   "iterations"),
         "ortools": ("ortools", "planners.peers.ortools_routing:ORToolsSharing", {"solutions": 200, "seconds": None},
                     "solutions")}


def _layer(preset):
    package, path, budget, count = PEERS[preset]
    pytest.importorskip(package)
    module, _, name = path.partition(":")
    return getattr(importlib.import_module(module), name), budget, count


@pytest.mark.parametrize("preset", PEERS)
def test_preset_layers(preset):
    from agents.controllers import uses_chip, validate_controller_spec

    layer, _budget, count = _layer(preset)
    p = make_pipeline(preset)
    assert isinstance(p.sharing, layer) and isinstance(p.tour, KeepOrderTour)
    assert p.sharing.seconds == 1.0 and getattr(p.sharing, count) is None and p.name == preset
    assert not uses_chip(preset) and validate_controller_spec(preset) == preset


@pytest.mark.parametrize("preset", PEERS)
def test_separated_components_keep_each_robot_on_its_side(preset):
    _, budget, _ = _layer(preset)
    grid = np.zeros((5, 9), dtype=bool)
    grid[:, 4] = True  # a wall: two components
    world = World(grid, robots=[[0, 0], [0, 8]], targets=[[4, 0], [2, 2], [4, 8], [1, 6], [3, 3]])
    plan = make_pipeline(preset, sharing_options=budget).plan(world, seed=0)
    validate_plan(world, plan)
    assert sorted(plan.routes[0].targets) == [0, 1, 4] and sorted(plan.routes[1].targets) == [2, 3]


@pytest.mark.parametrize("preset", PEERS)
def test_a_target_no_robot_reaches_is_a_failure_not_an_exception(preset):
    layer, budget, _ = _layer(preset)
    dist = np.array([[0, np.inf, 3], [np.inf, 0, np.inf], [3, np.inf, 0]], dtype=float)
    res = layer(**budget).assign(dist, 1, KeepOrderTour(), np.random.default_rng(0))
    assert not res.success and "targets [0]" in res.failure
    with pytest.raises(ValueError, match="n_robots must be an integer in 1..3"):
        layer(**budget).assign(dist, 4, KeepOrderTour(), np.random.default_rng(0))


@pytest.mark.parametrize("preset", PEERS)
@pytest.mark.parametrize("opts, message", [
    ({"seconds": 0}, "{p} seconds must be a number in (0, 3600]"),
    ({"seconds": float("nan")}, "got nan"),
    ({"COUNT": 0}, "{p} COUNT must be an integer >= 1"),
    ({"seconds": None}, "{p} needs a budget: seconds, COUNT or both"),
])
def test_bad_budgets_name_the_value(preset, opts, message):
    layer, _, count = _layer(preset)
    opts = {count if k == "COUNT" else k: v for k, v in opts.items()}
    message = message.replace("{p}", preset).replace("COUNT", count)
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace("]", r"\]")):
        layer(**opts)


@pytest.mark.parametrize("preset", PEERS)
def test_without_the_package_the_error_names_the_extra(preset, tmp_path):
    src = tmp_path / "w.json"
    write_worlds([generate_world(0)], src)
    code = (f"import sys; sys.modules[{PEERS[preset][0]!r}] = None; from agents.cli import main; "
            f"sys.exit(main(['plan', {str(src)!r}, '--pipeline', {preset!r}]))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 2
    (line,) = out.stderr.strip().splitlines()
    assert "pip install 'mrmt-ising[peers]'" in line
