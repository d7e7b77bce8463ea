"""The learned lifelong controller: the task-choice env, its masks, training, loading and evaluation."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import mrmt_env  # noqa: F401  (registers the ids)
from agents.lifelong.controllers import LifelongController, make_lifelong_controller
from agents.lifelong.choice import N_CANDIDATES, N_FEATURES, LearnedAssigner
from agents.lifelong.learned import LifelongDecisionEnv

pytest.importorskip("sb3_contrib")

SMALL = dict(height=12, width=14, n_robots=6, n_targets=9, layout="warehouse",
             layout_options={"shelf_length": 4, "margin": 1})
WAREHOUSE = "mrmt_env/MRMT-Lifelong-Warehouse-v0"


class _First:
    """Always the nearest candidate (the mask's first entry)."""

    def predict(self, obs, deterministic=True, action_masks=None):
        return np.array([int(np.flatnonzero(action_masks)[0])]), None


@pytest.mark.parametrize("seed", [0, 3])
def test_nearest_candidate_policy_moves_exactly_as_greedy(seed):
    env_a = gym.make(WAREHOUSE, **SMALL, max_episode_steps=80)
    env_b = gym.make(WAREHOUSE, **SMALL, max_episode_steps=80)
    obs_a, _ = env_a.reset(seed=seed)
    obs_b, _ = env_b.reset(seed=seed)
    greedy = make_lifelong_controller("greedy", seed=seed)
    learned = LifelongController(LearnedAssigner(_First()), seed=seed)
    for _ in range(80):
        act_a, act_b = greedy.act(obs_a), learned.act(obs_b)
        assert np.array_equal(act_a, act_b)
        obs_a, *_, info_a = env_a.step(act_a)
        obs_b, *_, info_b = env_b.step(act_b)
    assert info_a["tasks_completed"] == info_b["tasks_completed"] > 5


def test_masks_offer_only_open_unclaimed_tasks_to_an_idle_robot_and_refuse_the_rest():
    env = LifelongDecisionEnv(WAREHOUSE, SMALL, max_episode_steps=60)
    rng = np.random.default_rng(0)
    for seed in range(3):
        x, info = env.reset(seed=seed)
        taken_this_step: set[int] = set()
        last_step = -1
        ended = False
        while not ended:
            mask = env.action_masks()
            ch = env.chooser
            robot = int(ch.idle[ch.cursor])
            assert info["robot"] == robot and env.ctrl.queues[robot] == []  # the decider has no task
            if info["steps"] != last_step:
                taken_this_step, last_step = set(), info["steps"]
            open_cells = set(np.flatnonzero(env.env.unwrapped.state.task_t[0] >= 0).tolist())  # the env's own
            claimed = {c for q in env.ctrl.queues for c in q} | taken_this_step
            allowed = np.flatnonzero(mask)
            assert 1 <= len(allowed) <= N_CANDIDATES and np.array_equal(allowed, np.arange(len(allowed)))
            cells = {int(ch.unclaimed[ch.cand[a]]) for a in allowed}
            assert cells <= open_cells and not cells & claimed
            assert x.shape == (N_CANDIDATES * N_FEATURES,) and np.all(x.reshape(N_CANDIDATES, -1)[len(allowed):] == 0)
            if len(allowed) < N_CANDIDATES:
                with pytest.raises(ValueError, match="is masked"):
                    env.step(len(allowed))
            a = int(rng.choice(allowed))
            taken_this_step.add(int(ch.unclaimed[ch.cand[a]]))
            x, r, term, ended, info = env.step(a)
            assert np.isfinite(r) and not term
        assert info["steps"] == 60 and info["blocked_moves"] == 0 and info["conflicts"] == 0


def test_tiny_training_run_gives_a_model_that_compare_evaluates(tmp_path, capsys):
    from agents.cli import main
    from agents.lifelong.evaluation import run_lifelong_episode

    model = tmp_path / "ll.zip"
    assert main(["train", "--env-id", "mrmt_env/MRMT-Lifelong-v0", "--timesteps", "256", "--n-envs", "2",
                 "--out", str(model), "--no-progress"]) == 0
    meta = json.loads((tmp_path / "ll.json").read_text())
    assert meta["algo"] == "maskable_ppo" and meta["decision"] == "lifelong-task"
    # the same model on another world size and fleet (the decision's spaces do not depend on them)
    row = run_lifelong_episode(WAREHOUSE, f"ppo:{model}", seed=1, steps=40, env_kwargs=SMALL)
    assert row["steps"] == 40 and row["conflicts"] == 0 and row["tasks_completed"] > 0
    assert row["accelerator_energy_j"] == 0 and row["host_energy_j"] > 0
    capsys.readouterr()
    assert main(["compare", "--env-id", "mrmt_env/MRMT-Lifelong-v0", "--controllers", f"greedy,ppo:{model}",
                 "--worlds", "1", "--max-steps", "30", "--no-progress"]) == 0
    assert f"ppo:{model}" in capsys.readouterr().out
    # and as a League of Robot Runners scheduler (each free robot's next task), through PIBT with turning
    from agents.lorr.run import run_lorr
    from mrmt_env.lorr.instance import example_instance_path

    record, sim, _ = run_lorr(example_instance_path(), f"ppo:{model}", "pibt", steps=60)
    assert record["errors"] == 0 and record["schedule_errors"] == 0 and record["tasks_finished"] == sim.finished > 0


def test_compare_names_a_model_that_is_not_a_lifelong_one(tmp_path, capsys):
    from agents.cli import main

    assert main(["compare", "--env-id", "mrmt_env/MRMT-Lifelong-v0", "--controllers", "ppo:" + str(tmp_path / "no.zip"),
                 "--worlds", "1", "--max-steps", "5", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("mrmt compare: error:") and "does not exist" in err and "\n" not in err


def test_train_refuses_an_algorithm_without_masks_on_a_lifelong_id(tmp_path, capsys):
    from agents.cli import main

    assert main(["train", "--env-id", "mrmt_env/MRMT-Lifelong-v0", "--algo", "ppo", "--timesteps", "16",
                 "--out", str(tmp_path / "x.zip"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert "needs action masks: algo must be 'maskable_ppo', got 'ppo'" in err and "\n" not in err
