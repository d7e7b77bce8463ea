"""EPIBT whose neighbourhood groups choose their operations jointly on an Ising machine (``epibt-ising``).

After :class:`~planners.mapf.epibt.plans.EPIBT`'s plan and search, each call runs up to ``rounds`` rounds of up to
``groups`` decisions of class ``lns_groups`` on the kept plan, every robot free to start a group
(:class:`~planners.mapf.chip.group_rounds.GroupRounds`; the groups, their programs, the host rule and the decoding:
:mod:`planners.mapf.chip.group_kernels`).  ``decider="host"`` puts the host rule in the chip's place (no machine
call).  Charges as :class:`~planners.mapf.chip.joint_executor.JointMovesPIBT` (:attr:`ledger`,
:attr:`last_compute`).  Measurements: ``docs/design/lifelong_turning.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planners.mapf.chip.group_kernels import (apply_choices, decode_choice, greedy_choice, group_qubo,
                                              select_groups)
from planners.mapf.chip.group_rounds import DECIDERS, GroupOptions, build_rounds, delegated
from planners.mapf.epibt.plans import EPIBT, EPIBTOptions

__all__ = ["EPIBTIsing", "EPIBTIsingOptions", "select_groups", "group_qubo", "greedy_choice", "decode_choice",
           "apply_choices", "DECIDERS"]


@dataclass(frozen=True)
class EPIBTIsingOptions(GroupOptions, EPIBTOptions):
    """:class:`EPIBTIsing`'s options: :class:`~planners.mapf.epibt.plans.EPIBTOptions`, then its decisions'
    (:class:`~planners.mapf.chip.group_rounds.GroupOptions`)."""


class EPIBTIsing(EPIBT):
    """EPIBT plus the joint choice of operations of neighbourhood groups (module docstring).

    Args:
        grid, seed: as :class:`~planners.mapf.epibt.plans.EPIBT`.
        machine: any Ising machine; default ``ising_backend.EmulatedChip(seed=seed)`` (not built with
            ``decider="host"``; a machine given there shapes the groups, as it would for the chip, and is not called).
        options: the fields of :class:`EPIBTIsingOptions`.  ``penalty`` 2 was chosen on RANDOM-03 and -05
            (docs/design/lifelong_turning.md).  ``rounds`` > 1 with ``lns=0`` makes the chip the search's
            annealer: each round poses fresh groups on the plan the rounds before it left; under a clock the
            rounds stop when the next, as long as the longest so far, would end past the deadline less
            :data:`~planners.mapf.epibt.plans.DEADLINE_MARGIN_S` on the step's charged time (host seconds, not
            the emulation's, plus the machine's own).
    """

    name = "epibt-ising"
    Options = EPIBTIsingOptions

    def __init__(self, grid, seed: int = 0, machine=None, **options) -> None:
        super().__init__(grid, seed=seed, **options)
        opts = self.options
        self.decider = opts.decider
        self.rounds_ = build_rounds(machine, opts, self.seed)
        self.machine = self.rounds_.machine
        lim = self.rounds_.limits
        self.n_groups, self.max_robots, self.max_options, self.max_spins = (lim.groups, lim.max_robots,
                                                                            lim.max_options, lim.max_spins)

    ledger = delegated("ledger", "Every machine call's charges.")
    last_compute = delegated("last_compute", "The last call's machine charges.")
    stats = delegated("stats", "The group decisions' counts (GroupRounds).")

    def _improve(self, state) -> None:
        """Up to ``rounds`` rounds of group decisions (class docstring), the machine's charges summed."""
        self.rounds_.improve(state, self._res, self.t, self.deadline, np.ones(len(state.ncand), dtype=np.int8))
