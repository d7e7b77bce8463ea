"""Host-rule ablation: the named decision classes answered by greedy + descent, nothing charged to the chip."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from ising_backend.audit.judge import greedy_descent
from ising_backend.audit.host_rule import HOST_RULE_CLASSES, HostRule, host_answer, host_rule_classes, parse_classes
from mrmt_env.generation import generate_world
from planners.pipeline import make_pipeline


def _energy(h, J, s):
    return float(h @ s + s @ np.triu(J, 1) @ s + s @ np.tril(J, -1) @ s)


def test_host_answer_is_greedy_descent_on_every_program_and_read():
    rng = np.random.default_rng(0)
    h = rng.normal(size=(3, 6))
    J = np.triu(rng.normal(size=(3, 6, 6)), 1)
    spins, energies = host_answer(h, J, 4)
    assert spins.shape == (3, 4, 6) and spins.dtype == np.int8 and energies.shape == (3, 4)
    for b in range(3):
        e, s = greedy_descent(h[b], J[b])
        assert (spins[b] == s).all() and np.allclose(energies[b], e)
        assert np.isclose(e, _energy(h[b], J[b], s.astype(float)))
    shared, _ = host_answer(h, J[0], 2)  # one J for the B programs
    assert all((shared[b, 0] == greedy_descent(h[b], J[0])[1]).all() for b in range(3))
    one, e1 = host_answer(h[1], J[1], 5)
    assert one.shape == (5, 6) and (one == spins[1, 0]).all() and np.allclose(e1, energies[1, 0])


def test_classes_parse_and_nest():
    assert parse_classes("all") == frozenset(HOST_RULE_CLASSES)
    assert parse_classes("sharing_split, path_query") == {"sharing_split", "path_query"}
    assert parse_classes("joint_moves,lns_groups") == {"joint_moves", "lns_groups"}
    with pytest.raises(ValueError, match=r"unknown host-rule class\(es\) \['joint'\]; known: path_query.*lns_groups, task_groups or all"):
        parse_classes("joint")
    assert host_rule_classes() == frozenset()
    with HostRule("tour_moves"):
        with HostRule(["path_query"]):
            assert host_rule_classes() == {"path_query"}
        assert host_rule_classes() == {"tour_moves"}
    assert host_rule_classes() == frozenset()


@pytest.mark.parametrize("preset", ["ising", "ising-paper"])
def test_a_host_rule_class_takes_no_chip_call_and_closed_changes_nothing(preset):
    world = generate_world(3, n_robots=3, n_targets=10)
    before = make_pipeline(preset).plan(world, seed=0)
    with HostRule("sharing_split"):
        ablated = make_pipeline(preset).plan(world, seed=0)
    after = make_pipeline(preset).plan(world, seed=0)
    assert after.route_cost == before.route_cost and after.compute.chip_calls == before.compute.chip_calls
    assert [(r.targets, r.path.tolist()) for r in after.routes] == [(r.targets, r.path.tolist()) for r in before.routes]
    sharing = ablated.stats["layers"]["sharing"]
    assert before.stats["layers"]["sharing"].chip_calls > 0 and sharing.chip_calls == 0
    assert ablated.success
    layers = ablated.stats["layers"]  # the other layers still decide on the chip, and are charged
    assert sum(layers[k].chip_calls + layers[k].logical_calls for k in ("tour", "path")) > 0
    assert ablated.compute.chip_calls + ablated.compute.logical_calls == sum(
        ablated.stats["layers"][k].chip_calls + ablated.stats["layers"][k].logical_calls for k in ("sharing", "tour", "path"))


def test_every_class_on_the_host_makes_no_chip_call():
    world = generate_world(5, n_robots=5, n_targets=40, height=20, width=20)
    with HostRule("all"):
        plan = make_pipeline("ising").plan(world, seed=0)
    assert plan.success and plan.compute.chip_calls == 0 and plan.compute.logical_calls == 0


def _mrmt(*args):
    return subprocess.run([sys.executable, "-m", "agents.cli", *args], capture_output=True, text=True, timeout=600)


@pytest.mark.parametrize("args, needle", [
    (["compare", "--worlds", "1", "--controllers", "ising", "--host-rule", "bogus", "--jobs", "1", "--no-progress"],
     "--host-rule: unknown host-rule class(es) ['bogus']"),
    (["compare", "--worlds", "1", "--controllers", "ising", "--host-rule", "all", "--jobs", "2", "--no-progress"],
     "--host-rule acts on the decisions made in this process"),
])
def test_bad_host_rule_is_one_line_and_exit_2(args, needle):
    proc = _mrmt(*args)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in proc.stderr
