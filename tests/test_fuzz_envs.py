"""Fuzzing the envs: arbitrary actions (values, dtypes, shapes), resets and stepping past the end, for every id.

A refused action raises ``ValueError`` (one line) and changes nothing; a step after the episode ended
raises ``RuntimeError`` until ``reset`` and changes nothing; every accepted step gives an observation
inside the observation space.
"""

from __future__ import annotations

import operator

import gymnasium as gym
import numpy as np
import pytest
from fuzzing import fuzz_settings, junk, no_hang, one_line
from gymnasium.envs.registration import load_env_creator
from hypothesis import given
from hypothesis import strategies as st

import mrmt_env

GRID_IDS = sorted(mrmt_env.GYM_IDS)
ASSIGN_IDS = sorted(mrmt_env.ASSIGN_IDS)
LIFELONG_IDS = sorted(mrmt_env.LIFELONG_IDS)  # grid actions, no termination
ALL_IDS = GRID_IDS + ASSIGN_IDS + LIFELONG_IDS
#: keyword overrides that keep the worlds small, so a fuzz episode ends within its actions
SMALL = {"height": 5, "width": 5, "obstacle_density": 0.04, "n_robots": 2, "n_targets": 3}


def _small(env_id: str) -> dict:
    """:data:`SMALL` for ``env_id``: a small uniform world also for the ids of other map families."""
    return {**SMALL, "layout": "uniform"} if "layout" in gym.spec(env_id).kwargs else dict(SMALL)


def _direct(env_id: str, limit: int | None, small: bool):
    """The id's env class built directly, with its own step limit (no TimeLimit wrapper)."""
    spec = gym.spec(env_id)
    kwargs = dict(spec.kwargs)
    if small:
        kwargs.update(_small(env_id))
    return load_env_creator(spec.entry_point)(**kwargs, max_episode_steps=limit)


def _state(env) -> tuple:
    """Everything a step may change, for 'nothing changed' checks."""
    u = env.unwrapped
    if hasattr(u, "setup"):  # the lifelong envs
        s = u.state
        return tuple(a.tobytes() for a in (s.pos, s.task_t, s.counters, s.moves, s.draws))
    if hasattr(u, "core"):
        c = u.core
        return (tuple(c.pos), tuple(c.visited), c.steps, c.route_cost, c.invalid_moves, c.vertex_conflicts,
                c.swap_conflicts)
    s = u.state
    return tuple(a.tobytes() for a in (s.cell, s.free_at, s.active, s.open_, s.decider, s.counters))


def _is_grid_action(a, n_robots: int) -> bool:
    try:
        arr = np.asarray(a)
    except (TypeError, ValueError):
        return False
    if arr.shape != (n_robots,):
        return False
    values = arr.tolist()
    if arr.dtype.kind not in "iu" and (arr.dtype.kind != "O" or any(
            isinstance(v, bool) or not isinstance(v, int) for v in values)):
        return False
    return all(0 <= v < 5 for v in values)


def _is_assign_action(a, n_targets: int) -> bool:
    try:
        arr = np.asarray(a)
    except (TypeError, ValueError):
        return False
    if arr.shape not in ((), (1,)):
        return False
    v = arr.reshape(-1)[0]
    v = v.item() if isinstance(v, np.generic) else v
    return isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= n_targets


def _is_move(a) -> bool:
    """A PettingZoo grid agent's move: an integer scalar 0..4 (not a bool)."""
    if isinstance(a, (bool, np.bool_)):
        return False
    try:
        return 0 <= operator.index(a) < 5
    except TypeError:
        return False


def _valid_action(data, env, env_id):
    u = env.unwrapped
    if env_id in mrmt_env.ASSIGN_IDS:
        legal = np.flatnonzero(u.action_masks())
        pick = data.draw(st.one_of(st.sampled_from(legal.tolist()), st.integers(0, u.n_targets)))  # forbidden: no-op
        return data.draw(st.sampled_from([pick, np.int64(pick), np.array(pick), np.array([pick], dtype=np.uint8)]))
    moves = data.draw(st.lists(st.integers(0, 4), min_size=u.n_robots, max_size=u.n_robots))
    return data.draw(st.sampled_from([moves, np.array(moves), np.array(moves, dtype=np.uint8), tuple(moves)]))


@fuzz_settings(40)
@given(env_id=st.sampled_from(ALL_IDS), small=st.booleans(), limit=st.one_of(st.none(), st.integers(1, 12)),
       seed=st.integers(0, 2**64), data=st.data())
def test_step_anything_for_every_id(env_id, small, limit, seed, data):
    env = _direct(env_id, limit, small)
    assign = env_id in mrmt_env.ASSIGN_IDS
    with no_hang():
        obs, info = env.reset(seed=seed)
        assert env.observation_space.contains(obs)
        ended = None
        for _ in range(data.draw(st.integers(0, 60), label="steps")):
            valid = data.draw(st.booleans(), label="valid")
            action = _valid_action(data, env, env_id) if valid else data.draw(junk, label="action")
            good = _is_assign_action(action, env.n_targets) if assign else _is_grid_action(action, env.n_robots)
            before = _state(env)
            try:
                obs, reward, term, trunc, info = env.step(action)
            except RuntimeError as exc:
                assert ended is not None and "the episode has ended" in one_line(exc) and ended in str(exc)
                assert _state(env) == before
                continue
            except ValueError as exc:
                assert not good and ended is None, (action, one_line(exc))
                one_line(exc)
                assert _state(env) == before
                continue
            assert good and ended is None, action
            assert env.observation_space.contains(obs) and np.isfinite(reward)
            assert not (term and trunc)
            if limit is not None and not term:
                assert trunc == (info["steps"] >= limit)
            if term or trunc:
                ended = "terminated" if term else "truncated"
        # reset always brings the env back
        obs, info = env.reset(seed=seed)
        assert info["steps"] == 0 and env.observation_space.contains(obs)


@fuzz_settings(40)
@given(env_id=st.sampled_from(ALL_IDS), seed=junk, options=st.one_of(junk, st.just({"world": "w.json"})))
def test_reset_with_anything(env_id, seed, options):
    env = _direct(env_id, 5, True)
    try:
        obs, info = env.reset(seed=seed, options=options)
    except (TypeError, ValueError, gym.error.Error) as exc:
        one_line(exc)
    else:
        assert env.observation_space.contains(obs) and info["steps"] == 0


def test_gym_make_env_refuses_a_step_after_termination_through_its_wrappers():
    world = mrmt_env.World(np.zeros((1, 3), bool), [[0, 0]], [[0, 1]])
    for env_id in [i for i in GRID_IDS + ASSIGN_IDS if not gym.spec(i).kwargs]:  # ids that take any fixed world
        env = gym.make(env_id, world=world)
        env.reset(seed=0)
        action = 0 if env_id in mrmt_env.ASSIGN_IDS else np.array([4])
        *_, term, trunc, info = env.step(action)
        assert term and not trunc and info["route_cost"] == 1
        with pytest.raises(RuntimeError, match=r"the episode has ended \(terminated at step 1.*call reset\(\)"):
            env.step(action)
        assert env.unwrapped.core.route_cost == 1 if env_id in GRID_IDS else env.unwrapped.state.counters[0, 0] == 1
        env.reset(seed=0)
        assert env.step(action)[2]


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_own_truncation_is_final(env_id):
    world = mrmt_env.World(np.zeros((1, 4), bool), [[0, 0]], [[0, 3]])
    env = load_env_creator(gym.spec(env_id).entry_point)(world=world, max_episode_steps=1)
    env.reset(seed=0)
    if env_id in mrmt_env.ASSIGN_IDS:
        env = load_env_creator(gym.spec(env_id).entry_point)(
            world=mrmt_env.World(np.zeros((1, 4), bool), [[0, 0], [0, 1]], [[0, 2], [0, 3]]), max_episode_steps=1)
        env.reset(seed=0)
        action = 0
    else:
        action = np.array([4])
    *_, term, trunc, info = env.step(action)
    assert trunc and not term and info["steps"] == 1
    before = _state(env)
    with pytest.raises(RuntimeError, match=r"truncated at step 1: max_episode_steps=1\); call reset\(\)"):
        env.step(action)
    assert _state(env) == before


# ------------------------------------------------------------------ PettingZoo
@fuzz_settings(30)
@given(seed=st.integers(0, 2**32), data=st.data())
def test_parallel_env_with_anything(seed, data):
    env = mrmt_env.parallel_env(**SMALL, max_cycles=data.draw(st.integers(1, 8)))
    env.reset(seed=seed)
    with no_hang():
        for _ in range(data.draw(st.integers(0, 20))):
            live = list(env.agents)
            if data.draw(st.booleans()):
                actions = {a: data.draw(st.integers(0, 4)) for a in live}
                good = bool(live)
            else:
                actions = data.draw(st.one_of(junk, st.dictionaries(st.sampled_from(env.possible_agents + ["x"]),
                                                                    junk, max_size=3)))
                good = (isinstance(actions, dict) and set(actions) == set(live) and bool(live)
                        and all(_is_move(v) for v in actions.values()))
            before = _state(env)
            try:
                env.step(actions)
            except RuntimeError as exc:
                assert not live and "episode is over" in one_line(exc)
                assert _state(env) == before
            except (ValueError, TypeError, AttributeError) as exc:
                assert not good, actions
                if isinstance(exc, ValueError):
                    one_line(exc)
                else:  # a non-dict: PettingZoo's contract is a dict of actions
                    assert not isinstance(actions, dict)
                assert _state(env) == before
            else:
                assert good, actions


@fuzz_settings(30)
@given(assign=st.booleans(), seed=st.integers(0, 2**32), data=st.data())
def test_aec_envs_with_anything(assign, seed, data):
    env = (mrmt_env.assign_aec_env(**SMALL, max_cycles=data.draw(st.integers(1, 8))) if assign
           else mrmt_env.env(**SMALL, max_cycles=data.draw(st.integers(1, 8))))
    env.reset(seed=seed)
    n = SMALL["n_targets"] if assign else 4
    with no_hang():
        for _ in range(data.draw(st.integers(0, 30))):
            if not env.agents:
                break
            agent = env.agent_selection
            done = env.terminations[agent] or env.truncations[agent]
            if done:
                action = None
            elif data.draw(st.booleans()):
                action = data.draw(st.integers(0, n))
            else:
                action = data.draw(junk)
            good = done or (_is_assign_action(action, n) if assign else _is_move(action))
            try:
                env.step(action)
            except ValueError as exc:
                assert not good and agent in one_line(exc), action
            else:
                assert good, action


# ------------------------------------------------------------------ vector envs
@fuzz_settings(30)
@given(env_id=st.sampled_from(ALL_IDS), mode=st.sampled_from(["NextStep", "SameStep"]), data=st.data())
def test_vector_envs_refuse_bad_actions_and_keep_autoresetting(env_id, mode, data):
    env = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point", autoreset_mode=mode,
                       max_episode_steps=4, **_small(env_id))
    env.reset(seed=data.draw(st.integers(0, 2**32)))
    ends = 0
    with no_hang():
        for _ in range(data.draw(st.integers(0, 25))):
            if data.draw(st.booleans()):
                action = env.action_space.sample()
                _, _, term, trunc, _ = env.step(action)
                ends += int((term | trunc).sum())
                continue
            action = data.draw(junk)
            try:
                env.step(action)
            except ValueError as exc:
                assert ("0..4" if env_id not in ASSIGN_IDS else f"0..{SMALL['n_targets']}") in one_line(exc)
            else:
                a = np.asarray(action)
                assert a.shape == env.action_space.shape and a.dtype.kind in "iu"
