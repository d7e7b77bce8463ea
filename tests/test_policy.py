"""PlannerPolicy: plain loops, SB3 evaluate_policy, PettingZoo per-robot form, replanning."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import mrmt_env
from agents.policy import PlannerPolicy, move_action
from mrmt_env.observation import world_from_observation
from planners.compute import ComputeReport
from planners.plan import Plan, RobotRoute, validate_plan


def run_loop(env, policy, seed):
    obs, info = env.reset(seed=seed)
    start, done = True, False
    while not done:
        action, _ = policy.predict(obs, episode_start=start)
        start = False
        obs, _, terminated, truncated, info = env.step(action)
        done = terminated or truncated
    return info, terminated


@pytest.mark.parametrize("preset", ["fast", "strong"])
def test_plain_loop_reaches_success_with_plan_cost(preset):
    env = gym.make("mrmt_env/MRMT-v0")
    policy = PlannerPolicy(preset, seed=3)
    for seed in range(4):
        info, terminated = run_loop(env, policy, seed)
        plans = policy.episode_plans()
        assert terminated and info["is_success"]
        assert len(plans) == 1, "a successful plan is followed without replanning"
        validate_plan(policy.current_world(), plans[0])
        assert info["route_cost"] == plans[0].route_cost
        assert info["makespan"] == plans[0].makespan
        assert info["invalid_moves"] == 0
        assert policy.episode_compute() == plans[0].compute
    assert policy.n_plans == 4
    assert policy.total_compute.cpu_s > 0


def test_plan_targets_refer_to_rebuilt_world():
    env = gym.make("mrmt_env/MRMT-v0")
    obs, _ = env.reset(seed=11)
    policy = PlannerPolicy("strong")
    policy.predict(obs, episode_start=True)
    world = policy.current_world()
    assert world == world_from_observation(obs)
    listed = sorted(t for r in policy.current_plan().routes for t in r.targets)
    assert listed == list(range(world.n_targets))


def test_evaluate_policy_vecenv_batched():
    pytest.importorskip("stable_baselines3")  # extra "rl": without it this test is skipped, not failed
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.evaluation import evaluate_policy

    venv = make_vec_env("mrmt_env/MRMT-v0", n_envs=2, seed=5)
    policy = PlannerPolicy("strong", seed=0)
    finished = []

    def callback(local, _globals):
        i = local["i"]
        if local["dones"][i]:
            info = local["infos"][i]
            finished.append((info["is_success"], info["route_cost"], policy.episode_plans(i)[0].route_cost))

    rewards, lengths = evaluate_policy(policy, venv, n_eval_episodes=4, return_episode_rewards=True, callback=callback)
    assert len(rewards) == 4
    assert len(finished) >= 4
    for success, cost, plan_cost in finished:
        assert success and cost == plan_cost
    # the MultiDiscrete joint action of a batch
    obs = venv.reset()
    action, state = policy.predict(obs, episode_start=np.ones(2, bool))
    assert action.shape == (2, 3) and state is None
    assert venv.action_space.contains(action[0])


def test_deterministic_given_seed():
    env = gym.make("mrmt_env/MRMT-v0")
    a = PlannerPolicy("fast", seed=1)
    b = PlannerPolicy("fast", seed=1)
    obs, _ = env.reset(seed=2)
    assert np.array_equal(a.predict(obs, episode_start=True)[0], b.predict(obs, episode_start=True)[0])


def test_replans_when_world_stops_matching():
    env = gym.make("mrmt_env/MRMT-v0")
    policy = PlannerPolicy("strong")
    obs0, _ = env.reset(seed=0)
    policy.predict(obs0, episode_start=True)
    obs1, _ = env.reset(seed=1)  # a different world without telling the policy
    policy.predict(obs1)
    assert len(policy.episode_plans()) == 2
    assert policy.current_world() == world_from_observation(obs1)


class _GiveUp:
    """A pipeline whose plans never move anyone (a failed plan)."""

    name = "give-up"

    def plan(self, world, seed=None):
        routes = [RobotRoute((), np.asarray(world.robots[k]).reshape(1, 2)) for k in range(world.n_robots)]
        return Plan(routes, ComputeReport(cpu_s=1e-3, chip_calls=2), success=False, failure="test")


def test_failed_plan_replans_at_most_max_replans_then_stays():
    env = gym.make("mrmt_env/MRMT-v0", max_episode_steps=10)
    policy = PlannerPolicy(_GiveUp(), max_replans=2)
    info, terminated = run_loop(env, policy, 0)
    assert not terminated and not info["is_success"]
    assert len(policy.episode_plans()) == 3
    assert policy.episode_compute().chip_calls == 6
    assert info["route_cost"] == 0


def test_parallel_env_per_robot_form():
    penv = mrmt_env.parallel_env()
    policy = PlannerPolicy("strong", seed=0)
    obs, infos = penv.reset(seed=4)
    start = True
    while penv.agents:
        actions = policy.predict_parallel(obs, episode_start=start)
        start = False
        assert set(actions) == set(penv.agents)
        obs, rewards, terms, truncs, infos = penv.step(actions)
    info = infos["robot_0"]
    assert info["is_success"]
    assert info["route_cost"] == policy.episode_plans()[0].route_cost


def test_aec_env_per_robot_form():
    aec = mrmt_env.env()
    aec.reset(seed=4)
    policy = PlannerPolicy("strong", seed=0)
    start = True
    last = None
    for agent in aec.agent_iter():
        obs, _, term, trunc, info = aec.last()
        last = info
        action = None if (term or trunc) else policy.predict_agent(agent, obs, episode_start=start)
        start = False
        aec.step(action)
    assert last["is_success"]
    assert last["route_cost"] == policy.episode_plans()[0].route_cost


def test_bad_inputs_are_clear_errors():
    policy = PlannerPolicy("fast")
    with pytest.raises(ValueError, match="shape"):
        policy.predict(np.zeros((5, 10)))
    with pytest.raises(ValueError, match="robot_k"):
        policy.predict_parallel({"bob": np.zeros((6, 5, 5), np.uint8)})
    with pytest.raises(TypeError, match="plan"):
        PlannerPolicy(object())
    with pytest.raises(ValueError, match="max_replans"):
        PlannerPolicy("fast", max_replans=-1)
    with pytest.raises(ValueError, match="4-neighbours"):
        move_action([0, 0], [2, 0])
    assert [move_action([1, 1], c) for c in ([1, 1], [0, 1], [2, 1], [1, 0], [1, 2])] == [0, 1, 2, 3, 4]


def test_first_plan_of_a_policy_reports_the_warm_up_apart():
    env = gym.make("mrmt_env/MRMT-v0")
    warm, cold = PlannerPolicy("strong", seed=1), PlannerPolicy("strong", seed=1)
    cold.pipeline.warmup_first = False
    for seed in range(2):
        assert run_loop(env, warm, seed)[0] == run_loop(env, cold, seed)[0]  # same episodes
        warm_plan, cold_plan = warm.episode_plans()[0], cold.episode_plans()[0]
        assert [r.targets for r in warm_plan.routes] == [r.targets for r in cold_plan.routes]
        if seed == 0:
            assert warm.last_compute.warmup_s > 0 and warm.episode_compute().warmup_s == warm.last_compute.warmup_s
        else:
            assert warm.last_compute.warmup_s == 0
    assert cold.total_compute.warmup_s == 0 and warm.total_compute.warmup_s == warm.pipeline.warmup_s
