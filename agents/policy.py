"""A planner as a policy: plan once, then emit one joint move per step.

:class:`PlannerPolicy` wraps any pipeline (a preset name or a :class:`planners.pipeline.Pipeline`) behind the
stable-baselines3 policy interface, so ``evaluate_policy`` scores a planner as it scores a PPO model::

    action, state = policy.predict(observation, state=None, episode_start=None, deterministic=True)

Design notes (replanning, seeds, compute, PettingZoo): docs/design/evaluation.md#a-planner-as-a-policy.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mrmt_env.core import action_between, actions_from_path
from mrmt_env.observation import ROBOT_CHANNEL0, TARGET_CHANNEL, world_from_observation
from mrmt_env.world import World
from planners.compute import ComputeReport
from planners.plan import Plan

__all__ = ["PlannerPolicy", "move_action", "resolve_pipeline", "DEFAULT_MAX_REPLANS"]

#: Replans allowed per episode after a plan runs out with targets left.
DEFAULT_MAX_REPLANS = 3


#: The action taking a robot from one cell to the next (the env's own helper).
move_action = action_between


@dataclass
class _Episode:
    """Per-env-index state: the current plan and where the robots are in it."""

    plan: Plan | None = None
    actions: list = field(default_factory=list)
    world: World | None = None
    t: int = 0
    n_plans: int = 0
    replans: int = 0
    compute: ComputeReport = field(default_factory=ComputeReport)
    plans: list = field(default_factory=list)

    def expected_cells(self) -> np.ndarray:
        return np.array([r.path[min(self.t, len(r.path) - 1)] for r in self.plan.routes], dtype=np.int64)

    def exhausted(self) -> bool:
        return all(self.t >= len(r.path) - 1 for r in self.plan.routes)


def resolve_pipeline(pipeline, options: dict):
    """``(pipeline, name)`` from a preset name (built with ``options``) or an object with ``plan(world, seed)``."""
    if isinstance(pipeline, str):
        from planners.pipeline import make_pipeline

        return make_pipeline(pipeline, **options), pipeline
    if options:
        raise TypeError(f"options {sorted(options)} only apply when pipeline is a preset name")
    if not callable(getattr(pipeline, "plan", None)):
        raise TypeError(f"pipeline must be a preset name or have .plan(world, seed), got {pipeline!r}")
    return pipeline, getattr(pipeline, "name", type(pipeline).__name__)


def _robot_cells(obs: np.ndarray) -> np.ndarray:
    chans = obs[ROBOT_CHANNEL0:]
    flat = chans.reshape(chans.shape[0], -1).argmax(axis=1)
    return np.stack(np.unravel_index(flat, obs.shape[1:]), axis=1).astype(np.int64)


class PlannerPolicy:
    """A planning pipeline acting as a stable-baselines3-style policy.

    Args:
        pipeline: a preset name for :func:`planners.pipeline.make_pipeline`
            (``"fast"``, ``"strong"``, ``"ising"``) or an object with
            ``plan(world, seed) -> Plan``.
        seed: seed of the first plan of each episode (later plans of the same
            episode use ``seed + 1``, ``seed + 2``, ...).
        max_replans: plans allowed per episode after the first (when the
            world stops matching the plan or a plan runs out with targets
            left); past it the robots stay.
        **options: passed to ``make_pipeline`` when ``pipeline`` is a name.

    Attributes:
        last_compute: compute report of the most recent plan (``None`` before).
        total_compute: sum over every plan this policy made.
        n_plans: number of plans made.
    """

    def __init__(self, pipeline="strong", seed: int = 0, max_replans: int = DEFAULT_MAX_REPLANS, **options):
        self.pipeline, self.name = resolve_pipeline(pipeline, options)
        for name, value in (("seed", seed), ("max_replans", max_replans)):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
                raise ValueError(f"{name} must be an integer >= 0, got {value!r}")
        self.seed = int(seed)
        self.max_replans = int(max_replans)
        self.last_compute: ComputeReport | None = None
        self.total_compute = ComputeReport()
        self.n_plans = 0
        self._episodes: dict[int, _Episode] = {}
        self._agent_cache: tuple[bytes, np.ndarray, set] | None = None

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Forget every episode's plan (the running totals are kept)."""
        self._episodes.clear()
        self._agent_cache = None

    def episode_compute(self, index: int = 0) -> ComputeReport:
        """Sum of the compute reports of the plans made in env ``index``'s current episode."""
        ep = self._episodes.get(index)
        return ComputeReport() if ep is None else ep.compute

    def episode_plans(self, index: int = 0) -> list[Plan]:
        """The plans made in env ``index``'s current episode, first one first."""
        ep = self._episodes.get(index)
        return [] if ep is None else list(ep.plans)

    def current_plan(self, index: int = 0) -> Plan | None:
        ep = self._episodes.get(index)
        return None if ep is None else ep.plan

    def plan_step(self, index: int = 0) -> int:
        """How many steps of env ``index``'s current plan have been acted (0 before the first)."""
        ep = self._episodes.get(index)
        return 0 if ep is None else ep.t

    def current_world(self, index: int = 0) -> World | None:
        """The world rebuilt from the observation the current plan was made for."""
        ep = self._episodes.get(index)
        return None if ep is None else ep.world

    # ----------------------------------------------------------------- acting
    def _plan(self, ep: _Episode, obs: np.ndarray) -> None:
        world = world_from_observation(obs)
        plan = self.pipeline.plan(world, seed=self.seed + ep.n_plans)
        ep.plan, ep.world, ep.t = plan, world, 0
        ep.actions = [actions_from_path(r.path) for r in plan.routes]
        ep.n_plans += 1
        ep.plans.append(plan)
        ep.compute = ep.compute + plan.compute
        self.last_compute = plan.compute
        self.total_compute = self.total_compute + plan.compute
        self.n_plans += 1

    def _act(self, index: int, obs: np.ndarray, start: bool) -> np.ndarray:
        n_robots = obs.shape[0] - ROBOT_CHANNEL0
        if n_robots < 1:
            raise ValueError(f"observation has {obs.shape[0]} channels; expected 2 + R with R >= 1")
        ep = self._episodes.get(index)
        if start or ep is None:
            ep = self._episodes[index] = _Episode()
        if not obs[TARGET_CHANNEL].any():
            return np.zeros(n_robots, dtype=np.int64)  # nothing left to visit
        if ep.plan is None:
            self._plan(ep, obs)
        else:
            cells = _robot_cells(obs)
            mismatch = len(ep.plan.routes) != n_robots or not np.array_equal(cells, ep.expected_cells())
            if mismatch or ep.exhausted():
                if ep.replans >= self.max_replans:
                    return np.zeros(n_robots, dtype=np.int64)
                ep.replans += 1
                self._plan(ep, obs)
        action = np.zeros(n_robots, dtype=np.int64)
        for k, moves in enumerate(ep.actions):
            if ep.t < len(moves):
                action[k] = moves[ep.t]
        ep.t += 1
        return action

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        """SB3 policy interface: ``(action, state)``.

        Args:
            observation: ``(2 + R, H, W)`` or a batch ``(n_envs, 2 + R, H, W)``.
            state: passed through unchanged (the policy keeps its own per-index plans).
            episode_start: bool or ``(n_envs,)`` bools; true forces a new plan.
            deterministic: accepted for interface compatibility (planning is
                seeded, hence always deterministic).

        Returns:
            ``(action, state)`` with action ``(R,)`` or ``(n_envs, R)`` int64.
        """
        obs = np.asarray(observation)
        if obs.ndim == 3:
            start = bool(np.any(episode_start)) if episode_start is not None else False
            return self._act(0, obs, start), state
        if obs.ndim == 4:
            n = obs.shape[0]
            if episode_start is None:
                starts = np.zeros(n, dtype=bool)
            else:
                starts = np.asarray(episode_start, dtype=bool)
                if starts.ndim > 1 or starts.size not in (1, n):
                    raise ValueError(
                        f"episode_start must be a bool or {n} bools (one per env in the batch), got shape {starts.shape}"
                    )
                starts = np.broadcast_to(starts, (n,))
            return np.stack([self._act(i, obs[i], bool(starts[i])) for i in range(n)]), state
        raise ValueError(f"observation must have shape (C, H, W) or (n_envs, C, H, W), got {obs.shape}")

    __call__ = predict

    # ------------------------------------------------------------ PettingZoo
    @staticmethod
    def _agent_index(agent: str, n_robots: int) -> int:
        prefix, _, num = str(agent).rpartition("_")
        if not num.isdigit() or not (0 <= int(num) < n_robots):
            raise ValueError(f"agent name {agent!r} is not robot_k with k in 0..{n_robots - 1}")
        return int(num)

    def predict_parallel(self, observations: dict, episode_start: bool = False, index: int = 0) -> dict:
        """Per-robot form for the PettingZoo parallel env: one shared plan.

        Args:
            observations: ``{agent: (3 + R, H, W) observation}`` (the global
                channels plus the agent's own cell), as ``parallel_env`` gives.
            episode_start: true right after ``reset``.

        Returns:
            ``{agent: action}`` for every agent in ``observations``.
        """
        if not observations:
            return {}
        first = np.asarray(next(iter(observations.values())))
        if first.ndim != 3:
            raise ValueError(f"agent observation must have shape (3 + R, H, W), got {first.shape}")
        joint = self._act(index, first[:-1], episode_start)
        return {a: int(joint[self._agent_index(a, len(joint))]) for a in observations}

    def predict_agent(self, agent: str, observation, episode_start: bool = False, index: int = 0) -> int:
        """Per-robot form for the AEC env (``env.last()`` one agent at a time).

        The joint move is computed once per round (when the global
        observation changes or an agent asks a second time) and each agent
        gets its own component, so all agents follow the same plan step.
        ``episode_start`` may be passed for every agent of the first round
        after ``reset``; only the call that computes the joint move uses it.
        """
        obs = np.asarray(observation)
        if obs.ndim != 3:
            raise ValueError(f"agent observation must have shape (3 + R, H, W), got {obs.shape}")
        glob = obs[:-1]
        key = glob.tobytes()
        k = self._agent_index(agent, glob.shape[0] - ROBOT_CHANNEL0)
        cache = self._agent_cache
        if cache is None or cache[0] != key or k in cache[2]:
            joint = self._act(index, glob, episode_start)
            cache = self._agent_cache = (key, joint, set())
        cache[2].add(k)
        return int(cache[1][k])

    def __repr__(self) -> str:
        return f"PlannerPolicy({self.name!r}, seed={self.seed})"
