"""Where the push-chain search's work goes, and what its push cap buys (issue 57).

On a dense state of a League map (default RANDOM-05's, 800 robots on random distinct cells with random goals, moved
``--warm`` steps by ``epibt-chain`` so that they stand in each other's way), one construction of the chain plan, then:
(1) ``--chains`` search chains run one at a time, each one's work (its pushes and itself, ``plan.work``) and whether
it changed the plan; (2) for each push cap of ``--caps``, the search run from the same construction for ``--seconds``
of one thread, in batches as under the clock, and the score it adds (three plans' seeds each).  One thread; run
nothing beside it.

    python benchmarks/chain_work.py [--instance RANDOM-05] [--robots 800] [--write]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import cpu_name, finish  # noqa: E402

SECTION = "## Where the push-chain search's work goes, and its push cap (issue 57)"
ROOT = Path(__file__).resolve().parents[2] / "shared" / "lorr" / "2024-main" / "random.domain"
BANDS = ((0, 10), (10, 100), (100, 1000), (1000, None))


def dense_state(args):
    """The planner (``epibt-chain``, lanes of weight 2, one plan) and a state after ``args.warm`` steps."""
    from mrmt_env.lorr.instance import read_instance
    from planners.mapf import make_turning_planner

    grid = read_instance(ROOT / f"{args.instance}.json").grid
    free = np.flatnonzero(~grid.reshape(-1))
    rng = np.random.default_rng(args.seed)
    ex = make_turning_planner("epibt-chain", grid, seed=args.seed, guidance=2, threads=1, lns=2000)
    pos = rng.choice(free, args.robots, replace=False).astype(np.int64)
    orient = rng.integers(0, 4, args.robots).astype(np.int64)
    goals = rng.choice(free, args.robots).astype(np.int64)
    for _ in range(args.warm):
        pos, orient = ex.step(pos, orient, goals)
        goals = np.where(pos == goals, rng.choice(free, args.robots), goals)
    return ex, pos, orient, goals


def main(argv=None) -> None:
    from planners.mapf.epibt.chains import ChainKnobs, ChainRobots, chain_build, chain_search, new_plan

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--instance", default="RANDOM-05")
    parser.add_argument("--robots", type=int, default=800)
    parser.add_argument("--warm", type=int, default=8)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--chains", type=int, default=20000)
    parser.add_argument("--caps", default="1000,300,100,30")
    parser.add_argument("--seconds", type=float, default=0.45, help="search time per plan (the entry's two plans "
                        "share a 1 s step on two cores)")
    parser.add_argument("--write", action="store_true")
    args = parser.parse_args(argv)
    ex, pos, orient, goals = dense_state(args)
    chain = ex.decider  # the push chains' decider (ChainStep)
    pc, gc = ex.site.cid[pos], ex.site.cid[goals]
    fields, rows = ex.source.heuristic(pc, gc, ex.prio.order(len(pos)))  # the goal fields (epibt-chain: flow off)
    ranked = chain.ranked(ChainRobots(pc, orient, gc, rows), fields)
    cand, gain, order = ranked.cand, ranked.gain, ranked.order
    opts, r, cells = ex.options, len(pos), len(ex.site.cell_of)

    def built(seed, knobs):
        plan = new_plan(r, cells, seed, opts.anneal)
        chain_build(cand, gain, order, chain.draws, knobs, (0, r), plan)
        return plan

    knobs = ChainKnobs(opts.push_built, opts.skip)
    plan = built(1, knobs)
    work, changed = np.zeros(args.chains, np.int64), np.zeros(args.chains, bool)
    for i in range(args.chains):
        before, w0 = plan.choice.copy(), int(plan.work[0])
        chain_search(cand, gain, chain.draws, knobs, (i, 1), 1 << 62, plan)
        work[i], changed[i] = int(plan.work[0]) - w0, not np.array_equal(before, plan.choice)
    total = max(int(work.sum()), 1)
    lines = [SECTION, "", f"`python benchmarks/chain_work.py --instance {args.instance} --robots {args.robots} --warm "
             f"{args.warm} --chains {args.chains} --caps {args.caps} --seconds {args.seconds}` ({cpu_name()}, one "
             f"thread; `epibt-chain`, lanes of weight 2, the cap of 1,000 for the chains counted).", "",
             "| chain's work (pushes + 1) | chains | changed the plan | share of the search's work |",
             "|---|---:|---:|---:|"]
    for lo, hi in BANDS:
        m = (work >= lo) & (work < (hi if hi is not None else 1 << 62))
        band = f"{lo:,}-{hi - 1:,}" if hi is not None else f"{lo:,} and more (the cap)"
        lines.append(f"| {band} | {int(m.sum()):,} | {100 * changed[m].mean() if m.any() else 0:.1f} % | "
                     f"{100 * work[m].sum() / total:.1f} % |")
    lines += ["", "| push cap | chains in the time | score added (3 seeds) | mean |", "|---:|---:|---|---:|"]
    for cap in [int(c) for c in args.caps.split(",")]:
        knobs, gains, counts = ChainKnobs(opts.push_built, opts.skip, cap), [], []
        for seed in (11, 12, 13):
            plan = built(seed, knobs)
            s0, done, t0 = int(plan.score[0]), 0, time.perf_counter()
            while time.perf_counter() - t0 < args.seconds:
                done += chain_search(cand, gain, chain.draws, knobs, (done, 512), 1 << 62, plan)
            gains.append(int(plan.score[0]) - s0)
            counts.append(done)
        lines.append(f"| {cap:,} | {int(np.mean(counts)):,} | {' / '.join(f'{g:.3g}' for g in gains)} | "
                     f"{np.mean(gains):.3g} |")
        print(lines[-1], file=sys.stderr)
    finish(SECTION, lines, args.write)


if __name__ == "__main__":
    main()
