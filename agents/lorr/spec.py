"""What a League run plays, as typed records built once: :class:`PlannerSpec` (a planner's name and its options record)
and :class:`SchedulerSpec` (a scheduler's name and its options), from an entry file, the command line or Python, and
handed unchanged to the roles (:func:`agents.lorr.run.make_roles`).

A planner is one of :data:`planners.mapf.TURNING_PLANNERS`, or a user's own class named ``package.module:Class``,
built as ``Class(grid, seed=seed, **options)``; it must meet :class:`agents.lorr.roles.Planner`.  A scheduler is one
of :func:`agents.lorr.schedulers.make_scheduler`'s names, or ``package.module:Class`` built as
``Class(seed=seed, **options)`` meeting :class:`agents.lorr.roles.Scheduler`.  Bad names and options are one
``ValueError`` line naming them.
"""

from __future__ import annotations

import importlib
import re
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING

from agents.lorr.roles import Planner, Scheduler

if TYPE_CHECKING:
    from planners.options import Options

__all__ = ["PlannerSpec", "SchedulerSpec", "user_class", "is_class_path", "specs_from_options", "check_role"]


_CLASS_PATH = re.compile(r"[A-Za-z_][\w.]*:[A-Za-z_]\w*")


def is_class_path(name: str) -> bool:
    """Whether ``name`` names a user's class, ``package.module:Class`` (not ``ppo:MODEL.zip``)."""
    return bool(_CLASS_PATH.fullmatch(name)) and not name.startswith("ppo:")


def user_class(path: str) -> type:
    """The class named ``package.module:Class``; ``ValueError`` when it cannot be imported or is no class."""
    module, _, name = path.partition(":")
    if not module or not name:
        raise ValueError(f"{path!r} is not package.module:Class")
    try:
        cls = getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"cannot load {path!r}: {exc}") from None
    if not isinstance(cls, type):
        raise ValueError(f"{path!r} is not a class")
    return cls


def check_role(obj, role: type, what: str):
    """``obj`` when it meets ``role`` (a runtime-checkable Protocol), else ``ValueError`` naming what it lacks."""
    if not isinstance(obj, role):
        need = sorted(k for k, v in vars(role).items() if callable(v) and not k.startswith("_"))
        raise ValueError(f"{what} does not meet the {role.__name__} role: a {role.__name__} has "
                         f"{', '.join(need)} (agents.lorr.roles)")
    return obj


@dataclass(frozen=True)
class PlannerSpec:
    """A planner by name with its options: for a built-in planner its typed options record (checked when the spec
    is made), for a user's class (``package.module:Class``) the keyword options its constructor takes; ``None``: the
    built-in planner's defaults."""

    name: str
    options: Options | dict | None = None

    @classmethod
    def of(cls, name: str, options: dict | None = None) -> "PlannerSpec":
        """The spec of planner ``name`` with ``options`` (a dict, checked against its record); ``ValueError``
        naming an unknown planner or option."""
        from planners.mapf import TURNING_PLANNERS

        if is_class_path(name):
            if not callable(getattr(user_class(name), "actions", None)):
                raise ValueError(f"{name} does not meet the Planner role: a Planner has actions (agents.lorr.roles)")
            return cls(name, dict(options or {}))
        if name not in TURNING_PLANNERS:
            raise ValueError(f"unknown planner {name!r}; known: {', '.join(TURNING_PLANNERS)}, or "
                             f"package.module:Class")
        return cls(name, TURNING_PLANNERS[name].Options.from_dict(dict(options or {}), name))

    @property
    def given(self) -> dict:
        """The options that differ from the planner's defaults (a user class: all given)."""
        if isinstance(self.options, dict):
            return dict(self.options)
        if self.options is None:
            return {}
        default = type(self.options)()
        return {f.name: getattr(self.options, f.name) for f in fields(self.options)
                if getattr(self.options, f.name) != getattr(default, f.name)}

    @property
    def machine(self) -> bool:
        """Whether the planner takes an Ising machine."""
        from planners.mapf import MACHINE_PLANNERS

        return self.name in MACHINE_PLANNERS

    def build(self, grid, seed: int = 0, machine=None):
        """The planner on ``grid``."""
        if isinstance(self.options, dict):
            return check_role(user_class(self.name)(grid, seed=seed, **self.options), Planner, self.name)
        from planners.mapf import TURNING_PLANNERS, TurningPlanner

        return TurningPlanner(TURNING_PLANNERS[self.name], grid, seed, self.options, machine)

    def check_team(self, grid, n_robots: int) -> None:
        """``ValueError`` when the planner cannot take ``n_robots`` robots on ``grid`` within its memory bound."""
        if not isinstance(self.options, dict):
            from planners.mapf import TURNING_PLANNERS

            kind = TURNING_PLANNERS[self.name]
            kind.check_team(grid, n_robots, kind.Options() if self.options is None else self.options)


@dataclass(frozen=True)
class SchedulerSpec:
    """A scheduler by name with its options (``replan``, ``keep`` and its own; checked when the spec is made)."""

    name: str
    options: dict = field(default_factory=dict)

    @classmethod
    def of(cls, name: str, options: dict | None = None, chip=None) -> "SchedulerSpec":
        """The spec of scheduler ``name``; ``ValueError`` naming an unknown scheduler or option (the scheduler is
        built once to check them)."""
        spec = cls(name, dict(options or {}))
        spec.build(0, chip)
        return spec

    def build(self, seed: int = 0, chip=None):
        """The scheduler (``chip``: the machine recipe of a chip scheduler)."""
        if is_class_path(self.name):
            return check_role(user_class(self.name)(seed=seed, **self.options), Scheduler, self.name)
        from agents.lorr.schedulers import make_scheduler

        try:
            return make_scheduler(self.name, seed=seed, chip=chip, **self.options)
        except TypeError as exc:  # a pipeline layer's keyword it does not take
            raise ValueError(f"{self.name}: {exc}") from None


def specs_from_options(scheduler: str, planner: str, options: dict | None) -> tuple[SchedulerSpec, PlannerSpec]:
    """The two specs of the dict form ``{"replan", "keep", "scheduler_options": {...}, "guidance", "planner_options"
    (or "executor_options"): {...}}``: ``guidance`` joins the planner's options, the rest the scheduler's."""
    options = dict(options or {})
    own = dict(options.pop("planner_options", None) or options.pop("executor_options", None) or {})
    if "guidance" in options:
        if "guidance" in own:
            raise ValueError(f"guidance given twice ({options['guidance']!r} and the planner option's "
                             f"{own['guidance']!r}); give it once")
        own["guidance"] = options.pop("guidance")
    sched = dict(options.pop("scheduler_options", None) or {})
    sched.update(options)
    return SchedulerSpec(scheduler, sched), PlannerSpec.of(planner, own)
