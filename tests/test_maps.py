"""Map families (mrmt_env.maps through generate_world): determinism, structure, placement, limits, ids, files.

check_env, determinism, rendering and pickling of every registered id (the new ones included) run in
tests/test_registry_envs.py; the native vector envs against single envs in tests/test_vector_envs.py.
"""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from fuzzing import one_line
from hypothesis import given, settings
from hypothesis import strategies as st

import mrmt_env
from mrmt_env import World, generate_world
from mrmt_env.core import MAX_GRID_ENV_CELLS
from mrmt_env.distances import component_labels
from mrmt_env.generation import MAX_FIELD_CELLS, MAX_GRID_CELLS, _largest_component, draw_budget
from mrmt_env.io import example_map_path, example_world_path, world_from_dict
from mrmt_env.movingai import (octile_distance_field, read_movingai_map, read_movingai_scen, world_from_movingai,
                               write_movingai_map, write_movingai_scen)
from mrmt_env.maps import LAYOUT_OPTIONS, build_layout

FAMILIES = ("warehouse", "rooms", "maze")
DATA = Path(__file__).resolve().parents[1] / "examples" / "data"
NEW_IDS = ("mrmt_env/MRMT-64x64-v0", "mrmt_env/MRMT-Warehouse-v0", "mrmt_env/MRMT-Rooms-v0", "mrmt_env/MRMT-Maze-v0",
           "mrmt_env/MRMT-Warehouse-128x128-v0", "mrmt_env/MRMT-Assign-Warehouse-v0")


def _edges(free: np.ndarray) -> int:
    """4-neighbour edges between free cells."""
    return int((free[1:] & free[:-1]).sum() + (free[:, 1:] & free[:, :-1]).sum())


def _one_component(grid: np.ndarray) -> bool:
    return len(component_labels(grid)[1]) == 1


def _check_placement(w: World, n_robots: int, n_targets: int) -> None:
    assert w.n_robots == n_robots and w.n_targets == n_targets
    cells = [tuple(c) for c in w.nodes.tolist()]
    assert len(set(cells)) == len(cells), "robots and targets on pairwise distinct cells"
    assert not w.grid[w.nodes[:, 0], w.nodes[:, 1]].any(), "on free cells"
    comp = w.distance_field(w.robots[0]) >= 0
    assert comp[w.nodes[:, 0], w.nodes[:, 1]].all(), "all in one 4-connected component"
    assert np.isfinite(w.distance_matrix).all()


# ------------------------------------------------------------- every family
@settings(max_examples=40, deadline=None)
@given(layout=st.sampled_from(FAMILIES), seed=st.integers(0, 2**32 - 1), h=st.integers(16, 40),
       w=st.integers(16, 40), n_robots=st.integers(1, 6), n_targets=st.integers(0, 30),
       placement=st.sampled_from(["uniform", "centre"]))
def test_families_place_everything_on_one_component_deterministically(layout, seed, h, w, n_robots, n_targets,
                                                                       placement):
    kw = dict(height=h, width=w, n_robots=n_robots, n_targets=n_targets, placement=placement, layout=layout)
    world = generate_world(seed, **kw)
    assert world.shape == (h, w)
    _check_placement(world, n_robots, n_targets)
    assert _one_component(world.grid), "every free cell of a family's map is reachable"
    assert generate_world(seed, **kw) == world  # a pure function of its arguments
    rng_a, rng_b = np.random.default_rng(seed), np.random.default_rng(seed)
    assert generate_world(rng_a, **kw) == generate_world(rng_b, **kw)
    assert rng_a.integers(1 << 40) == rng_b.integers(1 << 40)  # generators advanced alike


@pytest.mark.parametrize("layout", FAMILIES)
def test_seeds_give_different_worlds(layout):
    worlds = {generate_world(s, height=24, width=24, layout=layout, n_robots=3, n_targets=10) for s in range(10)}
    assert len(worlds) == 10


def test_shipped_maps_are_the_generators_output():
    """Golden worlds: the MovingAI files in examples/data were written from these calls, so a platform or
    numpy version that drew differently fails here."""
    for family, h, w, robots, targets in (("warehouse", 32, 32, 10, 100), ("rooms", 24, 24, 5, 40),
                                          ("maze", 31, 31, 5, 40)):
        name = f"{family}_{h}x{w}"
        shipped = world_from_movingai(DATA / f"{name}.map", DATA / f"{name}.scen", n_robots=robots,
                                      n_targets=targets)
        assert shipped == generate_world(0, height=h, width=w, n_robots=robots, n_targets=targets, layout=family)


#: generate_world(0) and generate_world(7, placement="centre") as drawn before the map families existed
GOLDEN = [
    ({}, {"grid": [".@.@..@...", ".....@....", "..@...@...", "..........", "..@...@...", "..@@.@.@.@", ".@......@.",
                   "@..@......", "...@......", "..@@......"],
          "robots": [[3, 3], [3, 4], [4, 7]],
          "targets": [[0, 2], [1, 1], [6, 2], [6, 3], [3, 6], [0, 0], [2, 4], [9, 5], [7, 7], [9, 0]]}),
    ({"placement": "centre"},
     {"grid": ["@...@.....", ".@@......@", ".....@.@..", "..........", "......@@.@", ".@....@...", "......@...",
               "..@..@@.@.", "@...@.....", ".......@.."],
      "robots": [[4, 3], [6, 3], [5, 5]],
      "targets": [[4, 8], [7, 7], [0, 5], [5, 4], [0, 3], [1, 0], [3, 9], [1, 4], [4, 2], [9, 5]]}),
]


def test_default_world_and_uniform_draws_unchanged():
    for (kwargs, golden), seed in zip(GOLDEN, (0, 7)):
        assert generate_world(seed, **kwargs) == world_from_dict(golden)
    assert generate_world(0, n_robots=3, n_targets=10) == generate_world(0, layout="uniform", obstacle_density=0.2)
    assert generate_world(5, placement="centre") == generate_world(5, placement="centre", layout_options={})


# ---------------------------------------------------------------- warehouse
@pytest.mark.parametrize("size", [32, 48, 64, 100, 128])
def test_warehouse_structure(size):
    o = LAYOUT_OPTIONS["warehouse"]
    w = generate_world(3, height=size, width=size, layout="warehouse", n_robots=10, n_targets=100)
    grid = w.grid
    # documented range of the default warehouse from 32 x 32 up
    assert 0.25 <= grid.mean() <= 0.45
    # the border is free; every shelf block is a shelf_depth x shelf_length rectangle
    m = o["margin"]
    assert not grid[:m].any() and not grid[-m:].any() and not grid[:, :m].any() and not grid[:, -m:].any()
    labels, sizes = component_labels(~grid)
    assert (sizes == o["shelf_depth"] * o["shelf_length"]).all()
    for k in range(len(sizes)):
        rows, cols = np.nonzero(labels == k)
        assert np.ptp(rows) + 1 == o["shelf_depth"] and np.ptp(cols) + 1 == o["shelf_length"]
    assert _one_component(grid)
    # targets on pick cells (beside a shelf), robots elsewhere
    def beside(r, c):
        return any(0 <= r + dr < size and 0 <= c + dc < size and grid[r + dr, c + dc]
                   for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)))
    assert all(beside(r, c) for r, c in w.targets.tolist())
    assert not any(beside(r, c) for r, c in w.robots.tolist())


def test_warehouse_options_shape_the_map():
    narrow = generate_world(0, height=40, width=40, layout="warehouse", n_robots=2, n_targets=5,
                            layout_options={"aisle_width": 1, "shelf_depth": 2, "cross_aisle_width": 1})
    wide = generate_world(0, height=40, width=40, layout="warehouse", n_robots=2, n_targets=5,
                          layout_options={"aisle_width": 3})
    assert narrow.grid.mean() > wide.grid.mean()
    # the layout itself is fixed for given sizes: seeds only move robots and targets
    a = generate_world(1, height=40, width=40, layout="warehouse", n_robots=2, n_targets=5)
    b = generate_world(2, height=40, width=40, layout="warehouse", n_robots=2, n_targets=5)
    assert np.array_equal(a.grid, b.grid) and a != b


# -------------------------------------------------------------------- rooms
def _rooms_grid(seed, size, **options):
    return build_layout("rooms", np.random.default_rng(seed), size, size, options).grid


@pytest.mark.parametrize("seed", range(5))
def test_rooms_every_room_reachable_and_tree_doors(seed):
    size, room = 40, 7
    grid = _rooms_grid(seed, size, room_size=room, extra_doors=0.0)
    assert _one_component(grid), "every room reachable"
    walls = [i for i in range(size) if grid[i].sum() > size // 2]  # wall rows (doors leave most cells)
    k = len(walls) + 1
    assert k == (size + 1) // (room + 1)
    # room interiors: at least room_size free cells a side
    bounds = [-1] + walls + [size]
    assert min(b - a - 1 for a, b in zip(bounds, bounds[1:])) >= room
    # without extra doors the doors form a spanning tree of the k x k rooms: k*k - 1 doors of width 1
    wall_cols = [j for j in range(size) if grid[:, j].sum() > size // 2]
    assert wall_cols == walls
    on_walls = np.zeros_like(grid)
    on_walls[walls, :] = True
    on_walls[:, walls] = True
    assert int((on_walls & ~grid).sum()) == k * k - 1
    every = _rooms_grid(seed, size, room_size=room, extra_doors=1.0, door_width=2)
    assert int((on_walls & ~every).sum()) == 2 * 2 * k * (k - 1)  # a door of width 2 in every shared wall


def test_rooms_one_room_when_rooms_do_not_fit():
    assert not _rooms_grid(0, 6, room_size=7).any()


# --------------------------------------------------------------------- maze
@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), h=st.integers(1, 45), w=st.integers(1, 45))
def test_perfect_maze_is_a_tree(seed, h, w):
    grid = build_layout("maze", np.random.default_rng(seed), h, w).grid
    free = ~grid
    nodes = int(free.sum())
    assert nodes == 2 * ((h + 1) // 2) * ((w + 1) // 2) - 1
    assert _one_component(grid) and _edges(free) == nodes - 1, "free cells form a tree"
    assert not free[1::2, 1::2].any(), "corridors one cell wide"


@pytest.mark.parametrize("loops", [0.1, 0.5, 1.0])
def test_maze_loops_open_walls(loops):
    n_r = n_c = 16
    grid = build_layout("maze", np.random.default_rng(4), 31, 31, {"loops": loops}).grid
    free = ~grid
    inner_walls = n_r * (n_c - 1) + (n_r - 1) * n_c
    opened = int(round(loops * (inner_walls - (n_r * n_c - 1))))
    assert _one_component(grid)
    assert _edges(free) - (int(free.sum()) - 1) == opened  # one opened wall: one node, two edges, one cycle


# ------------------------------------------------------------ bad arguments
@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(layout="forest"), r"layout must be one of \('uniform', 'warehouse', 'rooms', 'maze'\), got 'forest'"),
        (dict(layout="maze", obstacle_density=0.2), "obstacle_density=0.2 applies to layout 'uniform' only"),
        (dict(layout="rooms", layout_options={"room": 5}), r"unknown layout_options \['room'\] for layout 'rooms'"),
        (dict(layout_options={"loops": 0.1}), r"unknown layout_options \['loops'\] for layout 'uniform'"),
        (dict(layout="maze", layout_options={"loops": 1.5}), r"loops must be a number in \[0, 1\], got 1.5"),
        (dict(layout="maze", layout_options={"loops": float("nan")}), "loops must be a number in"),
        (dict(layout="rooms", layout_options={"room_size": 0}), r"room_size must be an integer in \[1, 2048\]"),
        (dict(layout="rooms", layout_options={"door_width": 2.5}), "door_width must be an integer"),
        (dict(layout="warehouse", layout_options={"aisle_width": True}), "aisle_width must be an integer"),
        (dict(layout="rooms", layout_options=[("room_size", 3)]), "layout_options must be a dict or None"),
        (dict(layout="warehouse"), "needs height >= 6 and width >= 14, got 10x10"),
        (dict(layout="warehouse", height=20, width=20, n_targets=500),
         r"3 robots \+ 500 targets do not fit this 20x20 warehouse map: it has \d+ target \(pick\) cells"),
        (dict(layout="maze", height=5, width=5, n_targets=20), "need 23 distinct free cells, but this 5x5 maze"),
        (dict(height=4096, width=2048), f"at most {MAX_GRID_CELLS} \\(MAX_GRID_CELLS"),
        (dict(height=2048, width=2048, n_targets=100), f"at most {MAX_FIELD_CELLS} \\(MAX_FIELD_CELLS.*at most 32"),
        (dict(height=True), "height must be an integer >= 1, got True"),
        (dict(n_targets=float("inf")), "n_targets must be an integer >= 0, got inf"),
        (dict(n_targets=10**400), r"\(MAX_FIELD_CELLS, 512 MiB\)"),
    ],
)
def test_bad_arguments_are_one_line_errors(kwargs, match):
    with pytest.raises(ValueError, match=match) as info:
        generate_world(0, **kwargs)
    one_line(info.value)


def test_hopeless_uniform_density_gives_up_within_its_budget():
    assert draw_budget(100) == 10_000 and draw_budget(64 * 64) == 4096 and draw_budget(2048 * 2048) == 100
    with pytest.raises(ValueError, match=r"in 1024 tries \(draw_budget\); lower the density") as info:
        generate_world(0, height=128, width=128, obstacle_density=0.6, n_robots=2, n_targets=50)
    one_line(info.value)


def test_largest_component_is_the_first_largest():
    tie = _largest_component(np.array([[0, 0, 0, 1, 0, 0, 0]], dtype=bool))
    assert tie.tolist() == [[True, True, True, False, False, False, False]]
    grid = np.array([[0, 1, 0, 0], [0, 1, 1, 1], [1, 1, 0, 0], [0, 0, 1, 0]], dtype=bool)
    comp = _largest_component(grid)  # components of 2, 2, 3 and 2 cells
    assert comp.sum() == 3 and comp[2, 2] and comp[2, 3] and comp[3, 3]
    assert not _largest_component(np.ones((3, 3), dtype=bool)).any()


# ---------------------------------------------------------------- the envs
def test_envs_take_the_layout():
    env = gym.make("mrmt_env/MRMT-v0", layout="rooms", height=20, width=30, n_robots=4, n_targets=12,
                   layout_options={"room_size": 5})
    env.reset(seed=1)
    world = env.unwrapped.world
    assert world.shape == (20, 30) and world.n_robots == 4 and _one_component(world.grid)
    pz = mrmt_env.parallel_env(layout="maze", height=15, width=15, n_robots=2, n_targets=4)
    pz.reset(seed=0)
    assert _edges(~pz.world.grid) == int((~pz.world.grid).sum()) - 1
    assign = gym.make("mrmt_env/MRMT-Assign-v0", layout="warehouse", height=20, width=20, n_robots=2, n_targets=6)
    obs, info = assign.reset(seed=0)
    assert obs.shape == (8, 14) and info["action_mask"][:6].all()


@pytest.mark.parametrize(
    "env_id, kwargs, match",
    [
        ("mrmt_env/MRMT-Warehouse-v0", dict(obstacle_density=0.1), "applies to layout 'uniform' only"),
        ("mrmt_env/MRMT-Warehouse-v0", dict(layout_options={"aisle": 1}), "unknown layout_options"),
        ("mrmt_env/MRMT-v0", dict(layout="cave"), "layout must be one of"),
        ("mrmt_env/MRMT-v0", dict(height=1025, width=1024), f"at most {MAX_GRID_ENV_CELLS} \\(MAX_GRID_ENV_CELLS"),
        ("mrmt_env/MRMT-Assign-v0", dict(height=4096, width=1025), "MAX_GRID_CELLS"),
        ("mrmt_env/MRMT-v0", dict(world=str(example_world_path()), layout="maze"),
         "only applies to generated worlds"),
    ],
)
def test_env_arguments_are_checked(env_id, kwargs, match):
    with pytest.raises(ValueError, match=match) as info:
        gym.make(env_id, **kwargs)
    one_line(info.value)
    with pytest.raises(ValueError, match=match):
        gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", **kwargs)


def test_new_ids_are_registered_with_their_worlds():
    assert set(NEW_IDS) <= set(gym.registry)
    for env_id in NEW_IDS:
        spec = gym.spec(env_id)
        assert spec.kwargs["height"] >= 64 and spec.kwargs["n_robots"] >= 10 and spec.kwargs["n_targets"] >= 100
    assert gym.spec("mrmt_env/MRMT-v0").kwargs == {}  # the paper's id is unchanged


@pytest.mark.parametrize("env_id", NEW_IDS)
def test_strong_pipeline_episode_succeeds(env_id):
    from agents.evaluation import evaluate
    from agents.runner import RunConfig

    rows = evaluate(["strong"], env_id=env_id, n_worlds=1, warmup=False,
                    run=RunConfig.from_jobs(1, progress=False)).rows
    assert [r["is_success"] for r in rows] == [True]
    assert rows[0]["steps"] <= gym.spec(env_id).max_episode_steps


# ---------------------------------------------------------- MovingAI files
@pytest.mark.parametrize("name, robots, targets", [("warehouse_32x32", 10, 100), ("rooms_24x24", 5, 40),
                                                   ("maze_31x31", 5, 40)])
def test_example_maps_load_and_plan(name, robots, targets):
    from agents.policy import PlannerPolicy
    from mrmt_env.grid.env import MRMTEnv

    grid = read_movingai_map(DATA / f"{name}.map")
    scen = read_movingai_scen(DATA / f"{name}.scen")
    assert len(scen) == max(robots, targets) and all(s.map == f"{name}.map" for s in scen)
    for s in scen[:5]:  # the recorded 8-neighbour optimum is MovingAI's octile length
        assert s.optimal_length_8conn == pytest.approx(octile_distance_field(grid, s.start)[s.goal], abs=1e-6)
        assert s.bfs_length(grid) >= s.optimal_length_8conn
    world = world_from_movingai(DATA / f"{name}.map", DATA / f"{name}.scen", n_robots=robots, n_targets=targets)
    env = MRMTEnv(world=world, max_episode_steps=2000)
    policy = PlannerPolicy("strong", seed=0)
    obs, info = env.reset(seed=0)
    done, start = False, True
    while not done:
        action, _ = policy.predict(obs, episode_start=start)
        start = False
        obs, _, terminated, truncated, info = env.step(action)
        done = terminated or truncated
    assert info["is_success"] and info["route_cost"] == policy.episode_plans()[0].route_cost


def test_packaged_map_is_the_example_warehouse():
    assert example_map_path().read_text() == (DATA / "warehouse_32x32.map").read_text()
    assert example_map_path(scen=True).read_text() == (DATA / "warehouse_32x32.scen").read_text()


def test_movingai_writers_round_trip(tmp_path):
    for layout in FAMILIES:
        world = generate_world(9, height=17, width=23, n_robots=4, n_targets=2, layout=layout)
        write_movingai_map(world.grid, tmp_path / "m.map")
        write_movingai_scen(world, tmp_path / "m.scen", "m.map")
        assert np.array_equal(read_movingai_map(tmp_path / "m.map"), world.grid)
        assert world_from_movingai(tmp_path / "m.map", tmp_path / "m.scen", n_robots=4, n_targets=2) == world
    no_targets = World(np.zeros((3, 3), dtype=bool), [[0, 0]], np.zeros((0, 2)))
    write_movingai_scen(no_targets, tmp_path / "e.scen", "e.map")
    assert [s.goal for s in read_movingai_scen(tmp_path / "e.scen")] == [(0, 0)]


def test_octile_distances_follow_movingai_rules():
    grid = np.array([[0, 0, 0], [0, 1, 0], [0, 0, 0]], dtype=bool)
    d = octile_distance_field(grid, (0, 0))
    assert d[0, 1] == 1 and d[2, 2] == pytest.approx(4.0)  # no diagonal past the obstacle's corner
    assert d[0, 2] == 2 and np.isinf(d[1, 1])
    open_ = octile_distance_field(np.zeros((3, 3), dtype=bool), (0, 0))
    assert open_[2, 2] == pytest.approx(2 * np.sqrt(2))
