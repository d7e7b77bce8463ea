"""EPIBT's own options record (:mod:`planners.options`) and the defaults it declares."""

from __future__ import annotations

from dataclasses import dataclass

from planners.options import Options, option

__all__ = ["EPIBTOptions", "portfolio_option", "threads_option", "DEFAULT_OP_LEN", "MAX_OP_LEN", "AUTO_OP_LEN_FILL", "DEFAULT_REVISITS",
           "DEFAULT_LNS_PER_ROBOT", "DEFAULT_LNS_MAX", "DEFAULT_GROUP", "DEFAULT_WEIGHT_POWER", "MAX_PORTFOLIO"]

DEFAULT_OP_LEN = 3
MAX_OP_LEN = 5
#: ``op_len="auto"``: 4 while the robots fill at most this share of the free cells, else 3 (measured on
#: random-32-32-20: 4 gains at 100-400 robots and loses at 700-800, docs/design/lifelong_turning.md).
AUTO_OP_LEN_FILL = 0.5
#: Choices a robot may make per call (the first, then each time it is pushed).
DEFAULT_REVISITS = 10
#: Large-neighbourhood iterations per call and robot (at most :data:`DEFAULT_LNS_MAX`), robots per neighbourhood
#: (chosen on RANDOM-01, -03, -04, 300 steps: docs/design/lifelong_turning.md).
DEFAULT_LNS_PER_ROBOT = 50
DEFAULT_LNS_MAX = 1 << 15
DEFAULT_GROUP = 16
#: The search's weights ``(R + 1 - rank) ** p``: p = 0 did best over full RANDOM runs (design note).
DEFAULT_WEIGHT_POWER = 0
#: Joint plans per call at most (option ``portfolio``).
MAX_PORTFOLIO = 64

def portfolio_option(kept: str):
    """The ``portfolio`` option of a planner whose plans are ranked by ``kept`` (EPIBT's and the push chains')."""
    return option(1, int, 1, MAX_PORTFOLIO, meaning=f"joint plans per call from seeds apart (portfolio_seed), the one "
                  f"of {kept} kept (ties: the first)")


def threads_option():
    """The ``threads`` option beside ``portfolio``."""
    return option(None, int, 1, MAX_PORTFOLIO, none=True, meaning="threads the portfolio's plans run on (null: one "
                  "per plan, at most the cores this process may use); plans do not depend on it")


@dataclass(frozen=True)
class EPIBTOptions(Options):
    """EPIBT's own options (:class:`~planners.mapf.epibt.plans.EPIBTStep`; the cost-to-go's and the focus' are their
    parts')."""

    op_len: int | str = option(DEFAULT_OP_LEN, int, 1, MAX_OP_LEN, words=("auto",), meaning="actions per operation; "
                               "auto: chosen on the first call from the team's share of the free cells "
                               "(AUTO_OP_LEN_FILL)")
    revisits: int = option(DEFAULT_REVISITS, int, 1, 1000, meaning="choices a robot may make per call")
    lns: int | None = option(None, int, 0, 1 << 24, none=True, meaning="large-neighbourhood iterations per call "
                             "(null: 50 per robot, at most 32,768; 0 = off)")
    group: int = option(DEFAULT_GROUP, int, 2, 4096, meaning="robots per neighbourhood")
    weight_power: int = option(DEFAULT_WEIGHT_POWER, int, 0, 2, meaning="the search weighs each robot's cost-to-go "
                               "by (R + 1 - rank) ** weight_power, rank 0 the first in priority order")
    portfolio: int = portfolio_option("least weighted cost-to-go")
    threads: int | None = threads_option()
    steady: bool = option(False, bool, meaning="of operations of equal cost-to-go, one that waits beats one that "
                          "turns (a blocked robot keeps facing its way instead of turning to another as good)")
    anneal: float = option(0.0, float, 0.0, 1.0, meaning="the search's starting temperature, a share of a "
                           "neighbourhood's cost (0 = descent)")
