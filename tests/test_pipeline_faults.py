"""The Ising pipeline on a faulty chip: degradation, fallbacks flagged and counted, defaults unchanged."""

import json

import numpy as np
import pytest

from agents.cli import main
from ising_backend import ChipSpec, EmulatedChip
from mrmt_env.generation import generate_world
from mrmt_env.io import write_worlds
from planners.compute import RECORD_KEYS
from planners.fallback import answer
from planners.ising.path import IsingPath
from planners.ising.sharing import IsingSharing
from planners.ising.tour import IsingTour
from planners.pipeline import make_pipeline
from planners.plan import validate_plan

TARGET = dict(readout_flip_prob=0.01, dead_cores=1, stuck_spins=2)


def _world(seed):
    return generate_world(seed, n_robots=3, n_targets=10, placement="centre")


def _ising(spec=None, **options):
    """The ising preset with the chip's path layer too (the preset takes its legs from the BFS field),
    so a fault reaches every layer."""
    return make_pipeline("ising", path="ising", chip=EmulatedChip(ChipSpec() if spec is None else spec), **options)


def _orders(plan):
    return [list(r.targets) for r in plan.routes]


def _direct(machine) -> bool:
    """Whether compiled loops run ``machine``'s own kernel (not the callback)."""
    from ising_backend import CallLedger

    return machine.session(CallLedger()).direct


def test_defaults_unchanged():
    """Route costs, target orders and calls of the fault-free paper pipeline as before the fault model."""
    before = [(32, 76, 12, [[6, 0, 5], [9, 4, 2], [1, 7, 3, 8]]), (29, 68, 10, [[9, 1, 5, 0], [8], [4, 3, 2, 6, 7]]),
              (24, 68, 10, [[], [7, 5, 8, 1], [4, 9, 6, 3, 0, 2]]),
              (28, 70, 30, [[8, 5, 4, 9, 1, 3, 0], [2, 6], [7]])]
    for seed, (cost, calls, logical, orders) in enumerate(before):
        pipe = make_pipeline("ising-paper")
        assert _direct(pipe.path.chip) and _direct(pipe.tour.onehot.solver)  # the emulator's kernels, in the loops
        plan = pipe.plan(_world(seed), seed=seed)
        assert (plan.route_cost, plan.compute.chip_calls, plan.compute.logical_calls, _orders(plan)) == \
            (cost, calls, logical, orders)
        assert plan.compute.retries == plan.compute.fallbacks == 0 and "fallback" not in plan.stats


@pytest.mark.parametrize("preset", ["ising", "ising-paper"])
def test_target_faults_plan_validly_without_fallbacks(preset):
    strong = make_pipeline("strong")
    for seed in range(6):
        chip = EmulatedChip(ChipSpec(seed=seed, **TARGET))
        assert len(chip.health.quarantined.nonzero()[0]) == 1 and chip.usable_spins == 43
        pipe = make_pipeline(preset, chip=chip)
        # faults: the compiled loops, annealing through the chip's fault-tolerant anneal_batch
        assert not _direct(pipe.sharing.chip)
        assert preset == "ising" or not _direct(pipe.path.chip)
        world = _world(seed)
        plan = pipe.plan(world, seed=seed)
        assert plan.success, plan.failure
        validate_plan(world, plan)
        assert plan.compute.fallbacks == 0 and plan.compute.chip_calls > 0
        assert (plan.compute.logical_calls > 0) == (preset == "ising-paper")  # ising: the tour runs on the chip
        assert plan.route_cost <= 1.15 * strong.plan(world, seed=seed).route_cost


def test_same_seed_same_faulty_plan():
    spec = ChipSpec(seed=3, program_error_prob=0.05, **TARGET)
    a, b = (_ising(spec).plan(_world(4), seed=4) for _ in range(2))
    assert _orders(a) == _orders(b) and [r.path.tolist() for r in a.routes] == [r.path.tolist() for r in b.routes]
    assert a.compute.replace(cpu_s=0.0) == b.compute.replace(cpu_s=0.0) and a.compute.retries > 0


def test_program_errors_are_retried_and_counted_in_the_plan():
    chip = EmulatedChip(ChipSpec(program_error_prob=0.2, max_retries=8, seed=1))
    probe = chip.ledger.physical_calls
    plan = make_pipeline("ising", path="ising", chip=chip).plan(_world(1), seed=1)
    assert plan.success and plan.compute.fallbacks == 0
    layers = plan.stats["layers"]
    assert plan.compute.retries == sum(rep.retries for rep in layers.values()) == chip.ledger.retries - \
        (chip.ledger.probe_calls - 2 * 8 * 4)  # probe re-dispatches are the chip's, not the plan's
    assert plan.compute.retries > 0
    assert plan.compute.chip_calls + plan.compute.logical_calls == \
        chip.ledger.physical_calls - probe + chip.ledger.logical_calls
    record = plan.compute.to_record()
    assert tuple(record) == RECORD_KEYS and record["retries"] == plan.compute.retries and record["fallbacks"] == 0


def test_all_cores_dead_falls_back_everywhere_and_stays_valid():
    world = _world(2)
    plan = _ising(ChipSpec(dead_cores=8)).plan(world, seed=2)
    strong = make_pipeline("strong").plan(world, seed=2)
    assert plan.success
    validate_plan(world, plan)
    assert _orders(plan) == _orders(strong)  # SSA + 3-opt + A*, the strong pipeline's layers
    fb = plan.stats["fallback"]
    assert set(fb) == {"sharing", "tour", "path"} and fb["sharing"] == 1
    assert fb["path"] == sum(len(r.targets) for r in plan.routes)
    layers = plan.stats["layers"]
    assert {k: rep.fallbacks for k, rep in layers.items()} == fb
    assert plan.compute.fallbacks == sum(fb.values())
    assert plan.compute.chip_calls == plan.compute.logical_calls == 0
    assert all("every core is quarantined" in r for r in plan.stats["fallback_reasons"])


def test_retries_exhausted_fall_back_with_the_spent_calls_charged():
    plan = _ising(ChipSpec(program_error_prob=1.0, max_retries=1)).plan(_world(0), seed=0)
    assert plan.success and plan.compute.fallbacks == sum(plan.stats["fallback"].values()) > 0
    assert plan.compute.retries > 0 and plan.compute.chip_calls > 0  # the failed writes were charged
    assert all("max_retries = 1" in r for r in plan.stats["fallback_reasons"])


def test_fallback_never_turns_an_unavailable_chip_into_a_failure():
    plan = _ising(ChipSpec(dead_cores=8), fallback="never").plan(_world(0), seed=0)
    assert not plan.success and "the chip could not answer" in plan.failure
    assert plan.compute.fallbacks == 0


@pytest.mark.parametrize("mode, falls_back", [("unavailable", False), ("failure", True)])
def test_fallback_on_failure_mode(mode, falls_back):
    world = _world(0)
    chip = EmulatedChip(ChipSpec())
    start, goal = world.robots[0], world.targets[int(np.argmax(world.distance_matrix[0, 3:]))]
    layer = IsingPath(chip, max_attempts=1, fallback=mode)
    alone = layer.find_path(world, start, goal, np.random.default_rng(0))
    assert alone.path is None and "budget spent" in alone.failure  # a layer alone never falls back
    res = answer("path", layer, world, start, goal, np.random.default_rng(0))  # as the pipeline calls it
    assert (res.path is not None) == falls_back
    if falls_back:
        assert res.stats["fallback"] == {"path": 1} and res.compute.fallbacks == 1 and res.compute.chip_calls > 0
        assert "budget spent" in res.stats["fallback_reasons"][0]
    else:
        assert "budget spent" in res.failure and res.compute.fallbacks == 0


def test_each_layer_falls_back_through_the_one_rule():
    """Alone, an Ising layer on a dead chip fails and says the chip could not answer; called as the
    pipeline calls it (:func:`planners.fallback.answer`), it gives the strong layer's answer, flagged
    and counted, with what it spent before charged."""
    from planners.sharing_classical import SSASharing
    from planners.tours_classical import ThreeOptTour

    dead = EmulatedChip(ChipSpec(dead_cores=8))
    world = _world(5)
    dist = world.distance_matrix
    local = dist[np.ix_([0, 3, 4, 5, 6], [0, 3, 4, 5, 6])]
    cases = [("tour", IsingTour(dead), (local,), ThreeOptTour().solve(local, np.random.default_rng(0))),
             ("sharing", IsingSharing(dead), (dist, 3, ThreeOptTour()),
              SSASharing().assign(dist, 3, ThreeOptTour(), np.random.default_rng(0)))]
    start, goal = world.robots[0], world.targets[3]
    cases.append(("path", IsingPath(dead), (world, start, goal), None))
    for layer, obj, args, strong in cases:
        alone = getattr(obj, {"tour": "solve", "sharing": "assign", "path": "find_path"}[layer])(
            *args, np.random.default_rng(0))
        assert alone.failure.startswith("the chip could not answer") and alone.stats["chip_unavailable"] == 1
        assert alone.compute.fallbacks == 0 and "fallback" not in alone.stats
        res = answer(layer, obj, *args, np.random.default_rng(0))
        assert res.failure is None and res.compute.fallbacks == 1 and res.stats["fallback"] == {layer: 1}
        assert res.stats["fallback_reasons"] == [f"{layer}: {alone.failure}"]
        assert res.compute.chip_calls == alone.compute.chip_calls  # the spent calls stay charged
        if strong is not None:
            assert getattr(res, "order", None) == getattr(strong, "order", None)
            assert getattr(res, "assignment", None) == getattr(strong, "assignment", None)
    never = answer("tour", IsingTour(dead, fallback="never"), local, np.random.default_rng(0))
    assert never.failure.startswith("the chip could not answer") and never.compute.fallbacks == 0
    with pytest.raises(ValueError, match="fallback"):
        IsingPath(dead, fallback="sometimes")


def test_cli_plan_with_fault_options(tmp_path, capsys):
    src = tmp_path / "w.jsonl"
    write_worlds([_world(0), _world(1)], src)
    assert main(["plan", str(src), "--pipeline", "ising", "--chip", "dead_cores=8", "--no-progress"]) == 0
    for line in capsys.readouterr().out.splitlines():
        d = json.loads(line)
        assert d["success"] and d["compute"]["fallbacks"] > 0 and d["compute"]["chip_calls"] == 0
    assert main(["plan", str(src), "--pipeline", "ising", "--chip", "stuck_spins=46"]) == 2
    assert "stuck_spins = 46" in capsys.readouterr().err
