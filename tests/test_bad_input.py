"""Bad input at public entry points: a clear error naming the value and the limit, never a silent truncation."""

from __future__ import annotations

import numpy as np
import pytest

from agents.cli import main
from agents.evaluation import evaluate
from agents.runner import RunConfig
from agents.policy import PlannerPolicy
from ising_backend import IsingModel, MergeError, QuantizeError, merge_spins, quantize, saturate
from mrmt_env import World, WorldError, generate_world
from mrmt_env.io import write_worlds
from mrmt_env.observation import world_from_observation

MODEL = IsingModel(np.array([1.0, 2.0, 3.0]), np.triu(np.ones((3, 3)), 1))


def test_world_grid_value_named():
    grid = np.zeros((3, 3), dtype=int)
    grid[1, 2] = 2
    with pytest.raises(WorldError, match=r"got 2 at cell \[1, 2\]"):
        World(grid, [[0, 0]], [])


def test_observation_value_named():
    obs = np.zeros((3, 4, 4))
    obs[2, 0, 0] = 1
    obs[1, 3, 1] = 0.5
    with pytest.raises(ValueError, match=r"got 0\.5 at \[channel, row, col\] = \[1, 3, 1\]"):
        world_from_observation(obs)


@pytest.mark.parametrize("bad", [(-7, 7, 1), (-7.5, 7.5), (-7.0, 7.0), 7])
def test_quantize_range_not_truncated(bad):
    with pytest.raises(QuantizeError, match="h_range .* integer \\(low, high\\) pair"):
        quantize(MODEL, "linear", h_range=bad)
    with pytest.raises(QuantizeError, match="j_range"):
        saturate(MODEL, 1.0, j_range=bad)


@pytest.mark.parametrize("pct", [0, 150, float("nan")])
def test_quantize_percentile_limit(pct):
    with pytest.raises(QuantizeError, match=r"percentile = .* must be in \(0, 100\]"):
        quantize(MODEL, "clip95", percentile=pct)


def test_quantize_good_ranges_still_accepted():
    q = quantize(MODEL, "linear", h_range=np.array([-3, 3]), j_range=(-7, 7))
    assert np.abs(q.h).max() == 3


@pytest.mark.parametrize("tie", [2.5, True, 8, 0])
def test_merge_tie_integer_in_range(tie):
    with pytest.raises(MergeError, match=r"tie = .* must be an integer in \[1, 7\]"):
        merge_spins(MODEL, "overload", tie=tie)
    assert merge_spins(MODEL, "overload", tie=np.int64(3)).physical.n >= 3


@pytest.mark.parametrize("name, value", [("seed", 1.5), ("seed", -1), ("max_replans", 1.5), ("max_replans", -1)])
def test_policy_integer_args(name, value):
    with pytest.raises(ValueError, match=f"{name} must be an integer >= 0, got {value!r}"):
        PlannerPolicy("fast", **{name: value})


def test_policy_episode_start_length():
    policy = PlannerPolicy("fast")
    obs = np.zeros((2, 3, 4, 4))
    with pytest.raises(ValueError, match=r"episode_start must be a bool or 2 bools .* got shape \(3,\)"):
        policy.predict(obs, episode_start=[True, False, True])


def test_evaluate_n_worlds_not_truncated():
    with pytest.raises(ValueError, match="n_worlds must be an integer >= 1, got 1.5"):
        evaluate(["fast"], n_worlds=1.5, run=RunConfig.from_jobs(2, progress=False))


def test_cli_plan_negative_seed(tmp_path, capsys):
    worlds = tmp_path / "w.jsonl"
    write_worlds([generate_world(0, n_robots=1, n_targets=2)], worlds)
    assert main(["plan", str(worlds), "--seed", "-1", "--no-progress"]) == 2
    assert "--seed must be >= 0" in capsys.readouterr().err


def test_model_non_finite_value_plain():
    with pytest.raises(ValueError, match=r"^J\[0, 1\] = nan is not finite$"):
        IsingModel(np.zeros(2), np.array([[0.0, np.nan], [0.0, 0.0]]))


@pytest.mark.parametrize("seed", [-1, 1.5, "x"])
def test_pipeline_seed_named(seed):
    from planners.pipeline import make_pipeline

    with pytest.raises(ValueError, match=f"seed = {seed!r} is not a numpy seed"):
        make_pipeline("fast").plan(generate_world(0), seed=seed)


def test_pipeline_world_type():
    from planners.pipeline import make_pipeline

    with pytest.raises(TypeError, match="world must be a mrmt_env.world.World, got str"):
        make_pipeline("fast").plan("world.json", seed=0)


@pytest.mark.parametrize("cls", ["EmulatedChip", "LogicalIsingSolver"])
@pytest.mark.parametrize("seed", [-1, 1.5])
def test_solver_seed_named(cls, seed):
    import ising_backend

    with pytest.raises(ValueError, match=f"{cls}: seed = {seed!r} is not a numpy seed"):
        getattr(ising_backend, cls)(seed=seed)


def test_chip_seeds_are_integers_and_empty_programs_cost_nothing():
    import dimod

    from ising_backend import ChipSpec, EmulatedChip, LogicalIsingSolver

    with pytest.raises(ValueError, match=r"seed = -1 must be an integer in \[0, 2\*\*63\)"):
        ChipSpec(seed=-1)
    with pytest.raises(ValueError, match="seed = 1.5"):
        ChipSpec(seed=1.5)
    for solver in (EmulatedChip(), LogicalIsingSolver()):
        for bad in (1.5, float("nan"), -1, True, 2**64):
            with pytest.raises(ValueError, match=r"must be None or an integer in \[0, 2\*\*64\)"):
                solver.sample_ising({0: 1.0}, {}, seed=bad)
        empty = solver.sample(dimod.BinaryQuadraticModel("SPIN"), num_reads=3, seed=0)
        assert len(empty.variables) == 0
        assert solver.ledger.physical_calls + solver.ledger.logical_calls == 0
