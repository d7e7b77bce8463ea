"""The machine step of ``epibt-ising``: EPIBT's neighbourhood groups choose their operations jointly on an Ising
machine.

After :class:`~planners.mapf.epibt.plans.EPIBTStep`'s plan and search, each call runs up to ``rounds`` rounds of up
to ``groups`` decisions of class ``lns_groups`` on the kept plan, every robot free to start a group
(:class:`~planners.mapf.chip.group_rounds.GroupRounds`; the groups, their programs, the host rule and the decoding:
:mod:`planners.mapf.chip.group_kernels`).  ``decider="host"`` puts the host rule in the chip's place (no machine
call).  ``penalty`` 2 was chosen on RANDOM-03 and -05; ``rounds`` > 1 with ``lns=0`` makes the chip the search's
annealer: each round poses fresh groups on the plan the rounds before it left; under a clock the rounds stop when
the next, as long as the longest so far, would end past the deadline less
:data:`~planners.mapf.epibt.plans.DEADLINE_MARGIN_S` on the step's charged time (host seconds, not the emulation's,
plus the machine's own).  Charges: :attr:`GroupStep.ledger`, :attr:`GroupStep.last_compute`.  Measurements:
``docs/design/lifelong_turning.md``.
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
