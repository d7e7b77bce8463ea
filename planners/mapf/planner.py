"""A one-step planner with turning as a composition of parts (the start kit's ``MAPFPlanner`` role).

A planner is a named choice of parts (a :class:`PlannerKind`), each with its own options record. Contract:
:meth:`TurningPlanner.actions` ``(pos, orient, goals, deadline=None, rest=None) -> (R,)`` actions F 0, R 1, C 2,
W 3, always a valid joint action, deterministic for a seed without a deadline.
Design notes (the parts): docs/design/league_parts.md#the-shell-turningplanner.
"""

from __future__ import annotations

from typing import Any, Callable, NamedTuple, Protocol

import numpy as np

from planners.compute import ComputeReport
from planners.mapf.guides.fields import FieldOptions, FieldSource
from planners.mapf.guides.focus import Focus, FocusOptions, checked_rest
from planners.mapf.pibt.turning import CLOCKWISE, COUNTER, FORWARD
from planners.mapf.site import Priorities, TurnSite, int_array
from planners.options import Options

__all__ = ["TurningPlanner", "PlannerKind"]

_NO_CHARGE = ComputeReport()
OptionsRecord = Options  # within PlannerKind the name ``Options`` is its field


class Decider(Protocol):
    """A decider as the shell uses it: its options record, whether it reads ``rest``, its step and its cells."""

    # its options record class; Any, as mypy takes a class body's ``Options = PIBTOptions`` for an alias, which
    # matches no protocol member typed type[Options]
    Options: Any
    uses_rest: bool
    targets: np.ndarray  # the last call's PIBT cells (flat)

    def __init__(self, site, source, priorities, opts, machine_step=None) -> None: ...

    def decide(self, pos, orient, goals, deadline: float | None = None, rest=None) -> np.ndarray: ...


class PlannerKind(NamedTuple):
    """A planner as a named choice of parts: its options record (the union of its parts'), its decider class, and
    ``machine_step(options, machine, seed, site)`` building its machine step (``None``: no machine decides)."""

    name: str
    Options: type[OptionsRecord]
    decider: type[Decider]
    machine_step: Callable | None = None
    summary: str = ""

    def check_team(self, grid, n_robots: int, options: OptionsRecord) -> None:
        """``ValueError`` when the planner cannot take ``n_robots`` robots on ``grid`` within its memory bound."""
        FieldSource.check_team(grid, n_robots, options.part(FieldOptions))


class TurningPlanner:
    """One planner of :class:`PlannerKind` ``kind`` on ``grid`` (``(H, W)`` bool obstacles), ``seed`` for its
    tie-breaks, ``options`` its record or a dict of its options (checked), ``machine`` any Ising machine for a kind
    with a machine step (default there: the paper's emulated chip)."""

    def __init__(self, kind: PlannerKind, grid, seed: int = 0, options: Options | dict | None = None,
                 machine=None) -> None:
        opts = options if isinstance(options, kind.Options) else kind.Options.from_dict(dict(options or {}), kind.name)
        if machine is not None and kind.machine_step is None:
            raise ValueError(f"planner {kind.name!r} runs on no machine; a machine was given")
        self.kind, self.name, self.options = kind, kind.name, opts
        self.site = TurnSite(grid)
        self.prio = Priorities(seed, self.site.dead_end)
        self.source = FieldSource(self.site, opts.part(FieldOptions), self.prio.seed)
        self.focus = Focus(opts.part(FocusOptions))
        self.machine_step = None if kind.machine_step is None else kind.machine_step(opts, machine, self.prio.seed,
                                                                                     self.site)
        self.decider = kind.decider(self.site, self.source, self.prio, opts.part(kind.decider.Options),
                                    self.machine_step)
        #: whether :meth:`actions` wants ``rest`` (each robot's task beyond its goal, ``active_by="task"``)
        self.takes_rest = self.focus.by_task and (self.focus.active < 1 or kind.decider.uses_rest)

    @property
    def guidance(self) -> int:
        return self.source.guidance

    @property
    def last_compute(self) -> ComputeReport:
        """The latest step's machine charge (none without a machine step)."""
        return _NO_CHARGE if self.machine_step is None else self.machine_step.last_compute

    @property
    def machine(self):
        return None if self.machine_step is None else self.machine_step.machine

    def actions(self, pos, orient, goals, deadline: float | None = None, rest=None) -> np.ndarray:
        """``(R,)`` int64 actions (0 F, 1 R, 2 C, 3 W) of robots at flat cells ``pos`` facing ``orient`` heading to
        flat ``goals`` (a robot without a task takes its own cell); always a valid joint action.  Advances the
        priorities, assuming the actions are executed.  ``deadline``: the step's ``time.perf_counter()`` deadline
        under a clock, or ``None``.  ``rest``: each robot's task beyond its goal in moves
        (:func:`mrmt_env.lorr.tasks.rest_under`), needed when :attr:`takes_rest`, else unused."""
        pos, orient, goals = self.site.check(pos, orient, goals)
        rest = checked_rest(rest, len(pos)) if self.takes_rest else None
        return self.decider.decide(pos, orient, self.steer(pos, goals, rest), deadline, rest)

    def steer(self, pos, goals, rest=None) -> np.ndarray:
        """The flat goals this step heads for (flat ``pos`` and ``goals`` checked; ``rest`` when
        :attr:`takes_rest`): the focus' robots at work keep theirs (:meth:`Focus.steer
        <planners.mapf.guides.focus.Focus.steer>`)."""
        return self.focus.steer(pos, goals, rest, self.source, self.prio)

    def step(self, pos, orient, goals):
        """:meth:`actions` applied: ``(next pos, next orient)``."""
        pos, orient = int_array("pos", pos), int_array("orient", orient)
        act = self.actions(pos, orient, goals)
        nxt = np.where(act == FORWARD, self.decider.targets, pos)
        turn = np.where(act == CLOCKWISE, 1, np.where(act == COUNTER, 3, 0))
        return nxt, (orient + turn) % 4
