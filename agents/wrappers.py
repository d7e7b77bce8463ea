"""Opt-in Gymnasium wrapper putting compute, latency and energy into ``info`` at episode end.

The base env stays deterministic (no wall-clock value ever enters its
``info``); users who run their own loop and want the evaluation runner's
compute columns wrap the env with :class:`ComputeInfoWrapper`.  On the step
that ends an episode (``terminated or truncated``) ``info`` gains the
:data:`agents.evaluation.COMPUTE_KEYS` (``cpu_s``, ``chip_calls``,
``chip_batches``, ``logical_calls``, ``chip_time_s``, ``chip_time_parallel_s``,
``latency_s``, ``latency_parallel_s``, ``accelerator_energy_j``,
``host_energy_j``, ``total_energy_j``, ``retries``, ``fallbacks``, ``warmup_s`` -- the one-off
kernel warm-up before a pipeline's first plan, apart from ``cpu_s``); on every other step ``info`` is the
base env's, unchanged.

Where the numbers come from:

* with ``controller=`` an object that has ``episode_compute(index)`` (a
  :class:`agents.policy.PlannerPolicy` or :class:`agents.learned.training.LearnedPolicy`),
  its report for the episode (planning compute, chip counts, inference time);
* without one, the wrapper measures the host time the caller spends between
  one ``reset``/``step`` returning and the next ``step`` call -- the time the
  user's controller took to choose its actions -- as ``cpu_s`` (no chip).
"""

from __future__ import annotations

import time

import gymnasium as gym

from agents.evaluation import COMPUTE_KEYS, compute_record
from planners.compute import ComputeReport

__all__ = ["ComputeInfoWrapper", "COMPUTE_KEYS"]


class ComputeInfoWrapper(gym.Wrapper):
    """Adds the episode's compute record to ``info`` when the episode ends.

    Args:
        env: the Gymnasium env.
        controller: optional object with ``episode_compute(index) -> ComputeReport``.
        index: the env index passed to ``episode_compute`` (0 for a single env).
    """

    def __init__(self, env: gym.Env, controller=None, index: int = 0):
        super().__init__(env)
        if controller is not None and not callable(getattr(controller, "episode_compute", None)):
            raise TypeError(f"controller must have episode_compute(index), got {controller!r}")
        self.controller = controller
        self.index = int(index)
        self._think_s = 0.0
        self._returned_at: float | None = None

    def reset(self, **kwargs):
        out = self.env.reset(**kwargs)
        self._think_s = 0.0
        self._returned_at = time.perf_counter()
        return out

    def step(self, action):
        now = time.perf_counter()
        if self._returned_at is not None:
            self._think_s += now - self._returned_at
        obs, reward, terminated, truncated, info = self.env.step(action)
        if terminated or truncated:
            if self.controller is not None:
                report = self.controller.episode_compute(self.index)
            else:
                report = ComputeReport(cpu_s=self._think_s)
            info = dict(info)
            info.update(compute_record(report))
        self._returned_at = time.perf_counter()
        return obs, reward, terminated, truncated, info
