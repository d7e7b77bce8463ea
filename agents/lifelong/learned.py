"""The training env of the learned lifelong controller (:mod:`agents.lifelong.choice`).

:class:`LifelongDecisionEnv` (``mrmt train --env-id mrmt_env/MRMT-Lifelong-v0``): one step per
decision; reward = tasks served in the env steps it advances before the next decision minus the
episode's throughput so far times those steps (a differential, average-reward return: with tasks
alone, a discount per decision would favour far tasks, which space decisions out).
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from agents.lifelong.controllers import LifelongController
from agents.lifelong.choice import N_CANDIDATES, TaskChooser, decision_spaces

__all__ = ["LifelongDecisionEnv", "decision_vec_env"]


class LifelongDecisionEnv(gym.Env):
    """One step per idle robot's task choice on a lifelong id (see the module docstring).

    ``env_id`` / ``env_kwargs``: the lifelong env; ``max_episode_steps``: its steps per episode
    (default: the id's).  Each ``step(a)`` gives the deciding robot candidate ``a`` (an action the
    mask forbids raises ``ValueError``), then runs env steps (moves by ``executor``) until another
    decision is due; reward: see the module docstring.  Truncated when the lifelong episode is;
    ``info`` is the lifelong env's (plus ``robot``: the robot deciding next)."""

    metadata = {"render_modes": []}

    def __init__(self, env_id: str = "mrmt_env/MRMT-Lifelong-v0", env_kwargs: dict | None = None,
                 max_episode_steps: int | None = None, executor: str = "pibt") -> None:
        import mrmt_env

        if env_id not in mrmt_env.LIFELONG_IDS:
            raise ValueError(f"env_id must be a lifelong id ({', '.join(mrmt_env.LIFELONG_IDS)}), got {env_id!r}")
        kwargs = dict(env_kwargs or {})
        if max_episode_steps is not None:
            kwargs["max_episode_steps"] = max_episode_steps
        self.env = gym.make(env_id, **kwargs)
        self.observation_space, self.action_space = decision_spaces()
        self.ctrl = LifelongController(_Pending(), executor=executor)
        self.chooser: TaskChooser | None = None
        self._mask = np.zeros(N_CANDIDATES, dtype=bool)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        obs, info = self.env.reset(seed=seed if seed is None else int(seed), options=options)
        self.ctrl.seed = 0 if seed is None else int(seed)
        self.ctrl.reset()
        self._served0, self._steps0 = info["tasks_completed"], info["steps"]
        x, _, _, info = self._advance(obs, info)
        return x, info

    def action_masks(self) -> np.ndarray:
        return self._mask.copy()

    def step(self, action):
        if self.chooser is None:
            raise RuntimeError("call reset() before step() (or after the episode ended)")
        if not (0 <= int(action) < N_CANDIDATES and self._mask[int(action)]):
            raise ValueError(f"action {action!r} is masked: allowed candidates {np.flatnonzero(self._mask).tolist()}")
        self.chooser.choose(action)
        if self.chooser.next_robot() is not None:
            x, self._mask = self.chooser.observation()
            return x, 0.0, False, False, dict(self._info, robot=int(self.chooser.idle[self.chooser.cursor]))
        self.ctrl.apply(self._round, self.chooser.queues)
        obs, _, term, trunc, info = self.env.step(self.ctrl.move(self._round))
        if term or trunc:
            return self._end(info)
        x, reward, ended, info = self._advance(obs, info)
        return x, reward, False, ended, info

    def _end(self, info):
        self.chooser = None
        self._mask = np.zeros(N_CANDIDATES, dtype=bool)
        reward = self._reward(info)
        return np.zeros(self.observation_space.shape, np.float32), reward, False, True, dict(info, robot=-1)

    def _reward(self, info) -> float:
        """Tasks served since the last decision minus the episode's rate so far times the steps taken."""
        done, steps = info["tasks_completed"], info["steps"]
        rate = self._served0 / self._steps0 if self._steps0 else 0.0
        reward = float(done - self._served0) - rate * (steps - self._steps0)
        self._served0, self._steps0 = done, steps
        return reward

    def _advance(self, obs, info):
        """Env steps until a decision is due; ``(observation, reward, truncated, info)``."""
        while True:
            rnd = self.ctrl.observe(obs)
            if len(rnd.idle) and len(rnd.unclaimed):
                chooser = TaskChooser(self.ctrl.fields, rnd)
                if chooser.next_robot() is not None:
                    self.chooser, self._round, self._info = chooser, rnd, info
                    x, self._mask = chooser.observation()
                    reward = self._reward(info)
                    return x, reward, False, dict(info, robot=int(chooser.idle[chooser.cursor]))
            obs, _, term, trunc, info = self.env.step(self.ctrl.move(rnd))
            if term or trunc:
                x, reward, _terminated, _truncated, info = self._end(info)
                return x, reward, True, info


def decision_vec_env(env_id: str, env_kwargs: dict, n_envs: int, seed: int):
    """``n_envs`` :class:`LifelongDecisionEnv` as an SB3 ``VecEnv`` (``DummyVecEnv`` + ``VecMonitor``),
    env ``i`` seeded ``seed + i``."""
    from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor

    kwargs = dict(env_kwargs)
    steps = kwargs.pop("max_episode_steps", None)
    venv = DummyVecEnv([lambda: LifelongDecisionEnv(env_id, kwargs, steps) for _ in range(n_envs)])
    venv.seed(seed)
    return VecMonitor(venv)


class _Pending:
    """The training env's stand-in assigner: the decisions come from ``step`` (never called)."""

    name = "ppo"
    accelerated = False
