"""``epibt-chain``: EPIBT by push chains (:mod:`planners.mapf.epibt.chains`) as a planner with turning.

Contract: as :class:`~planners.mapf.epibt.plans.EPIBTStep` (``decide(pos, orient, goals, deadline, rest)``, one
valid joint action a call, deterministic for a seed without a deadline), with the 2024 winner's plan in place of
EPIBT's and a ``portfolio`` of plans, the one of highest score kept.
Design notes (scores, the clock): docs/design/lifelong_turning.md#epibt-chain-the-planner.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from planners.mapf.epibt.chains import (SEARCH_PUSHES, STEPS, Candidates, ChainKnobs, ChainRobots, chain_build,
                                        chain_candidates, chain_finish, chain_operations, chain_search, new_plan,
                                        stamp_seed)
from planners.mapf.epibt.options import portfolio_option, threads_option
from planners.mapf.epibt.plans import DEADLINE_MARGIN_S, op_idle, portfolio_threads, run_waves
from planners.mapf.guides.focus import checked_rest
from planners.mapf.pibt.turning import FORWARD, WAIT
from planners.options import Options, option

__all__ = ["ChainStep", "ChainOptions", "Ranked", "DEFAULT_CHAINS_PER_ROBOT"]

#: Search chains per call and robot (option ``lns``: null), at most :data:`DEFAULT_CHAINS_MAX`, in batches of at most
#: :data:`SEARCH_BATCH` chains; under a clock each batch also stops at its work budget (:data:`FIRST_WORK`).
DEFAULT_CHAINS_PER_ROBOT = 100
DEFAULT_CHAINS_MAX = 1 << 17
SEARCH_BATCH = 512
#: Under a clock the construction runs in spans of this many robots, stopped between two at the deadline.
BUILD_SPAN = 8
#: Under a clock the search's first batch stops after this much work (chains and their pushes); each later one after
#: the work half the time left allows at the pace of the batches before, none with less than :data:`_LAST_S` left.
FIRST_WORK = 2000
_LAST_S = 0.002
_NO_BUDGET = int(np.iinfo(np.int64).max)


class Ranked(NamedTuple):
    """One call's robots as the plans read them (:meth:`ChainStep.ranked`)."""

    cand: Candidates   # each robot's operations, best first
    gain: np.ndarray   # (R, M) each operation's gain over waiting, weighed by the robot's power
    order: np.ndarray  # the robots in rank order: at work first, least task still to go first
    busy: np.ndarray   # (R,) which are at work


@dataclass(frozen=True)
class ChainOptions(Options):
    """The push chains' own options (:class:`ChainStep`; the cost-to-go's and the focus' are their parts')."""

    lns: int | None = option(None, int, 0, 1 << 24, none=True, meaning="search chains per plan and call (null: "
                             f"{DEFAULT_CHAINS_PER_ROBOT} per robot, at most {DEFAULT_CHAINS_MAX:,}; 0 = off)")
    weight_power: int = option(2, int, 0, 2, meaning="a robot's score counts (R + 1 - rank) ** weight_power times, "
                               "rank 0 the robot of least task still to go")
    anneal: float = option(0.001, float, 0.0, 1.0, meaning="the search's starting temperature, a share of the plan's "
                           "score (cooling by 0.999 a chain; 0 = keep only chains that do not lower the score)")
    push_built: float = option(0.2, float, 0.0, 1.0, meaning="the chance the construction pushes a robot that has "
                               "already chosen (one still waiting is always pushed)")
    skip: float = option(0.2, float, 0.0, 1.0, meaning="the chance a search chain passes over a robot in its way")
    pushes: int = option(SEARCH_PUSHES, int, 1, 1 << 20, meaning="a search chain pushing more robots than this is "
                         "refused (the winner's cap: 1,000)")
    portfolio: int = portfolio_option("highest score")
    threads: int | None = threads_option()


class ChainStep:
    """EPIBT by push chains as a planner's decider (module docstring) over the cost-to-go of ``source`` (a
    :class:`~planners.mapf.guides.fields.FieldSource`); with a ``machine_step``, its ``search_stop(now, stop)`` says
    under a clock when the host search of a plan stops, and ``improve(self, plan, ranked, deadline)`` may change the
    kept plan before its first actions are taken (its :attr:`last_compute` the step's machine charge)."""

    Options = ChainOptions
    uses_rest = True  # the ranking reads each robot's task beyond its goal when given

    def __init__(self, site, source, priorities, opts: ChainOptions, machine_step=None) -> None:
        self.site, self.source, self.prio = site, source, priorities
        self.machine_step = machine_step
        self.options = opts
        self.portfolio = opts.portfolio
        self.threads = portfolio_threads(opts.portfolio, opts.threads)
        self.lns_option, self.weight_power = opts.lns, opts.weight_power
        self.kernel_s = 0.0
        self.ops, depth = chain_operations()
        self.depth = depth
        self.idle = op_idle(self.ops)
        self.quiet = ((self.ops != WAIT) * (STEPS - np.arange(STEPS))).sum(axis=1).astype(np.int64)
        self.draws = np.arange(3, STEPS + 1, dtype=np.int64)  # the depths a plan draws from
        self.portfolio_scores = np.zeros(0, dtype=np.int64)
        self.search_work = np.zeros(0, dtype=np.int64)  # the last call's search work per plan: chains and pushes
        self.search_batches = 0  # and its batches over the plans
        self.plan_score = 0  # the score of the plan the last call took its actions from
        self.kept = 0
        self.plans = np.zeros((0, STEPS), dtype=np.int8)  # the last call's operations (-1 rows: waiting)
        self.targets = np.zeros(0, dtype=np.int64)

    def decide(self, pos, orient, goals, deadline: float | None = None, rest=None) -> np.ndarray:
        """The joint action (as :meth:`PIBTStep.decide <planners.mapf.pibt.turning.PIBTStep.decide>`), by push
        chains; ``rest`` (checked), when given, joins each robot's way in the ranking."""
        if rest is not None:
            rest = checked_rest(rest, len(pos))
        r = len(pos)
        site, prio = self.site, self.prio
        pc, gc = site.cid[pos], site.cid[goals]
        fields, rows = self.source.heuristic(pc, gc, prio.order(r), deadline, self.kernel_s)
        t0 = time.perf_counter()
        ranked = self.ranked(ChainRobots(pc, orient, gc, rows), fields, rest)
        cand, gain, order = ranked.cand, ranked.gain, ranked.order
        chains = min(r * DEFAULT_CHAINS_PER_ROBOT, DEFAULT_CHAINS_MAX) if self.lns_option is None else self.lns_option
        opts = self.options
        plans = [new_plan(r, len(site.cell_of), stamp_seed(prio.seed, prio.t, k), opts.anneal)
                 for k in range(self.portfolio)]
        knobs = ChainKnobs(opts.push_built, opts.skip, opts.pushes)
        stop = None if deadline is None else deadline - 2 * DEADLINE_MARGIN_S
        batches = [0] * self.portfolio

        def run(k):
            built = 0
            while built < r or built == 0:  # under a clock in spans, stopped between two (the rest wait)
                n = r if stop is None else BUILD_SPAN
                chain_build(cand, gain, order, self.draws, knobs, (built, built + n), plans[k])
                built += n
                if stop is not None and time.perf_counter() > stop:
                    break
            plan, done, spent, worked = plans[k], 0, 0.0, 0
            halt = None if stop is None else self._search_stop(time.perf_counter(), stop)
            while done < chains:  # in batches; under a clock each given the work half the time left allows
                budget = _NO_BUDGET
                if halt is not None:
                    t1 = time.perf_counter()
                    if halt - t1 < _LAST_S:
                        break
                    pace = FIRST_WORK if worked == 0 else int(0.5 * (halt - t1) * worked / max(spent, 1e-9))
                    budget = int(plan.work[0]) + max(pace, 1)
                w0 = int(plan.work[0])
                done += chain_search(cand, gain, self.draws, knobs, (done, min(SEARCH_BATCH, chains - done)), budget,
                                     plan)
                batches[k] += 1
                if halt is not None:
                    spent, worked = spent + time.perf_counter() - t1, worked + int(plan.work[0]) - w0
            chain_finish(cand, gain, plan)

        done = run_waves(run, self.portfolio, self.threads, deadline)
        self.kernel_s = time.perf_counter() - t0
        self.portfolio_scores = np.array([p.score[0] for p in plans[:done]], dtype=np.int64)
        self.search_work = np.array([p.work[0] for p in plans[:done]], dtype=np.int64)
        self.search_batches = sum(batches[:done])
        self.kept = int(np.argmax(self.portfolio_scores))
        if self.machine_step is not None:
            self.machine_step.improve(self, plans[self.kept], ranked, deadline)
        self.plan_score = int(plans[self.kept].score[0])
        choice = plans[self.kept].choice
        on = choice >= 0
        op = np.where(on, cand.op[np.arange(r), np.maximum(choice, 0)], 0)
        self.plans = np.where(on[:, None], self.ops[op], WAIT).astype(np.int8)
        act = np.where(on, self.ops[op, 0], cand.idle_act).astype(np.int64)
        ahead = site.nbr[pc, orient].astype(np.int64)
        nxt = np.where(act == FORWARD, ahead, pc)
        self.targets = site.cell_of[nxt]
        prio.advance(nxt, gc)
        return act

    def ranked(self, robots: ChainRobots, fields: np.ndarray, rest=None) -> Ranked:
        """What the plans of one call work on (a :class:`Ranked`) for ``robots`` in compact cells with their rows of
        ``fields``."""
        r, n_ops = len(robots.pos), self.ops.shape[0]
        cand = Candidates(np.empty((r, n_ops, STEPS + 1), np.int64), np.zeros((r, n_ops), np.int64),
                          np.zeros((r, n_ops), np.int64), np.empty((r, n_ops), np.int64), np.empty(r, np.int64),
                          np.empty((r, STEPS + 1), np.int64), np.empty(r, np.int64), np.empty(r, np.int64),
                          np.empty(r, np.int64))
        per_cell = fields.shape[1] // max(len(self.site.cell_of), 1)
        chain_candidates(self.source.move_grid, (fields, int(np.iinfo(fields.dtype).max), per_cell), robots, self.ops,
                         (self.idle, self.quiet), cand)
        cand = cand._replace(depth=self.depth[cand.op])
        busy = robots.pos != robots.goals
        way = cand.to_go + (rest if rest is not None else 0)
        order = np.lexsort((np.arange(r), way, ~busy)).astype(np.int64)  # at work first, least way first
        rank = np.empty(r, dtype=np.int64)
        rank[order] = np.arange(r)
        power = np.where(busy, (r + 1 - rank) ** self.weight_power, 0).astype(np.int64)
        gain = power[:, None] * (cand.wait_value[:, None] - cand.value)
        return Ranked(cand, gain, order, busy)

    def _search_stop(self, now: float, stop: float) -> float:
        """Under a clock, when the search of a plan built by ``now`` stops: at ``stop``, the planner's own, or where
        the machine step says."""
        return stop if self.machine_step is None else self.machine_step.search_stop(now, stop)
