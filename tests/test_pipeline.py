"""Pipelines: presets, composition by name, accounting, failures, registry."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mrmt_env import World, generate_world
from planners import registry
from planners.base import PathResult, SharingResult, TourResult
from planners.compute import ComputeReport
from planners.paths_classical import AStarPath, BFSPath
from planners.pipeline import PRESETS, Pipeline, make_pipeline, merge_stats
from planners.plan import validate_plan
from planners.sharing_classical import ExactSharing, PSASharing, SSASharing
from planners.tours_classical import BruteTour, NearestNeighbourTour, ThreeOptTour


@pytest.mark.parametrize("preset", ["fast", "strong"])
@pytest.mark.parametrize("seed", range(8))
def test_presets_give_valid_complete_plans(preset, seed):
    world = generate_world(seed, n_robots=1 + seed % 3, n_targets=3 + seed, placement=("uniform", "centre")[seed % 2])
    plan = make_pipeline(preset).plan(world, seed=seed)
    assert plan.success and plan.failure is None
    validate_plan(world, plan)
    layers = plan.stats["layers"]
    assert set(layers) == {"sharing", "tour", "path"}
    # the layers' measured times fit inside the plan's (glue, the remainder, is never negative)
    assert 0 < sum(r.cpu_s for r in layers.values()) <= plan.compute.cpu_s
    assert 0 <= plan.stats["glue_cpu_s"] < plan.compute.cpu_s
    assert layers["path"].cpu_s > 0
    assert plan.compute.chip_calls == 0 and plan.compute.accelerator_energy_j == 0
    assert plan.stats["pipeline"] == preset


@pytest.mark.parametrize("sharing", ["round_robin", "psa", "ssa", "exact"])
@pytest.mark.parametrize("tour", ["nn", "2opt", "3opt", "brute"])
@pytest.mark.parametrize("path", ["bfs", "astar", "gbfs"])
def test_every_classical_triple(sharing, tour, path):
    world = generate_world(7, n_robots=3, n_targets=8)
    plan = make_pipeline(sharing=sharing, tour=tour, path=path).plan(world, seed=1)
    assert plan.success
    validate_plan(world, plan)


def test_exact_brute_bfs_reaches_the_optimum():
    world = generate_world(11, n_robots=3, n_targets=9)
    opt = ExactSharing().assign(world.distance_matrix, 3, BruteTour()).stats["optimum"]
    plan = make_pipeline(sharing="exact", tour="brute", path="bfs").plan(world)
    assert plan.route_cost == opt
    for p in ("fast", "strong"):
        assert make_pipeline(p).plan(world).route_cost >= opt


def test_route_cost_equals_tour_costs_with_shortest_paths():
    world = generate_world(5, n_robots=2, n_targets=7)
    pipe = make_pipeline("strong")
    plan = pipe.plan(world)
    d = world.distance_matrix
    for k, route in enumerate(plan.routes):
        nodes = [k] + [2 + t for t in route.targets]
        assert route.length == sum(d[a, b] for a, b in zip(nodes[:-1], nodes[1:]))


def test_same_seed_same_plan():
    world = generate_world(3)
    a = make_pipeline("strong").plan(world, seed=4)
    b = make_pipeline("strong").plan(world, seed=4)
    assert [r.targets for r in a.routes] == [r.targets for r in b.routes]
    assert all(np.array_equal(x.path, y.path) for x, y in zip(a.routes, b.routes))


# ------------------------------------------------------------ fake layers
class Counting:
    """Wrap a layer, count calls, optionally add accelerator counts and stats."""

    def __init__(self, inner, chip_calls=0, stats=None):
        self.inner, self.calls, self.chip_calls, self.extra = inner, 0, chip_calls, stats or {}
        self.name = inner.name

    def _wrap(self, res):
        self.calls += 1
        compute = ComputeReport(cpu_s=123.0, chip_calls=self.chip_calls)  # cpu_s must be replaced
        return type(res)(**{**res.__dict__, "compute": compute, "stats": {**res.stats, **self.extra}})

    def assign(self, *a, **k):
        return self._wrap(self.inner.assign(*a, **k))

    def solve(self, *a, **k):
        return self._wrap(self.inner.solve(*a, **k))

    def find_path(self, *a, **k):
        return self._wrap(self.inner.find_path(*a, **k))


def test_single_robot_single_target_uses_only_the_path_layer():
    world = generate_world(2, n_robots=1, n_targets=1)
    s, t, p = Counting(SSASharing()), Counting(ThreeOptTour()), Counting(AStarPath())
    plan = Pipeline(s, t, p).plan(world)
    assert (s.calls, t.calls, p.calls) == (0, 0, 1)
    assert plan.stats["layers"]["sharing"].cpu_s == 0 and plan.stats["layers"]["tour"].cpu_s == 0
    assert plan.route_cost == world.distance_matrix[0, 1]


def test_single_robot_many_targets_uses_tour_and_path():
    world = generate_world(2, n_robots=1, n_targets=6)
    s, t, p = Counting(SSASharing()), Counting(ThreeOptTour()), Counting(AStarPath())
    Pipeline(s, t, p).plan(world)
    assert (s.calls, t.calls, p.calls) == (0, 1, 6)


def test_layer_accounting_and_stats_merge():
    world = generate_world(9, n_robots=3, n_targets=10)
    s = Counting(PSASharing(), chip_calls=2, stats={"mapping": {"sharing": {"valid": 1}}})
    t = Counting(NearestNeighbourTour(), chip_calls=5)
    p = Counting(BFSPath(), chip_calls=1, stats={"mapping": {"path": {"valid": 1}}, "tag": ["x"]})
    plan = Pipeline(s, t, p).plan(world)
    layers = plan.stats["layers"]
    assert layers["sharing"].chip_calls == 2
    assert layers["tour"].chip_calls == 5 * t.calls
    assert layers["path"].chip_calls == 10 == p.calls
    assert plan.compute.chip_calls == 2 + 5 * t.calls + 10
    assert all(r.cpu_s < 100 for r in layers.values())  # the layers' own cpu_s is replaced by the measurement
    assert plan.stats["mapping"] == {"sharing": {"valid": 1}, "path": {"valid": 10}}
    assert plan.stats["tag"] == ["x"] * 10
    assert plan.stats["expanded"] > 0


def test_merge_stats_rules():
    acc = merge_stats({}, {"n": 1, "f": True, "d": {"a": 1.5}, "l": [1], "s": "a", "failure": "x"})
    merge_stats(acc, {"n": 2, "f": False, "d": {"a": 1.0, "b": 2}, "l": [2], "s": "b"})
    assert acc == {"n": 3, "f": True, "d": {"a": 2.5, "b": 2}, "l": [1, 2], "s": "b"}


def _merge_reference(into: dict, new: dict) -> dict:
    """The merge rules written out one by one (the reference of the fast paths)."""
    for key, value in new.items():
        old = into.get(key)
        tv, to = type(value), type(old)
        if (tv is int or tv is float) and (to is int or to is float):
            into[key] = old + value
            continue
        if key == "failure":
            continue
        num, truth = (int, float, np.integer, np.floating), (bool, np.bool_)
        if isinstance(value, dict):
            into[key] = _merge_reference(old if isinstance(old, dict) else {}, value)
        elif isinstance(value, list):
            into[key] = (list(old) if isinstance(old, list) else []) + list(value)
        elif isinstance(value, truth) and isinstance(old, truth):
            into[key] = bool(old or value)
        elif (isinstance(value, num) and not isinstance(value, truth)
              and isinstance(old, num) and not isinstance(old, truth)):
            into[key] = old + value
        else:
            into[key] = value
    return into


_leaf = st.one_of(st.integers(-5, 5), st.floats(-2, 2), st.booleans(), st.none(), st.text(max_size=2),
                  st.integers(0, 3).map(np.int64), st.booleans().map(np.bool_), st.lists(st.integers(0, 3), max_size=3))
_stats = st.recursive(_leaf, lambda inner: st.dictionaries(st.sampled_from(["a", "b", "failure", "n"]), inner,
                                                           max_size=4), max_leaves=12)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.dictionaries(st.sampled_from(["a", "b", "c", "failure", "mapping"]), _stats, max_size=5),
                min_size=1, max_size=4))
def test_merge_stats_matches_the_rules(layers):
    """Merging layer after layer gives what the rules say, with the same types, and never
    shares a list or dict with a layer's stats."""
    import copy

    kept = copy.deepcopy(layers)
    fast, ref = {}, {}
    for new in layers:
        merge_stats(fast, new)
        _merge_reference(ref, copy.deepcopy(new))
        assert repr(fast) == repr(ref)
    assert repr(layers) == repr(kept)

    def containers(x):
        if isinstance(x, (dict, list)):
            yield id(x)
            for v in (x.values() if isinstance(x, dict) else x):
                yield from containers(v)

    assert not set(containers(fast)) & set(containers(layers))


class FailingPath:
    """Fails on the given (call index); returns an illegal path on another."""

    name = "failing"

    def __init__(self, fail_at=(), jump_at=()):
        self.fail_at, self.jump_at, self.calls = set(fail_at), set(jump_at), 0
        self.inner = BFSPath()

    def find_path(self, world, a, b, rng=None):
        i = self.calls
        self.calls += 1
        if i in self.fail_at:
            return PathResult(None, failure="patch solver gave up")
        res = self.inner.find_path(world, a, b)
        if i in self.jump_at and res.length >= 2:
            return PathResult(np.delete(res.path, 1, axis=0))
        return res


def test_path_failure_gives_failed_but_legal_partial_plan():
    world = generate_world(4, n_robots=1, n_targets=5)
    plan = Pipeline(PSASharing(), NearestNeighbourTour(), FailingPath(fail_at={2})).plan(world)
    assert not plan.success
    assert plan.failure.startswith("robot 0 leg 2 (") and "patch solver gave up" in plan.failure
    assert len(plan.routes[0].targets) == 2
    validate_plan(world, plan, require_complete=False)
    assert plan.to_dict()["failure"] == plan.failure and plan.to_dict()["success"] is False


def test_illegal_path_from_a_layer_is_a_failure_not_an_invalid_plan():
    world = generate_world(6, n_robots=2, n_targets=6)
    plan = Pipeline(PSASharing(), NearestNeighbourTour(), FailingPath(jump_at={0, 1, 2, 3, 4, 5})).plan(world)
    assert not plan.success and "jump" in plan.failure
    validate_plan(world, plan, require_complete=False)


def test_unreachable_target_with_round_robin_is_a_failure():
    grid = np.zeros((3, 5), dtype=bool)
    grid[:, 2] = True
    world = World(grid, [[0, 0], [0, 4]], [[2, 4], [2, 0]])  # target 0 only reachable by robot 1
    plan = make_pipeline(sharing="round_robin", tour="nn", path="astar").plan(world)
    assert not plan.success and "robot 0 leg 0" in plan.failure and "unreachable" in plan.failure
    validate_plan(world, plan, require_complete=False)
    assert make_pipeline("fast").plan(world).success


class BadSharing:
    name = "bad"

    def assign(self, dist, n_robots, tour, rng=None):
        return SharingResult(assignment=((0, 1),) * n_robots)


class GivingUpTour:
    name = "giveup"

    def solve(self, dist, rng=None):
        return TourResult(order=(), cost=np.inf, failure="no valid candidate")


def test_sharing_and_tour_failures():
    world = generate_world(1, n_robots=2, n_targets=4)
    plan = Pipeline(BadSharing(), NearestNeighbourTour(), BFSPath()).plan(world)
    assert not plan.success and plan.failure.startswith("sharing: target 0 assigned to robots 0 and 1")
    validate_plan(world, plan, require_complete=False)
    plan = Pipeline(PSASharing(), GivingUpTour(), BFSPath()).plan(world)
    assert not plan.success and "tour: no valid candidate" in plan.failure
    validate_plan(world, plan, require_complete=False)


# ------------------------------------------------------------- construction
def test_make_pipeline_presets_and_overrides():
    assert PRESETS == {"fast": ("psa", "nn", "astar"), "strong": ("ssa", "3opt", "astar"),
                       "ising": ("ising", "ising", "field"),
                       "ising-paper": ("ising-paper", "ising-paper", "ising-paper"),
                       "exact": ("exact", "brute", "bfs"), "pyvrp": ("pyvrp", "keep", "astar"),
                       "ising-fleet": ("ising-fleet", "keep", "field"), "ortools": ("ortools", "keep", "astar")}
    p = make_pipeline("strong")
    assert isinstance(p.sharing, SSASharing) and isinstance(p.tour, ThreeOptTour) and isinstance(p.path, AStarPath)
    p = make_pipeline("strong", tour_options={"moves": "7"}, sharing_options={"bid": "tour"}, path="bfs")
    assert p.tour.moves == "7" and p.sharing.bid == "tour" and isinstance(p.path, BFSPath)
    assert p.name == "ssa+3opt+bfs"
    obj = ThreeOptTour("7")
    assert make_pipeline("fast", tour=obj).tour is obj


def test_make_pipeline_errors():
    with pytest.raises(ValueError, match="unknown pipeline preset 'quick'; presets: fast, strong, ising"):
        make_pipeline("quick")
    with pytest.raises(ValueError, match="missing"):
        make_pipeline(sharing="psa", tour="nn")
    with pytest.raises(registry.UnknownPlannerError, match="valid tour planners: nn, 2opt, 3opt, brute, ising"):
        make_pipeline(sharing="psa", tour="4opt", path="bfs")
    with pytest.raises(ValueError, match="takes no option 'movez'"):
        make_pipeline("strong", tour_options={"movez": "7"})
    with pytest.raises(ValueError, match=r"option\(s\) \['chip'\] are accepted by no layer"):
        make_pipeline("strong", chip=object())
    with pytest.raises(ValueError, match="configure the object"):
        make_pipeline("fast", tour=ThreeOptTour(), tour_options={"moves": "7"})
    with pytest.raises(TypeError, match="no solve"):
        Pipeline(PSASharing(), BFSPath(), BFSPath())


def test_registry_names_custom_and_shared_options():
    assert registry.sharing_names() == ("round_robin", "psa", "ssa", "exact", "ising", "ising-paper", "pyvrp",
                                        "ortools", "ising-fleet")
    assert registry.tour_names() == ("nn", "2opt", "3opt", "brute", "ising", "ising-paper", "keep")
    assert registry.path_names() == ("bfs", "astar", "gbfs", "ising", "ising-paper", "field")
    seen = {}

    class ChipTour(NearestNeighbourTour):
        def __init__(self, chip=None):
            seen["chip"] = chip

    registry.register_tour("test_chip_nn", ChipTour)
    try:
        with pytest.raises(ValueError, match="already registered"):
            registry.register_tour("test_chip_nn", ChipTour)
        chip = object()
        pipe = make_pipeline(sharing="psa", tour="test_chip_nn", path="bfs", chip=chip)
        assert seen["chip"] is chip and isinstance(pipe.tour, ChipTour)
        assert "test_chip_nn" in registry.tour_names()
    finally:
        registry._REGISTRY["tour"].pop("test_chip_nn")


def test_unavailable_lazy_factory_is_a_clear_error():
    registry.register_path("test_missing", "planners.no_such_module:Nope")
    try:
        with pytest.raises(registry.UnknownPlannerError, match=r"path planner 'test_missing' .* is unavailable: "
                                                                r"ModuleNotFoundError.*valid path planners: bfs"):
            make_pipeline(sharing="psa", tour="nn", path="test_missing")
    finally:
        registry._REGISTRY["path"].pop("test_missing")
    with pytest.raises(ValueError, match="module:attr"):
        registry.register_path("x", "nocolon")


def test_no_targets_and_robot_on_target():
    grid = np.zeros((4, 4), dtype=bool)
    world = World(grid, [[0, 0], [3, 3]], np.zeros((0, 2)))
    plan = make_pipeline("strong").plan(world)
    assert plan.success and plan.route_cost == 0
    assert [r.path.tolist() for r in plan.routes] == [[[0, 0]], [[3, 3]]]
    world = World(grid, [[0, 0], [3, 3]], [[0, 0], [3, 2], [1, 1]])
    for preset in ("fast", "strong"):
        plan = make_pipeline(preset).plan(world)
        validate_plan(world, plan)
        assert plan.route_cost == 1 + 2


# ---------------------------------------------------------------- warm-up: compile time is not planning time
class _OneOffPath(BFSPath):
    """A path layer that, like a numba kernel, pays a one-off cost on its first call in a process
    (a class-level flag, shared by every copy, as a compiled kernel is)."""

    paid_by: list = []

    def __init__(self):
        super().__init__()
        self.calls = 0

    def find_path(self, world, a, b, rng):
        if not _OneOffPath.paid_by:
            _OneOffPath.paid_by.append(id(self))
        self.calls += 1
        return super().find_path(world, a, b, rng)


def test_first_plan_warms_up_on_a_scratch_copy_and_reports_it_apart():
    _OneOffPath.paid_by.clear()
    path = _OneOffPath()
    pipeline = Pipeline(SSASharing(), ThreeOptTour(), path)
    world = generate_world(3, n_robots=3, n_targets=8)
    first = pipeline.plan(world, seed=1)
    # the one-off cost was paid by the scratch copy, before the measured plan; the real layer only planned
    assert _OneOffPath.paid_by and _OneOffPath.paid_by[0] != id(path)
    assert path.calls == world.n_targets
    assert first.compute.warmup_s > 0 and "warmup_s" not in first.stats
    assert first.compute.warmup_s == pipeline.warmup_s
    # warm-up is in no layer and not in cpu_s
    layers = first.stats["layers"]
    assert all(rep.warmup_s == 0 for rep in layers.values())
    assert first.compute.cpu_s == pytest.approx(sum(r.cpu_s for r in layers.values()) + first.stats["glue_cpu_s"])
    record = first.compute.to_record()
    assert record["warmup_s"] == first.compute.warmup_s and record["host_cpu_s"] == pytest.approx(first.compute.cpu_s)
    second = pipeline.plan(world, seed=1)
    assert second.compute.warmup_s == 0 and path.calls == 2 * world.n_targets
    assert pipeline.warmup() == 0.0  # once per pipeline


class _SlowFirstSharing(SSASharing):
    """SSA that, like a numba kernel compiled on its first call, spends ``DELAY`` seconds on its first
    call in the process (a class-level flag, shared by every copy)."""

    DELAY = 0.4
    paid: list = []

    def assign(self, dist, n_robots, tour=None, rng=None):
        if not _SlowFirstSharing.paid:
            _SlowFirstSharing.paid.append(True)
            import time

            time.sleep(self.DELAY)
        return super().assign(dist, n_robots, tour, rng)


def test_the_first_plans_warm_up_time_is_not_in_its_cpu_time():
    """The one-off cost the warm-up pays is reported in ``warmup_s`` only: not in the first plan's
    ``cpu_s`` (nor its glue, host or energy figures), which stays that of a warm plan."""
    _SlowFirstSharing.paid.clear()
    pipeline = Pipeline(_SlowFirstSharing(), ThreeOptTour(), BFSPath())
    world = generate_world(3, n_robots=3, n_targets=8)
    first = pipeline.plan(world, seed=1)
    second = pipeline.plan(world, seed=1)
    delay = _SlowFirstSharing.DELAY
    assert first.compute.warmup_s >= delay and second.compute.warmup_s == 0
    # a warm plan of this world takes milliseconds: the delay is nowhere in the first plan's figures
    assert first.compute.cpu_s < delay / 2, (first.compute.cpu_s, first.compute.warmup_s)
    assert first.stats["glue_cpu_s"] < delay / 2 and first.stats["layers"]["sharing"].cpu_s < delay / 2
    record = first.compute.to_record()
    assert record["host_cpu_s"] < delay / 2 and record["latency_s"] < delay / 2
    assert record["total_energy_j"] < delay / 2 * 15.0


_COLD_PLANS = """
import json
from mrmt_env import generate_world
from planners.pipeline import make_pipeline
world = generate_world(7, n_robots=3, n_targets=10)
pipeline = make_pipeline("ising")
first, second = pipeline.plan(world, seed=1), pipeline.plan(world, seed=1)
print(json.dumps([first.compute.cpu_s, first.compute.warmup_s, second.compute.cpu_s, second.compute.warmup_s]))
"""


def test_a_fresh_process_first_plan_is_timed_like_its_second():
    """In a fresh process (the kernels compiled or loaded from numba's cache on first use) the first
    plan's ``cpu_s`` is that of a warm plan: below its ``warmup_s`` (the warm-up plans the same world
    once more, and loads or compiles the kernels besides) and within a factor of the second plan's."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    out = subprocess.run([sys.executable, "-c", _COLD_PLANS], capture_output=True, text=True, timeout=600,
                         cwd=Path(__file__).resolve().parents[1], check=True)
    first_cpu, first_warmup, second_cpu, second_warmup = json.loads(out.stdout.strip().splitlines()[-1])
    assert first_warmup > 0 and second_warmup == 0
    assert first_cpu < first_warmup, (first_cpu, first_warmup)
    assert first_cpu <= 20 * second_cpu + 0.05, (first_cpu, second_cpu)  # absolute slack: a busy machine


@pytest.mark.parametrize("preset", ["strong", "ising"])
def test_plans_are_the_same_with_and_without_warm_up(preset):
    world = generate_world(5, n_robots=3, n_targets=10)
    warmed = make_pipeline(preset)
    assert warmed.warmup(generate_world(11, n_robots=2, n_targets=6), seed=4) > 0
    auto = make_pipeline(preset)  # warms itself on the world it plans
    cold = make_pipeline(preset)
    cold.warmup_first = False
    plans = [p.plan(world, seed=2) for p in (warmed, auto, cold)]
    for plan in plans[1:]:
        assert [r.targets for r in plan.routes] == [r.targets for r in plans[0].routes]
        assert all(np.array_equal(a.path, b.path) for a, b in zip(plan.routes, plans[0].routes))
        counts = {k: v for k, v in plan.compute.to_record().items() if not k.endswith("_s") and "energy" not in k}
        assert counts == {k: v for k, v in plans[0].compute.to_record().items() if k in counts}
    assert plans[1].compute.warmup_s > 0 and plans[0].compute.warmup_s == 0 and plans[2].compute.warmup_s == 0
    if preset == "ising":  # the real chip's ledger holds the plan's calls only, never the warm-up's
        for p, plan in zip((warmed, auto, cold), plans):
            assert p.sharing.chip.ledger.physical_calls == plan.compute.chip_calls > 0


def test_warm_up_leaves_a_generator_seed_alone():
    world = generate_world(2, n_robots=2, n_targets=5)
    a, b = np.random.default_rng(9), np.random.default_rng(9)
    cold = make_pipeline("fast")
    cold.warmup_first = False
    pa, pb = make_pipeline("fast").plan(world, seed=a), cold.plan(world, seed=b)
    assert [r.targets for r in pa.routes] == [r.targets for r in pb.routes] and a.random() == b.random()


def _kernel_signatures() -> dict:
    """Every compiled (or cache-loaded) signature of the project's numba kernels in this process."""
    import sys

    from numba.core.dispatcher import Dispatcher

    return {(m, n): tuple(map(str, f.signatures)) for m, mod in list(sys.modules.items())
            if m.split(".")[0] in ("planners", "ising_backend", "mrmt_env") and mod is not None
            for n, f in list(vars(mod).items()) if isinstance(f, Dispatcher)}


@pytest.mark.parametrize("preset", ["strong", "ising"])
def test_the_first_plan_after_warm_up_compiles_and_loads_nothing(preset):
    from mrmt_env.io import world_from_dict, world_to_dict

    world = generate_world(21, n_robots=3, n_targets=10)
    for same in (world, world_from_dict(world_to_dict(world))):  # a world as generated, and as read from a file
        pipeline = make_pipeline(preset)
        pipeline.warmup(same, seed=3)
        before = _kernel_signatures()
        pipeline.plan(same, seed=3)
        after = _kernel_signatures()
        assert {k: v for k, v in after.items() if before.get(k) != v} == {}
