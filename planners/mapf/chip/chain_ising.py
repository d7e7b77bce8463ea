"""The machine step of ``epibt-chain-ising`` (issue 57): the chip as the annealer of the 2024 winner's plan.

After :class:`~planners.mapf.epibt.chain_planner.ChainStep`'s construction and host search, rounds of group
decisions of class ``lns_groups`` (:class:`~planners.mapf.chip.group_rounds.GroupRounds`) change the kept plan,
scored with the plan's own terms; ``decider="host"`` is the twin without machine calls.
Design notes: docs/design/lifelong_turning.md#the-epibt-chain-ising-machine-step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planners.mapf.chip.group_rounds import GroupOptions, build_rounds, delegated
from planners.mapf.epibt.chains import score_of
from planners.mapf.epibt.plans import DEADLINE_MARGIN_S
from planners.mapf.epibt.search import PlanState
from planners.options import Options, option

__all__ = ["ChainGroupStep", "ChainShareOptions"]


@dataclass(frozen=True)
class ChainShareOptions(Options):
    """The host search's share of the step beside the chip's rounds."""

    host_share: float = option(0.5, float, 0.0, 1.0, meaning="under a clock, the share of the time the construction "
                               "leaves that the host search may take (with lns > 0 or null)")


class ChainGroupStep:
    """Rounds of joint group choices on the push chains' kept plan (module docstring).

    Args:
        opts: :class:`~planners.mapf.chip.group_rounds.GroupOptions`; ``share``: :class:`ChainShareOptions`.
        machine, seed: as :class:`~planners.mapf.chip.epibt_ising.GroupStep`.
    """

    def __init__(self, opts: GroupOptions, share: ChainShareOptions, machine, seed: int) -> None:
        self.host_share = share.host_share
        self.rounds_ = build_rounds(machine, opts, seed)
        self.machine = self.rounds_.machine

    ledger = delegated("ledger", "Every machine call's charges.")
    last_compute = delegated("last_compute", "The last call's machine charges.")
    stats = delegated("stats", "The group decisions' counts (GroupRounds).")

    def search_stop(self, now: float, stop: float) -> float:
        """Under a clock, when the host search of a plan built by ``now`` stops (``host_share`` of the time left)."""
        return now + self.host_share * max(stop - now, 0.0)

    def improve(self, decider, plan, ranked, deadline: float | None) -> None:
        """The rounds on the kept ``plan`` (of ``ranked``, a :class:`~planners.mapf.epibt.chain_planner.Ranked`), its
        score recounted from its choices after them."""
        cand, gain = ranked.cand, ranked.gain
        r = len(plan.choice)
        on = plan.choice >= 0
        cur = np.where(on[:, None], cand.cells[np.arange(r), np.maximum(plan.choice, 0)], cand.still)
        state = PlanState(cand.cells, cand.op, -gain, cand.n, cur, plan.choice, cand.still, np.zeros(r, np.int64))
        stop = None if deadline is None else deadline - DEADLINE_MARGIN_S
        self.rounds_.improve(state, plan.res, decider.prio.t, stop, ranked.busy.astype(np.int8))
        plan.score[0] = score_of(plan, gain)
