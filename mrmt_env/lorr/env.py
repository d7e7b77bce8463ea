"""``mrmt_env/LoRR-v0``: a League of Robot Runners instance as a Gymnasium env.

Contract: ``gym.make("mrmt_env/LoRR-v0", instance=PATH)`` (default: the small instance shipped with the package).
One step = one LoRR timestep: the action is the joint MAPF_T move (``MultiDiscrete([4] * R)``), the step's schedule
the scheduler's proposal (``scheduler="greedy"`` by default); reward: tasks finished in the step.
Design notes (scheduling, action models, truncation): docs/design/lorr_simulator.md#the-gymnasium-env.
"""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from mrmt_env.config import EnvConfig
from mrmt_env.core import check_render_mode
from mrmt_env.lorr.greedy import GreedyScheduler
from mrmt_env.lorr.instance import LoRRInstance, example_instance_path, read_instance
from mrmt_env.lorr.loop import StepLoop
from mrmt_env.lorr.rules import ORIENT_LETTERS, n_actions
from mrmt_env.lorr.sim import LoRRSimulator

__all__ = ["LoRREnv", "LoRRSetup", "DEFAULT_STEPS"]

DEFAULT_STEPS = 1000
_ARROWS = ">v<^"


class LoRRSetup:
    """What every form of the LoRR env is built from: the instance, the steps and the scheduler."""

    #: The options of :class:`~mrmt_env.config.EnvConfig` the League envs take.
    config_options = ("instance", "steps", "scheduler", "action_model")

    def __init__(self, config: EnvConfig) -> None:
        instance, steps, scheduler, action_model = config.instance, config.steps, config.scheduler, config.action_model
        self.n_actions = n_actions(action_model)
        self.action_model = action_model
        if instance is None:
            instance = example_instance_path()
        self.instance = instance if isinstance(instance, LoRRInstance) else read_instance(Path(instance))
        limit = steps if steps is not None else (self.instance.steps or DEFAULT_STEPS)
        if isinstance(limit, bool) or not isinstance(limit, (int, np.integer)) or limit < 1:
            raise ValueError(f"steps must be an integer >= 1, got {steps!r}")
        self.steps = int(limit)
        if scheduler == "greedy":
            scheduler = GreedyScheduler()
        elif scheduler is not None and not callable(getattr(scheduler, "schedule", None)):
            raise ValueError(f"scheduler must be 'greedy', None or an object with schedule(sim), got {scheduler!r}")
        self.scheduler = scheduler
        self.sim: LoRRSimulator | None = None
        self.loop: StepLoop | None = None

    @classmethod
    def attach(cls, env, config, render_mode, options: dict) -> LoRRInstance:
        """Check ``render_mode`` against ``env.metadata``; set ``env.render_mode``, ``env.config`` (``config``
        with ``options``) and ``env.setup``; the instance."""
        check_render_mode(render_mode, env.metadata["render_modes"])
        env.render_mode = render_mode
        env.config = EnvConfig.of(config, takes=cls.config_options, env=type(env).__name__, **options)
        env.setup = cls(env.config)
        return env.setup.instance

    def observation_space(self, shape: tuple) -> spaces.Dict:
        """The observation of ``shape`` (``(R,)`` for the whole team, ``()`` for one robot)."""
        cells, big = self.instance.grid.size, np.iinfo(np.int64).max
        return spaces.Dict({
            "position": spaces.Box(0, cells - 1, shape, np.int64),
            "orientation": spaces.Box(0, 3, shape, np.int64),
            "task": spaces.Box(-1, big, shape, np.int64),
            "goal": spaces.Box(-1, cells - 1, shape, np.int64),
        })

    def reset(self) -> None:
        self.sim = LoRRSimulator(self.instance, action_model=self.action_model)
        self.loop = StepLoop(self.sim, self.scheduler)
        self.loop.propose()

    @property
    def pending(self) -> np.ndarray | None:
        """The proposal the coming step applies (``None``: none)."""
        return None if self.loop is None else self.loop.pending

    def running(self) -> tuple[LoRRSimulator, StepLoop]:
        """The simulation and its step loop; ``RuntimeError`` before :meth:`reset`."""
        if self.sim is None or self.loop is None:
            raise RuntimeError("call reset() before step()")
        return self.sim, self.loop

    def propose(self, schedule) -> None:
        self.running()[1].hold(schedule)

    def goals(self) -> tuple[np.ndarray, np.ndarray]:
        """``(task, goal)`` per robot under the pending schedule: the task it is to serve and that
        task's next errand (-1 without one)."""
        sim, loop = self.running()
        pending = loop.pending
        task = sim.tasks.assigned.copy() if pending is None else pending.copy()
        return task, loop.goals()

    def step(self, actions) -> int:
        loop = self.running()[1]
        done = loop.advance(actions)
        loop.propose()
        return done

    def info(self) -> dict:
        sim = self.running()[0]
        return {"step": sim.t, "tasks_finished": sim.finished, "errands_reached": sim.tasks.errands_done,
                "errors": len(sim.errors), "schedule_errors": len(sim.tasks.schedule_errors)}


class LoRREnv(gym.Env):
    """A LoRR instance, one timestep per step (see the module docstring).

    Observation (``Dict``): ``position`` (flat cells ``row * W + col``), ``orientation`` (0 east,
    1 south, 2 west, 3 north), ``task`` (the task each robot is to serve, -1 none) and ``goal``
    (that task's next errand, -1 none), each ``(R,)`` int64.  ``info``: ``step``,
    ``tasks_finished``, ``errands_reached``, ``errors`` (invalid joint actions, each made a wait),
    ``schedule_errors`` (rejected schedules).  Options (``config``, an
    :class:`~mrmt_env.config.EnvConfig`, or keywords): ``instance``, ``steps``, ``scheduler``,
    ``action_model``; and ``render_mode``.
    """

    metadata = {"render_modes": ["ansi", "rgb_array"], "render_fps": 8}
    setup: LoRRSetup  # set by LoRRSetup.attach
    config: EnvConfig

    def __init__(self, config: EnvConfig | None = None, *, render_mode: str | None = None, **options) -> None:
        inst = LoRRSetup.attach(self, config, render_mode, options)
        self.instance = inst
        r = inst.team_size
        self.n_robots = r
        self.action_space = spaces.MultiDiscrete([self.setup.n_actions] * r)
        self.observation_space = self.setup.observation_space((r,))

    @property
    def sim(self) -> LoRRSimulator | None:
        """The simulation (``None`` before :meth:`reset`)."""
        return self.setup.sim

    def propose(self, schedule) -> None:
        """Replace the coming step's schedule (one task id or -1 per robot); it is checked, as the
        start kit checks it, when the step applies it."""
        self.setup.propose(schedule)

    def _obs(self) -> dict:
        task, goal = self.setup.goals()
        sim = self.setup.running()[0]
        return {"position": sim.pos.copy(), "orientation": sim.orient.copy(), "task": task, "goal": goal}

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self.setup.reset()
        return self._obs(), self.setup.info()

    def step(self, action):
        sim = self.setup.running()[0]  # RuntimeError before reset()
        done = self.setup.step(action)
        truncated = sim.t >= self.setup.steps
        return self._obs(), float(done), False, truncated, self.setup.info()

    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; give render_mode='ansi' or 'rgb_array'")
            return None
        return render_lorr(self.setup, self.render_mode)


def render_lorr(setup: LoRRSetup, mode: str):
    """``ansi``: the map with robots as arrows (``>v<^``), goals ``*``; ``rgb_array``: the same as
    an ``(H, W, 3)`` uint8 image (obstacles dark, goals yellow, robots blue)."""
    inst, sim = setup.instance, setup.running()[0]
    h, w = inst.grid.shape
    _, goal = setup.goals()
    if mode == "rgb_array":
        img = np.full((h * w, 3), 255, dtype=np.uint8)
        img[inst.grid.reshape(-1)] = (40, 40, 40)
        img[goal[goal >= 0]] = (230, 190, 30)
        img[sim.pos] = (40, 90, 220)
        return img.reshape(h, w, 3)
    rows = [["@" if b else "." for b in row] for row in inst.grid.tolist()]
    for g in goal[goal >= 0].tolist():
        rows[g // w][g % w] = "*"
    for p, o in zip(sim.pos.tolist(), sim.orient.tolist()):
        rows[p // w][p % w] = _ARROWS[o]
    head = f"t={sim.t} tasks finished={sim.finished} errors={len(sim.errors)} (robots {''.join(ORIENT_LETTERS)} = >v<^)"
    return head + "\n" + "\n".join("".join(r) for r in rows) + "\n"
