"""The options records of the PIBT family with turning (:mod:`planners.options`): the goal fields' (``LaneOptions``),
:class:`~planners.mapf.pibt.turning.TurningPIBT`'s, and the option fields other planners share."""

from __future__ import annotations

from dataclasses import dataclass

from planners.mapf.guides.guidance import MAX_GUIDANCE
from planners.options import Options, option

__all__ = ["LaneOptions", "TurningOptions", "commits_option", "congestion_options", "park_option", "active_option",
           "active_by_option", "DEFAULT_FIELD_BYTES", "DEFAULT_BFS_BUDGET", "DEFAULT_GUIDANCE", "DEFAULT_REFRESH"]

#: Default memory bound of the goal-field cache (the fields of the goals asked for in one call are always kept).
DEFAULT_FIELD_BYTES = 1 << 30
#: Default BFS work of one call, in cells: new goal fields per call = this // free cells.
DEFAULT_BFS_BUDGET = 1 << 24
#: Extra cost of a move against its lane (:mod:`planners.mapf.guides.guidance`) of TurningPIBT, by default: chosen
#: on RANDOM-01..05 (0, 2 and 4 tried, three seeds; docs/design/lifelong_turning.md).
DEFAULT_GUIDANCE = 2
#: Goal fields recomputed per call under ``congestion`` by default.
DEFAULT_REFRESH = 64


@dataclass(frozen=True)
class LaneOptions(Options):
    """The goal fields' options, shared by every planner with turning."""

    guidance: int = option(DEFAULT_GUIDANCE, int, 0, MAX_GUIDANCE, meaning="extra cost of a forward move against "
                           "its lane (crisscross lanes, planners.mapf.guides.guidance; 0 = plain BFS distances)")
    field_bytes: int = option(DEFAULT_FIELD_BYTES, int, 1, 1 << 40, meaning="memory bound of the goal-field cache "
                              "(TurnFields)")
    bfs_budget: int = option(DEFAULT_BFS_BUDGET, int, 1, 1 << 40, meaning="BFS work per call in cells (new goal "
                             "fields per call = this // free cells; a goal without a field goes by Manhattan distance)")
    corridors: int = option(0, int, 0, MAX_GUIDANCE, meaning="extra cost of a move against a one-way corridor "
                            "(corridors one cell wide, open at both ends, alternate their ways; 0 = off)")


def commits_option(default: bool):
    """The ``commits`` option (its default per planner)."""
    return option(default, bool, meaning="a robot keeps claiming the cell it chose until it stands on it (as in "
                  "the start kit's default planner)")


def congestion_options():
    """The ``congestion`` and ``refresh`` options (:mod:`planners.mapf.guides.congestion`), fresh fields."""
    return (option(0, int, 0, MAX_GUIDANCE, meaning="extra cost of a move into a cell a robot stands on now, in "
                   "goal fields refreshed each call (the 2024 winner's dynamic heuristic; 0 = off)"),
            option(DEFAULT_REFRESH, int, 0, 1 << 20, meaning="with congestion: goal fields recomputed per call at "
                   "most, first those with the most robots heading there x calls since computed"))


def park_option():
    """The ``park`` option (:mod:`planners.mapf.guides.parking`)."""
    return option(0.0, float, 0, 1, meaning="a robot without a goal (its goal its own cell) heads for the nearest "
                  "parking place, this share of the free cells with the least through-traffic "
                  "(planners.mapf.guides.parking; 0 = it stays where it is)")


def active_option():
    """The ``active`` option (:mod:`planners.mapf.guides.focus`)."""
    return option(1.0, float, 0.001, 1, meaning="the share of the team that heads for its goal each step, the robots "
                  "of least way to it (planners.mapf.guides.focus; the others stay and are pushed aside; 1 = all)")


def active_by_option():
    """The ``active_by`` option (:mod:`planners.mapf.guides.focus`)."""
    return option("goal", str, words=("goal", "task"), meaning="with active < 1, the robots at work are those of "
                  "least way to their goal (goal) or of least task still to go: that way plus the task's legs beyond "
                  "its goal, given per step as actions(..., rest=...) (task; the 2024 winner's ranking)")


@dataclass(frozen=True)
class TurningOptions(LaneOptions):
    """:class:`TurningPIBT`'s options."""

    commits: bool = commits_option(False)
    congestion: int = congestion_options()[0]
    refresh: int = congestion_options()[1]
    park: float = park_option()
    active: float = active_option()
    active_by: str = active_by_option()
