"""The machine step of ``epibt-ising``: EPIBT's neighbourhood groups choose their operations jointly on an Ising
machine.

After :class:`~planners.mapf.epibt.plans.EPIBTStep`'s plan and search, each call runs up to ``rounds`` rounds of up
to ``groups`` decisions of class ``lns_groups`` (:class:`~planners.mapf.chip.group_rounds.GroupRounds`);
``decider="host"`` puts the host rule in the chip's place. Charges: :attr:`GroupStep.ledger`,
:attr:`GroupStep.last_compute`. Design notes: docs/design/lifelong_turning.md#the-epibt-ising-machine-step.
"""

from __future__ import annotations

import numpy as np

from planners.mapf.chip.group_rounds import GroupOptions, build_rounds, delegated

__all__ = ["GroupStep"]


class GroupStep:
    """Rounds of joint group choices on EPIBT's kept plan (module docstring).

    Args:
        opts: :class:`~planners.mapf.chip.group_rounds.GroupOptions`.
        machine: any Ising machine; default ``ising_backend.EmulatedChip(seed=seed)`` (not built with
            ``decider="host"``; a machine given there shapes the groups, as it would for the chip, and is not called).
        seed: the machine's and the rounds' seed.
    """

    Options = GroupOptions

    def __init__(self, opts: GroupOptions, machine, seed: int) -> None:
        self.rounds_ = build_rounds(machine, opts, seed)
        self.machine = self.rounds_.machine

    ledger = delegated("ledger", "Every machine call's charges.")
    last_compute = delegated("last_compute", "The last call's machine charges.")
    stats = delegated("stats", "The group decisions' counts (GroupRounds).")

    def improve(self, decider, state, deadline: float | None) -> None:
        """Up to ``rounds`` rounds of group decisions on ``decider``'s kept plan ``state``, the machine's charges
        summed."""
        self.rounds_.improve(state, decider.res, decider.prio.t, deadline, np.ones(len(state.ncand), dtype=np.int8))
