"""MaskablePPO on the plan-level env, the grid env's learning options, and the CLI around them."""

from __future__ import annotations

import json
import zipfile

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("sb3_contrib")

from agents.cli import main  # noqa: E402
from agents.evaluation import evaluate  # noqa: E402
from agents.runner import RunConfig  # noqa: E402
from agents.errors import ControllerError  # noqa: E402
from agents.learned.training import (ASSIGN_ENV_ID, TrainOptions, curve_paths, load_policy, sidecar_path,  # noqa: E402
                                     train)


@pytest.fixture(scope="module")
def assign_model(tmp_path_factory):
    path = tmp_path_factory.mktemp("assign") / "m.zip"
    train(ASSIGN_ENV_ID, 512, out=path, options=TrainOptions(seed=0, n_envs=4))
    return path


def test_model_knows_its_algorithm_and_writes_a_curve(assign_model):
    meta = json.loads(sidecar_path(assign_model).read_text())
    assert meta["algo"] == "maskable_ppo" and meta["policy"] == "AssignPointerPolicy" and meta["timesteps"] == 512
    csv_path, png_path = curve_paths(assign_model)
    assert csv_path.read_text().startswith("timesteps,episodes,mean_return,success_rate,mean_route_cost")
    assert png_path.stat().st_size > 0
    policy = load_policy(assign_model)
    assert policy.uses_action_masks and type(policy.model).__name__ == "MaskablePPO"


def test_algorithm_read_from_the_model_file_without_sidecar(assign_model, tmp_path):
    bare = tmp_path / "bare.zip"
    bare.write_bytes(assign_model.read_bytes())
    # without a sidecar the spaces would have to come from the file's pickles: refused, unless the env is given
    with pytest.raises(ControllerError, match="no sidecar bare.json naming its env.*pass env_id="):
        load_policy(bare)
    assert type(load_policy(bare, env_id=ASSIGN_ENV_ID).model).__name__ == "MaskablePPO"


def test_learned_agent_acts_legally_and_always_succeeds(assign_model):
    res = evaluate(["strong", f"ppo:{assign_model}"], n_worlds=3, env_id=ASSIGN_ENV_ID,
                   run=RunConfig.from_jobs(1, progress=False))
    for r in res.rows:
        assert r["is_success"] and r["invalid_moves"] == 0 and r["steps"] <= 13
    ppo = res.by_controller(f"ppo:{assign_model}")
    assert all(r["cpu_s"] > 0 and r["chip_calls"] == 0 for r in ppo)


def test_compare_cli_on_the_assign_env(assign_model, capsys):
    code = main(["compare", "--env-id", ASSIGN_ENV_ID, "--worlds", "2", "--jobs", "1", "--no-progress",
                 "--controllers", f"fast,ising,ppo:{assign_model}"])
    out = capsys.readouterr().out
    assert code == 0 and "ising" in out and "100%" in out


def test_grid_model_on_the_wrong_env_is_named(assign_model):
    policy = load_policy(assign_model)
    with pytest.raises(ValueError, match="trained on observations of shape"):
        policy.predict(np.zeros((5, 10, 10), np.uint8))


def test_train_cli_errors(tmp_path, capsys):
    out = str(tmp_path / "m.zip")
    assert main(["train", "--env-id", ASSIGN_ENV_ID, "--algo", "ppo", "--timesteps", "64", "--out", out]) == 2
    assert "needs action masks" in capsys.readouterr().err
    assert main(["train", "--timesteps", "0", "--out", out]) == 2
    assert "--timesteps must be >= 1, got 0" in capsys.readouterr().err
    assert main(["train", "--env-id", ASSIGN_ENV_ID, "--observation", "image", "--timesteps", "64", "--out", out]) == 2
    err = capsys.readouterr().err
    assert "observation" in err and len(err.strip().splitlines()) == 1


def test_train_cli_assign(tmp_path, capsys):
    out = tmp_path / "a.zip"
    assert main(["train", "--env-id", ASSIGN_ENV_ID, "--timesteps", "256", "--n-envs", "2", "--out", str(out),
                 "--no-progress"]) == 0
    assert zipfile.is_zipfile(out) and curve_paths(out)[0].exists()


def test_grid_cnn_maskable_model_is_scored_on_the_binary_env(tmp_path):
    path = tmp_path / "cnn.zip"
    train("mrmt_env/MRMT-5x5-v0", 256, out=path, options=TrainOptions(algo="maskable_ppo", n_envs=2),
          env_kwargs={"observation": "image", "dense_reward": 1.0}, n_steps=64, batch_size=64)
    meta = json.loads(sidecar_path(path).read_text())
    assert meta["policy"] == "CnnPolicy" and meta["env_kwargs"]["observation"] == "image"
    res = evaluate([f"ppo:{path}"], n_worlds=2, env_id="mrmt_env/MRMT-5x5-v0",
                   run=RunConfig.from_jobs(1, progress=False))
    assert [r["steps"] >= 1 for r in res.rows] == [True, True]
    for r in res.rows:  # masked: the agent never walks into a wall
        assert r["invalid_moves"] == 0


# ---------------------------------------------------------------- grid env options
def test_grid_masks_are_exactly_the_blocked_moves():
    env = gym.make("mrmt_env/MRMT-v0")
    env.reset(seed=2)
    rng = np.random.default_rng(0)
    for _ in range(40):
        mask = env.unwrapped.action_masks().reshape(3, 5)
        before = env.unwrapped.core.positions()
        a = rng.integers(0, 5, size=3)
        _, _, _, _, info = env.step(a)
        after = env.unwrapped.core.positions()
        for k in range(3):
            moved = not np.array_equal(before[k], after[k])
            assert moved == (a[k] != 0 and mask[k, a[k]])
        assert mask[:, 0].all()


def test_dense_reward_is_potential_based():
    sparse = gym.make("mrmt_env/MRMT-v0")
    dense = gym.make("mrmt_env/MRMT-v0", dense_reward=0.5)
    sparse.reset(seed=4)
    dense.reset(seed=4)
    core = dense.unwrapped.core
    phi0 = core.potential(core.nearest_target_field())
    rng = np.random.default_rng(1)
    total_s = total_d = 0.0
    for _ in range(60):
        a = rng.integers(0, 5, size=3)
        total_s += sparse.step(a)[1]
        total_d += dense.step(a)[1]
    phi = core.potential(core.nearest_target_field())
    assert total_d == pytest.approx(total_s + 0.5 * (phi - phi0))
    assert phi0 < 0


def test_image_observation_is_cnn_ready():
    from stable_baselines3.common.preprocessing import is_image_space

    env = gym.make("mrmt_env/MRMT-v0", observation="image")
    obs, _ = env.reset(seed=0)
    assert obs.shape == (5, 40, 40) and obs.dtype == np.uint8 and set(np.unique(obs)) <= {0, 255}
    assert is_image_space(env.observation_space)
    binary = gym.make("mrmt_env/MRMT-v0").reset(seed=0)[0]
    assert np.array_equal(obs[:, ::4, ::4] // 255, binary)


@pytest.mark.parametrize("kw,match", [({"observation": "rgb"}, "observation must be one of"),
                                      ({"dense_reward": -1}, "dense_reward must be a finite number >= 0")])
def test_grid_option_errors(kw, match):
    with pytest.raises(ValueError, match=match):
        gym.make("mrmt_env/MRMT-v0", **kw)


def test_grid_options_pass_the_env_checkers():
    import warnings

    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = gym.make("mrmt_env/MRMT-v0", observation="image", dense_reward=1.0).unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an image SB3 accepts as it is: no warning at all
        check_env(env)
        sb3_check_env(env, warn=True)


def test_multi_start_decoding(assign_model, capsys):
    greedy, multi = f"ppo:{assign_model}", f"ppo-ms:{assign_model}"
    res = evaluate([greedy, multi], n_worlds=4, env_id=ASSIGN_ENV_ID, run=RunConfig.from_jobs(1, progress=False))
    g, m = res.by_controller(greedy), res.by_controller(multi)
    assert all(r["is_success"] and r["invalid_moves"] == 0 and r["cpu_s"] > 0 for r in m)
    # the greedy rollout is one of the starts, so the best start costs no more (summed: robust to float ties)
    assert sum(r["route_cost"] for r in m) <= sum(r["route_cost"] for r in g)
    assert main(["compare", "--env-id", "mrmt_env/MRMT-5x5-v0", "--worlds", "1", "--jobs", "1", "--no-progress",
                 "--controllers", multi]) == 2
    assert "multi-start decoding needs the plan-level env" in capsys.readouterr().err
