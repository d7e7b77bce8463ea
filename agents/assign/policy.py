"""A planner acting in the plan-level env ``MRMT-Assign-v0``: its plan's target orders become actions.

:class:`AssignPlannerPolicy` plans once per episode (:meth:`~AssignPlannerPolicy.begin_episode`), then answers each
decision with the deciding robot's next planned target and ``stop`` once its order is done; where a failed plan
left targets out, the deciding robot goes to the nearest legal target (counted in :attr:`fallbacks`).
Design notes: docs/design/learned-agents.md#a-planner-in-the-plan-level-env.
"""

from __future__ import annotations

import numpy as np

from agents.policy import resolve_pipeline
from mrmt_env.assign.kernels import N_ROBOT_FEATURES
from planners.compute import ComputeReport

__all__ = ["AssignPlannerPolicy"]

_DECIDER_COL = 6
_DIST_COL = 4


class AssignPlannerPolicy:
    """A pipeline (preset name or object with ``plan(world, seed)``) as a plan-level controller.

    ``predict(obs, episode_start=..., action_masks=...)`` needs the episode's
    world first: call :meth:`begin_episode` after every ``reset``.
    """

    uses_action_masks = True

    def __init__(self, pipeline="strong", seed: int = 0, **options) -> None:
        self.pipeline, self.name = resolve_pipeline(pipeline, options)
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
        self.seed = int(seed)
        self.fallbacks = 0
        self._world: dict[int, object] = {}
        self._plan: dict[int, object] = {}
        self._orders: dict[int, list[list[int]]] = {}

    def begin_episode(self, env, index: int = 0) -> None:
        """Take the world of the episode ``env`` (a ``MRMTAssignEnv``, unwrapped or not) has just reset to."""
        world = getattr(getattr(env, "unwrapped", env), "world", None)
        if world is None:
            raise ValueError("begin_episode needs an env that has been reset (its .world is None)")
        self._world[index] = world
        self._plan.pop(index, None)

    def _make_plan(self, index: int) -> None:
        world = self._world.get(index)
        if world is None:
            raise RuntimeError(f"{self!r}: call begin_episode(env) after reset; the observation holds no grid")
        plan = self.pipeline.plan(world, seed=self.seed)
        self._plan[index] = plan
        self._orders[index] = [list(r.targets) for r in plan.routes]

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True, action_masks=None):
        """The deciding robot's next planned target (``N`` = stop); SB3-style ``(action, state)``."""
        obs = np.asarray(observation)
        if obs.ndim != 2:
            raise ValueError(f"observation must have shape (N + R, 8 + N) (one env), got {obs.shape}")
        n = obs.shape[1] - N_ROBOT_FEATURES
        if action_masks is None:
            raise ValueError("action_masks is needed (env.action_masks() or info['action_mask'])")
        mask = np.asarray(action_masks, dtype=bool).reshape(-1)
        if mask.shape != (n + 1,):
            raise ValueError(f"action_masks must have {n + 1} entries, got {mask.shape}")
        index = 0
        if bool(np.any(episode_start)) or index not in self._plan:
            self._make_plan(index)
        k = int(np.argmax(obs[n:, _DECIDER_COL]))
        order = self._orders[index][k] if k < len(self._orders[index]) else []
        while order and not mask[order[0]]:
            order.pop(0)  # visited already (cannot happen with a valid plan, but never act illegally)
        if order:
            return np.int64(order.pop(0)), state
        if mask[n]:
            return np.int64(n), state
        self.fallbacks += 1
        dist = np.where(mask[:n], obs[:n, _DIST_COL], np.inf)
        return np.int64(int(np.argmin(dist))), state

    __call__ = predict

    def episode_compute(self, index: int = 0) -> ComputeReport:
        plan = self._plan.get(index)
        return ComputeReport() if plan is None else plan.compute

    def episode_plans(self, index: int = 0) -> list:
        plan = self._plan.get(index)
        return [] if plan is None else [plan]

    def __repr__(self) -> str:
        return f"AssignPlannerPolicy({self.name!r}, seed={self.seed})"
