"""One frozen record of an env's options, taken by every env constructor (POGEMA's ``GridConfig`` scope).

``EnvConfig`` holds the world (where worlds come from: a fixed world or file, or the generator's size,
density, counts, placement and map family), the episode (step limit, rewards, observation), the
lifelong task stream and the League instance.  Every env of the package takes one as ``config`` and
accepts the same names as keywords (what ``gym.make(id, n_robots=5)`` passes), which override it; an
env refuses, naming them, the options it does not take.  ``WorldConfig`` is the world part alone and is
accepted wherever an ``EnvConfig`` is.  World values are checked where worlds are made
(:class:`~mrmt_env.core.WorldSource`), the rest here or by the env part that owns them.
"""

from __future__ import annotations

from dataclasses import MISSING, dataclass, fields, replace
from typing import Any

import numpy as np

from mrmt_env.core import WorldSource, check_step_limit

__all__ = ["EnvConfig", "WorldConfig", "OBSERVATIONS", "WORLD_OPTIONS"]

#: Observation forms of the grid env.
OBSERVATIONS = ("binary", "image")


@dataclass(frozen=True)
class WorldConfig:
    """World arguments (``None``: the default; see :class:`~mrmt_env.core.WorldSource`).

    Attributes:
        world: a :class:`~mrmt_env.world.World` or a world file for every episode, or ``None`` to
            generate one per reset.
        height, width, obstacle_density, n_robots, n_targets, placement, layout, layout_options:
            the generator's arguments (defaults 10, 10, 0.2 for ``uniform``, 3, 10, ``"uniform"``,
            ``"uniform"``, the layout's defaults); with a fixed world, sizes given must agree with it.
    """

    world: Any = None
    height: int | None = None
    width: int | None = None
    obstacle_density: float | None = None
    n_robots: int | None = None
    n_targets: int | None = None
    placement: str | None = None
    layout: str | None = None
    layout_options: dict | None = None

    @classmethod
    def of(cls, config: WorldConfig | None = None, **overrides) -> WorldConfig:
        """``config`` (default: all defaults) with ``overrides`` given as keywords; ``ValueError`` naming an unknown
        keyword (as every option of the library), ``TypeError`` a ``config`` that is not a :class:`WorldConfig`."""
        if config is None:
            config = cls()
        elif not isinstance(config, cls):
            raise TypeError(f"config must be a WorldConfig, got {type(config).__name__}")
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(overrides) - names)
        if unknown:
            raise ValueError(f"unknown env argument(s) {unknown}; world arguments: {sorted(names)}")
        given = {k: v for k, v in overrides.items() if v is not None}
        return replace(config, **given) if given else config

    def params(self) -> dict:
        """The generator's arguments (every field but ``world``)."""
        return {f.name: getattr(self, f.name) for f in fields(WorldConfig) if f.name != "world"}

    def source(self, grid_env: bool = False) -> WorldSource:
        """The :class:`~mrmt_env.core.WorldSource` of these arguments (checks them)."""
        return WorldSource(self.world, grid_env=grid_env, **self.params())


#: The world options, every env on generated or fixed worlds takes them.
WORLD_OPTIONS = tuple(f.name for f in fields(WorldConfig))


@dataclass(frozen=True)
class EnvConfig(WorldConfig):
    """Every env option (a field left at its default means the env's default).

    Attributes:
        world, height, ..., layout_options: the world (:class:`WorldConfig`).
        max_episode_steps: steps before truncation (the registered id's limit, else none; PettingZoo
            envs: ``max_cycles``, default 200).
        max_cycles: the PettingZoo envs' step limit (``max_episode_steps`` is its alias there).
        target_reward: the reward of a target or task reached (default ``2 * height * width``).
        observation: ``"binary"`` planes or ``"image"`` (grid env).
        dense_reward: the weight of the distance-shaping reward, 0 = off (grid env).
        tasks, task_rate, collisions: the lifelong task stream (``refill`` or ``poisson`` at
            ``task_rate`` a step) and collision model (``block`` or ``allow``).
        instance, steps, scheduler, action_model: the League env's instance (path or
            :class:`~mrmt_env.lorr.instance.LoRRInstance`; default: the shipped example), step limit
            (default: the instance's simulation time), scheduler (``"greedy"``, ``None``, or an object
            with ``schedule(sim)``) and action model (``"MAPF_T"`` or ``"MAPF"``).
    """

    max_episode_steps: int | None = None
    max_cycles: int | None = None
    target_reward: float | None = None
    observation: str = "binary"
    dense_reward: float = 0.0
    tasks: str = "refill"
    task_rate: float | None = None
    collisions: str = "block"
    instance: Any = None
    steps: int | None = None
    scheduler: Any = "greedy"
    action_model: str = "MAPF_T"

    def __post_init__(self) -> None:
        if self.observation not in OBSERVATIONS:
            raise ValueError(f"observation must be one of {OBSERVATIONS}, got {self.observation!r}")
        d = self.dense_reward
        if isinstance(d, bool) or not isinstance(d, (int, float, np.integer, np.floating)) or not np.isfinite(d) \
                or d < 0:
            raise ValueError(f"dense_reward must be a finite number >= 0 (0 = off), got {d!r}")
        check_step_limit(self.max_episode_steps)

    @classmethod
    def of(cls, config: EnvConfig | WorldConfig | None = None, *, takes: tuple[str, ...] = WORLD_OPTIONS,
           env: str = "this env", **options) -> EnvConfig:
        """``config`` (an :class:`EnvConfig`, a :class:`WorldConfig` or ``None``) with the keyword ``options``
        put in (``None`` for a field whose default is ``None`` changes nothing); ``ValueError`` naming an unknown
        option or an option set away from its default that ``env`` (a name for the message) does not take
        (``takes``), as every option of the library; ``TypeError`` a ``config`` of another type."""
        if config is None:
            config = cls()
        elif type(config) is WorldConfig:
            config = cls(**{name: getattr(config, name) for name in WORLD_OPTIONS})
        elif not isinstance(config, cls):
            raise TypeError(f"config must be an EnvConfig or a WorldConfig, got {type(config).__name__}")
        names = [f.name for f in fields(cls)]
        unknown = sorted(set(options) - set(names))
        if unknown:
            raise ValueError(f"unknown env option(s) {unknown}; {env} takes {list(takes)}")
        # None leaves a field whose default is None as the config has it (what gym.make's unset keywords pass)
        defaults = {f.name: f.default for f in fields(cls)}
        given = {k: v for k, v in options.items() if v is not None or defaults[k] is not None}
        config = replace(config, **given) if given else config
        foreign = [f"{f.name}={getattr(config, f.name)!r}" for f in fields(cls)
                   if f.name not in takes and not _at_default(getattr(config, f.name), f.default)]
        if foreign:
            raise ValueError(f"{env} does not take {', '.join(foreign)}; it takes {list(takes)}")
        return config

    def world_config(self) -> WorldConfig:
        """The world part."""
        return WorldConfig(**{name: getattr(self, name) for name in WORLD_OPTIONS})


def _at_default(value, default) -> bool:
    if default is MISSING or default is None:
        return value is None
    return value is default or (not isinstance(value, bool) and isinstance(value, (str, int, float))
                                and value == default)
