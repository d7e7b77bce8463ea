"""Opt-in Gymnasium wrapper putting compute, latency and energy into ``info`` at episode end.

:class:`ComputeInfoWrapper` adds :data:`agents.evaluation.COMPUTE_KEYS` to the ``info`` of the step that ends an
episode: the report of ``controller=`` (``episode_compute(index)``) when given one, else the host time the caller
spends choosing actions. The base env stays deterministic.
Design notes: docs/design/evaluation.md#compute-in-info.
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
