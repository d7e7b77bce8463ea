"""Multi-start decoding of a learned allocator in the plan-level env (POMO-style).

:class:`MultiStartPolicy` wraps a MaskablePPO model of ``MRMT-Assign-v0``: one greedy rollout per legal first
decision in a private batch of the env's dynamics, the cheapest kept and then acted; every forward pass is charged
as inference time. Controller spec: ``ppo-ms:model.zip``.
Design notes: docs/design/learned-agents.md#multi-start-decoding.
"""

from __future__ import annotations

import time

import numpy as np

from mrmt_env.assign.state import AssignBatch
from planners.compute import ComputeReport

__all__ = ["MultiStartPolicy"]


class MultiStartPolicy:
    """A learned plan-level allocator decoded from every legal first decision, best kept.

    Args:
        learned: a :class:`agents.learned.training.LearnedPolicy` holding a MaskablePPO model.
    """

    uses_action_masks = True

    def __init__(self, learned) -> None:
        if not getattr(learned, "uses_action_masks", False):
            raise ValueError(f"multi-start decoding needs a MaskablePPO model of the plan-level env, got {learned!r}")
        self.learned = learned
        self.model = learned.model
        self.name = learned.name.replace("ppo:", "ppo-ms:", 1)
        self._world = None
        self._actions: list[int] = []
        self._cpu_s = 0.0
        self.last_costs: np.ndarray | None = None

    def begin_episode(self, env, index: int = 0) -> None:
        """Search from the world ``env`` (a ``MRMTAssignEnv``) has just reset to."""
        u = getattr(env, "unwrapped", env)
        if getattr(u, "world", None) is None:
            raise ValueError("begin_episode needs an env that has been reset (its .world is None)")
        self._world = u.world
        self._actions = []
        self._cpu_s = 0.0
        self._search(u)

    def _search(self, env) -> None:
        t0 = time.perf_counter()
        world = self._world
        probe = AssignBatch(1, env.state.height, env.state.width, world.n_robots, world.n_targets)
        probe.load(0, world)
        first = np.flatnonzero(probe.masks()[0])
        k = len(first)
        batch = AssignBatch(k, env.state.height, env.state.width, world.n_robots, world.n_targets)
        for i in range(k):
            batch.load(i, world)
        actions = [first.astype(np.int64)]
        done = np.zeros(k, dtype=bool)
        _, term = batch.step(actions[0])
        done |= term
        limit = world.n_targets + world.n_robots
        while not done.all() and len(actions) < limit:
            obs = batch.observe()
            masks = batch.masks()
            a, _ = self.model.predict(obs, action_masks=masks, deterministic=True)
            a = np.where(done, world.n_targets, np.asarray(a, dtype=np.int64))  # finished rollouts: ignored
            actions.append(a)
            _, term = batch.step(a)
            done |= term
        self._cpu_s += time.perf_counter() - t0
        costs = batch.counters[:, 0].astype(np.float64)
        costs[~done] = np.inf
        self.last_costs = costs
        best = int(np.argmin(costs))
        self._actions = [int(step[best]) for step in actions]

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True, action_masks=None):
        """The chosen rollout's next decision (the env must follow it: the search replays its dynamics)."""
        if self._world is None:
            raise RuntimeError(f"{self!r}: call begin_episode(env) after reset")
        if not self._actions:
            raise RuntimeError(f"{self!r}: the searched rollout is finished but the env asks for another decision")
        a = self._actions.pop(0)
        if action_masks is not None and not np.asarray(action_masks, dtype=bool).reshape(-1)[a]:
            raise RuntimeError(f"{self!r}: the env left the searched rollout (action {a} is not legal now); "
                               "was begin_episode called right after reset?")
        return np.int64(a), state

    __call__ = predict

    def episode_compute(self, index: int = 0) -> ComputeReport:
        return ComputeReport(cpu_s=self._cpu_s)

    def __repr__(self) -> str:
        return f"MultiStartPolicy({self.name!r})"
