"""Collision-free execution for lifelong operation: one conflict-free joint move per step.

:class:`PIBT` (priority inheritance with backtracking, compiled) and
:class:`WindowedPlanner` (prioritized space-time A* over a short window,
compiled); both take flat robot cells and goal cells and return next cells or
env actions.  :func:`make_executor` builds one by name (:data:`EXECUTORS`).
:class:`TurningPIBT` is PIBT for the League of Robot Runners' action model with
turning (flat cells and orientations -> actions F, R, C, W);
:class:`WindowedTurningPlanner` is windowed prioritized space-time A* over (cell,
orientation, time) for the same rules; :func:`make_turning_executor` builds either by name
(:data:`TURNING_EXECUTORS`); :class:`FlowPIBT` is PIBT with turning along traffic-flow guide paths;
:class:`EPIBT` is PIBT over multi-action operations along the same guide paths.

Rooms: ``pibt/`` (the PIBT family and windowed A*), ``guides/`` (lane guidance, traffic-flow guide paths),
``epibt/`` (EPIBT's plans and search), ``chip/`` (the planners that leave a decision to an Ising machine),
``common`` (what they share: successor tables, goal fields, seeds, the groups record).
"""

from __future__ import annotations

from planners.mapf.chip.chain_ising import ChainEPIBTIsing
from planners.mapf.chip.epibt_ising import EPIBTIsing
from planners.mapf.chip.joint_executor import JointMovesPIBT
from planners.mapf.chip.work_set import WorkChainEPIBT
from planners.mapf.epibt.chain_planner import ChainEPIBT
from planners.mapf.epibt.plans import EPIBT
from planners.mapf.guides.flow import FlowPIBT
from planners.mapf.pibt.grid import PIBT
from planners.mapf.pibt.turning import TurningPIBT
from planners.mapf.pibt.windowed import WindowedPlanner
from planners.mapf.pibt.windowed_turning import WindowedTurningPlanner

__all__ = ["PIBT", "WindowedPlanner", "TurningPIBT", "WindowedTurningPlanner", "EXECUTORS", "make_executor",
           "TURNING_EXECUTORS", "MACHINE_PLANNERS", "make_turning_executor", "JointMovesPIBT", "FlowPIBT", "EPIBT",
           "EPIBTIsing", "ChainEPIBT", "ChainEPIBTIsing", "WorkChainEPIBT"]

EXECUTORS = {"pibt": PIBT, "windowed": WindowedPlanner}
#: Executors of the action model with turning (``actions(pos, orient, goals)`` -> F, R, C, W).
TURNING_EXECUTORS = {"pibt": TurningPIBT, "windowed": WindowedTurningPlanner, "pibt-flow": FlowPIBT,
                     "epibt": EPIBT, "epibt-chain": ChainEPIBT, "epibt-ising": EPIBTIsing,
                     "epibt-chain-ising": ChainEPIBTIsing,  # epibt-chain + the chip's joint group choices
                     "epibt-chain-work": WorkChainEPIBT,  # epibt-chain + the chip's choice of who stays at work
                     "pibt-ising": JointMovesPIBT}  # TurningPIBT + the chip's joint moves in congested groups
#: The turning executors that take an Ising machine (``machine=``; default the paper's emulated chip).
MACHINE_PLANNERS = ("epibt-ising", "epibt-chain-ising", "epibt-chain-work", "pibt-ising")


def make_executor(name: str, grid, seed: int = 0, **options):
    """The executor ``name`` (``pibt`` or ``windowed``) on ``grid``; ``ValueError`` naming the known ones."""
    return _make(EXECUTORS, "executor", name, grid, seed, options)


def make_turning_executor(name: str, grid, seed: int = 0, **options):
    """The turning executor ``name`` (:data:`TURNING_EXECUTORS`) on ``grid``; ``ValueError`` naming the known ones."""
    return _make(TURNING_EXECUTORS, "turning executor", name, grid, seed, options)


def _make(table: dict, kind: str, name: str, grid, seed: int, options: dict):
    if name not in table:
        raise ValueError(f"unknown {kind} {name!r}; known: {', '.join(table)}")
    return table[name](grid, seed=seed, **options)
