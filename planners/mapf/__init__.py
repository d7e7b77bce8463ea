"""Collision-free execution for lifelong operation: one conflict-free joint move per step.

Grid executors :class:`PIBT` and :class:`WindowedPlanner` (:func:`make_executor`, :data:`EXECUTORS`); the League's
planners with turning, one :class:`PlannerKind` each in :data:`TURNING_PLANNERS`, built by
:func:`make_turning_planner`. Design notes (the rooms): docs/design/league_parts.md#the-rooms-of-plannersmapf.
"""

from __future__ import annotations

from planners.mapf.chip.chain_ising import ChainGroupStep, ChainShareOptions
from planners.mapf.chip.epibt_ising import GroupStep
from planners.mapf.chip.group_rounds import GroupOptions
from planners.mapf.chip.joint_executor import JointMovesOptions, JointMovesStep
from planners.mapf.epibt.chain_planner import ChainOptions, ChainStep
from planners.mapf.epibt.options import EPIBTOptions
from planners.mapf.epibt.plans import EPIBTStep
from planners.mapf.guides.fields import FieldOptions
from planners.mapf.guides.focus import FocusOptions
from planners.mapf.pibt.grid import PIBT
from planners.mapf.pibt.turning import PIBTOptions, PIBTStep
from planners.mapf.pibt.windowed import WindowedPlanner
from planners.mapf.planner import PlannerKind, TurningPlanner
from planners.options import record

__all__ = ["PIBT", "WindowedPlanner", "EXECUTORS", "make_executor", "TurningPlanner", "PlannerKind",
           "TURNING_PLANNERS", "MACHINE_PLANNERS", "make_turning_planner"]

EXECUTORS = {"pibt": PIBT, "windowed": WindowedPlanner}

_M = __name__
PIBTRecord = record("PIBTRecord", "``pibt``'s options.", FieldOptions, FocusOptions, PIBTOptions, module=_M)
FlowRecord = record("FlowRecord", "``pibt-flow``'s options: lanes off, guide paths and commitments on.", FieldOptions,
                    FocusOptions, PIBTOptions, defaults={"guidance": 0, "flow": True, "commits": True}, module=_M)
EPIBTRecord = record("EPIBTRecord", "``epibt``'s options: lanes off, guide paths on.", FieldOptions, FocusOptions,
                     EPIBTOptions, defaults={"guidance": 0, "flow": True}, module=_M)
ChainRecord = record("ChainRecord", "``epibt-chain``'s options: lanes off, goal fields.", FieldOptions, FocusOptions,
                     ChainOptions, defaults={"guidance": 0}, module=_M)
EPIBTIsingRecord = record("EPIBTIsingRecord", "``epibt-ising``'s options: ``epibt``'s and the group decisions'.",
                          FieldOptions, FocusOptions, EPIBTOptions, GroupOptions,
                          defaults={"guidance": 0, "flow": True}, module=_M)
ChainIsingRecord = record("ChainIsingRecord", "``epibt-chain-ising``'s options: ``epibt-chain``'s (host chains off) "
                          "and the group decisions' (64 rounds, growing groups).", FieldOptions, FocusOptions,
                          ChainOptions, GroupOptions, ChainShareOptions,
                          defaults={"guidance": 0, "lns": 0, "rounds": 64, "grow": True}, module=_M)
JointRecord = record("JointRecord", "``pibt-ising``'s options: ``pibt``'s, lanes off, and the joint moves'.",
                     FieldOptions, FocusOptions, PIBTOptions, JointMovesOptions, defaults={"guidance": 0}, module=_M)

#: The planners with turning by name: each a choice of parts (:mod:`planners.mapf.planner`).
TURNING_PLANNERS = {k.name: k for k in (
    PlannerKind("pibt", PIBTRecord, PIBTStep, summary="PIBT with turning on goal fields along crisscross lanes"),
    PlannerKind("pibt-flow", FlowRecord, PIBTStep, summary="the start kit's default: PIBT along traffic-flow guide "
                "paths, committed moves"),
    PlannerKind("epibt", EPIBTRecord, EPIBTStep, summary="EPIBT: PIBT over multi-action operations with a "
                "large-neighbourhood search"),
    PlannerKind("epibt-chain", ChainRecord, ChainStep, summary="EPIBT by push chains (the 2024 winner's "
                "construction and annealed search)"),
    PlannerKind("epibt-ising", EPIBTIsingRecord, EPIBTStep,
                lambda o, machine, seed, site: GroupStep(o.part(GroupOptions), machine, seed),
                summary="epibt + the chip's joint choices of neighbourhood groups"),
    PlannerKind("epibt-chain-ising", ChainIsingRecord, ChainStep,
                lambda o, machine, seed, site: ChainGroupStep(o.part(GroupOptions), o.part(ChainShareOptions),
                                                              machine, seed),
                summary="epibt-chain + the chip as the plan's annealer"),
    PlannerKind("pibt-ising", JointRecord, PIBTStep,
                lambda o, machine, seed, site: JointMovesStep(o.part(JointMovesOptions), machine, seed,
                                                              len(site.cell_of)),
                summary="pibt + the chip's joint next moves in congested groups"),
)}
#: The planners with turning that take an Ising machine (``machine=``; default the paper's emulated chip).
MACHINE_PLANNERS = tuple(k.name for k in TURNING_PLANNERS.values() if k.machine_step is not None)


def make_executor(name: str, grid, seed: int = 0, **options):
    """The executor ``name`` (``pibt`` or ``windowed``) on ``grid``; ``ValueError`` naming the known ones."""
    if name not in EXECUTORS:
        raise ValueError(f"unknown executor {name!r}; known: {', '.join(EXECUTORS)}")
    return EXECUTORS[name](grid, seed=seed, **options)


def make_turning_planner(name: str, grid, seed: int = 0, machine=None, **options) -> TurningPlanner:
    """The planner with turning ``name`` (:data:`TURNING_PLANNERS`) on ``grid``, ``options`` its own (checked);
    ``ValueError`` naming an unknown planner or option."""
    if name not in TURNING_PLANNERS:
        raise ValueError(f"unknown planner {name!r}; known: {', '.join(TURNING_PLANNERS)}")
    return TurningPlanner(TURNING_PLANNERS[name], grid, seed, options, machine)
