"""EPIBT by push chains whose neighbourhood groups choose their operations jointly on an Ising machine
(``epibt-chain-ising``, issue 57): the chip as the annealer of the 2024 winner's plan.

Contract: as :class:`~planners.mapf.epibt.chain_planner.ChainEPIBT` (its construction, a portfolio of plans), with
the kept plan then changed by rounds of group decisions of class ``lns_groups``
(:class:`~planners.mapf.chip.group_rounds.GroupRounds`): a robot's options are its candidate operations and waiting,
their costs the plan's own score terms (``-power x (value of waiting - value)``; waiting 0), so a group taken raises
the plan's score by its fall in cost.  Only robots with a goal start groups; any robot joins one (to be moved
aside).  ``lns`` host chains (default 0: the chip alone anneals after the construction) run before the rounds;
under a clock the host search stops at ``host_share`` of the time the construction leaves and the rounds run to the
deadline on the step's charged time (host seconds, not the emulation's, plus the machine's own).
``decider="host"`` is the twin: the same groups decided by the host rule, no machine call.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planners.mapf.chip.group_rounds import GroupOptions, build_rounds, delegated, grow_option, rounds_option
from planners.mapf.epibt.chain_planner import ChainEPIBT, ChainOptions
from planners.mapf.epibt.chains import score_of
from planners.mapf.epibt.plans import DEADLINE_MARGIN_S
from planners.mapf.epibt.search import PlanState
from planners.options import option

__all__ = ["ChainEPIBTIsing", "ChainIsingOptions"]


@dataclass(frozen=True)
class ChainIsingOptions(GroupOptions, ChainOptions):
    """:class:`ChainEPIBTIsing`'s options: :class:`~planners.mapf.epibt.chain_planner.ChainOptions` (host chains off
    by default), then the group decisions' (:class:`~planners.mapf.chip.group_rounds.GroupOptions`, 64 rounds)."""

    lns: int | None = option(0, int, 0, 1 << 24, none=True, meaning="host search chains per plan and call before the "
                             "rounds (0: none, the chip alone anneals; null: 100 per robot, under a clock to host_share "
                             "of the time)")
    host_share: float = option(0.5, float, 0.0, 1.0, meaning="under a clock, the share of the time the construction "
                               "leaves that the host search may take (with lns > 0 or null)")
    rounds: int = rounds_option(64)
    grow: bool = grow_option(True)


class ChainEPIBTIsing(ChainEPIBT):
    """EPIBT by push chains plus rounds of joint group choices (module docstring).

    Args:
        grid, seed: as :class:`~planners.mapf.epibt.chain_planner.ChainEPIBT`.
        machine: any Ising machine; default ``ising_backend.EmulatedChip(seed=seed)`` (not built with
            ``decider="host"``; a machine given there shapes the groups, as it would for the chip, and is not called).
        options: the fields of :class:`ChainIsingOptions`.
    """

    name = "epibt-chain-ising"
    Options = ChainIsingOptions

    def __init__(self, grid, seed: int = 0, machine=None, **options) -> None:
        super().__init__(grid, seed=seed, **options)
        self.decider = self.options.decider
        self.rounds_ = build_rounds(machine, self.options, self.seed)
        self.machine = self.rounds_.machine

    ledger = delegated("ledger", "Every machine call's charges.")
    last_compute = delegated("last_compute", "The last call's machine charges.")
    stats = delegated("stats", "The group decisions' counts (GroupRounds).")

    def _search_stop(self, now: float, stop: float) -> float:
        return now + self.options.host_share * max(stop - now, 0.0)

    def _improve_plan(self, plan, cand, gain, busy) -> None:
        """The rounds on the kept plan, its score recounted from its choices after them."""
        r = len(plan.choice)
        on = plan.choice >= 0
        cur = np.where(on[:, None], cand.cells[np.arange(r), np.maximum(plan.choice, 0)], cand.still)
        state = PlanState(cand.cells, cand.op, -gain, cand.n, cur, plan.choice, cand.still, np.zeros(r, np.int64))
        deadline = None if self.deadline is None else self.deadline - DEADLINE_MARGIN_S
        self.rounds_.improve(state, plan.res, self.t, deadline, busy.astype(np.int8))
        plan.score[0] = score_of(plan, gain)
