"""The learned lifelong controller's decision: its candidates, features and the assigner that asks a policy.

An idle robot picks one of its :data:`N_CANDIDATES` nearest unclaimed open tasks; the observation is
``N_CANDIDATES x N_FEATURES`` normalised numbers per decision (:func:`TaskChooser.observation`), so one model fits
any world size. :class:`LearnedAssigner` is the controller's assigner (``ppo:model.zip`` in ``mrmt compare``).
Design notes (the features): docs/design/learned-agents.md#lifelong-an-idle-robots-next-task.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from planners.compute import ComputeReport

__all__ = ["N_CANDIDATES", "N_FEATURES", "TaskChooser", "LearnedAssigner", "decision_spaces"]

N_CANDIDATES = 8
N_FEATURES = 8
#: Moves within which a robot counts as near a task (feature 5) and its scale.
NEAR, NEAR_SCALE = 3, 4.0
_FAR = np.int64(1 << 40)


def decision_spaces() -> tuple[spaces.Box, spaces.Discrete]:
    """The decision's observation ``(N_CANDIDATES * N_FEATURES,)`` float32 and action ``Discrete(N_CANDIDATES)``."""
    obs = spaces.Box(-np.inf, np.inf, (N_CANDIDATES * N_FEATURES,), np.float32)
    return obs, spaces.Discrete(N_CANDIDATES)


class TaskChooser:
    """The decisions of one step: idle robots in index order each take one of their nearest unclaimed tasks.

    ``fleet`` is the step's :class:`agents.lifelong.controllers.Round`; ``fields`` the controller's
    :class:`planners.mapf.common.GoalFields`.  :meth:`next_robot` advances to the next idle robot with
    a candidate (``None`` when none is left), :meth:`observation` gives its features and mask,
    :meth:`choose` records its choice; :attr:`queues` are the choices as indices into ``fleet.unclaimed``.
    """

    def __init__(self, fields, fleet) -> None:
        h, w = fleet.grid.shape
        self.scale = float(h + w)
        self.n_robots = len(fleet.pos)
        self.idle = fleet.idle
        self.unclaimed = fleet.unclaimed
        busy = np.ones(self.n_robots, dtype=bool)
        busy[fleet.idle] = False
        bi = np.flatnonzero(busy)
        u = len(fleet.unclaimed)
        rows = fields.rows(np.concatenate([fleet.unclaimed, fleet.goals[bi]]))  # one call: no row is evicted
        f = fields.fields
        to_pos = f[np.ix_(rows[:u], fleet.pos)].astype(np.int64)  # (U, R): task -> robot cell
        to_goal = f[np.ix_(rows[:u], fleet.goals)].astype(np.int64)  # (U, R): task -> robot's goal
        self.between = f[np.ix_(rows[:u], fleet.unclaimed)].astype(np.int64)  # (U, U)
        for d in (to_pos, to_goal, self.between):
            d[d < 0] = _FAR
        remaining = np.zeros(self.n_robots, dtype=np.int64)
        remaining[bi] = f[rows[u:], fleet.pos[bi]]
        rows = rows[:u]
        self.to_pos, self.to_goal = to_pos, to_goal
        self.eta = np.where(busy[None, :], remaining[None, :] + to_goal, to_pos)  # (U, R)
        np.fill_diagonal(self.between, _FAR)
        self.near = (to_pos <= NEAR).sum(axis=1)
        self.free = np.ones(len(fleet.unclaimed), dtype=bool)
        self.queues: list[list[int]] = [[] for _ in fleet.idle]
        self.cursor = -1
        self.cand = np.zeros(0, dtype=np.int64)

    def next_robot(self) -> int | None:
        """Move to the next idle robot that has a reachable unclaimed task; its index in ``fleet.idle``."""
        while self.cursor + 1 < len(self.idle):
            self.cursor += 1
            k = int(self.idle[self.cursor])
            d = np.where(self.free, self.to_pos[:, k], _FAR)
            ok = np.flatnonzero(d < _FAR)
            if len(ok) == 0:
                continue
            order = ok[np.argsort(d[ok], kind="stable")]
            self.cand = order[:N_CANDIDATES]
            return self.cursor
        return None

    def observation(self) -> tuple[np.ndarray, np.ndarray]:
        """Features ``(N_CANDIDATES * N_FEATURES,)`` and mask ``(N_CANDIDATES,)`` of the current robot's choice."""
        k = int(self.idle[self.cursor])
        c = self.cand
        x = np.zeros((N_CANDIDATES, N_FEATURES), dtype=np.float32)
        n = len(c)
        others = self.eta[c].copy()
        others[:, k] = _FAR
        rival = others.min(axis=1) if self.n_robots > 1 else np.full(n, _FAR)
        rival = np.minimum(rival, 4 * int(self.scale))  # no other robot: "far" (4 (H + W))
        nxt = np.where(self.free[None, :], self.between[c], _FAR).min(axis=1)
        nxt = np.minimum(nxt, 4 * int(self.scale))
        d = self.to_pos[c, k]
        x[:n, 0] = 1.0
        x[:n, 1] = d / self.scale
        x[:n, 2] = rival / self.scale
        x[:n, 3] = (d - rival) / self.scale
        x[:n, 4] = nxt / self.scale
        x[:n, 5] = self.near[c] / NEAR_SCALE
        x[:n, 6] = (len(self.idle) - self.cursor) / self.n_robots
        x[:n, 7] = self.free.sum() / self.n_robots
        mask = np.zeros(N_CANDIDATES, dtype=bool)
        mask[:n] = True
        return x.reshape(-1), mask

    def choose(self, action) -> int:
        """The current robot takes candidate ``action``; returns the task's index in ``fleet.unclaimed``."""
        a = int(action)
        if not 0 <= a < len(self.cand):
            raise ValueError(f"action {action!r} is not an allowed candidate: the robot has {len(self.cand)} "
                             f"(0..{len(self.cand) - 1}); see action_masks()")
        j = int(self.cand[a])
        k = int(self.idle[self.cursor])
        self.free[j] = False
        self.queues[self.cursor] = [j]
        # the robot is now busy with task j: others see its way there, then onwards
        self.eta[:, k] = self.to_pos[j, k] + np.minimum(self.between[:, j], _FAR)
        self.eta[j, k] = self.to_pos[j, k]
        return j


class LearnedAssigner:
    """An assigner (:class:`agents.lifelong.controllers.LifelongController`) asking a policy, one idle robot at a time.

    ``policy``: a :class:`agents.learned.policy.LearnedPolicy` (or anything with ``predict(obs,
    action_masks=...)``).  Inference runs on the host; its time is part of the decision's latency."""

    accelerated = False

    def __init__(self, policy, name: str = "ppo") -> None:
        self.policy = policy
        self.name = name

    def assign(self, grid, fields, idle_cells, tasks, seed, fleet=None) -> tuple[list[list[int]], ComputeReport]:
        if fleet is None:
            raise ValueError("the learned assigner needs the fleet (a Round from LifelongController.observe)")
        chooser = TaskChooser(fields, fleet)
        while chooser.next_robot() is not None:
            obs, mask = chooser.observation()
            action, _ = self.policy.predict(obs, deterministic=True, action_masks=mask)
            chooser.choose(int(np.asarray(action).reshape(-1)[0]))
        return chooser.queues, ComputeReport()
