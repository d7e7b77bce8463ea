"""One frozen record of an env's world arguments, taken by every env constructor.

``WorldConfig`` holds where worlds come from (a fixed world or file, or the generator's size,
density, counts, placement and map family); every env of the package takes one as ``config``
and accepts the same names as keywords (what ``gym.make(id, n_robots=5)`` passes), which
override it.  The values are checked where worlds are made (:class:`~mrmt_env.core.WorldSource`).
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Any

from mrmt_env.core import WorldSource

__all__ = ["WorldConfig"]


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
        """``config`` (default: all defaults) with ``overrides`` given as keywords; ``TypeError``
        naming an unknown keyword or a ``config`` that is not a :class:`WorldConfig`."""
        if config is None:
            config = cls()
        elif not isinstance(config, cls):
            raise TypeError(f"config must be a WorldConfig, got {type(config).__name__}")
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(overrides) - names)
        if unknown:
            raise TypeError(f"unknown env argument(s) {unknown}; world arguments: {sorted(names)}")
        given = {k: v for k, v in overrides.items() if v is not None}
        return replace(config, **given) if given else config

    def params(self) -> dict:
        """The generator's arguments (every field but ``world``)."""
        return {f.name: getattr(self, f.name) for f in fields(self) if f.name != "world"}

    def source(self, grid_env: bool = False) -> WorldSource:
        """The :class:`~mrmt_env.core.WorldSource` of these arguments (checks them)."""
        return WorldSource(self.world, grid_env=grid_env, **self.params())
