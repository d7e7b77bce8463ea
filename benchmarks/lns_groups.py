"""Neighbourhood groups of EPIBT's search decided on the Ising chip vs the search's greedy (issue 33, item 3).

Every run: the start kit's greedy scheduler on RANDOM-0x for ``--steps`` steps, executor ``epibt-ising`` with the
chip deciding (``decider="chip"``) and with the host rule in its place (``decider="host"``, same seeds, same
groups per step), beside plain ``epibt`` (its own search, the best host configuration).  ``--lns`` sets the
search iterations of both ``epibt-ising`` arms (default 0: the groups are the only search).  In the chip arm each
decision is also solved exactly (depth-first over the group's options), so the chip's and the host rule's costs
are compared with the optimum of the same problem.  ``--levels L`` gives the chip arm a chip whose fields and
couplings take ``-L .. L`` (the paper's chip: 7), ``--chip-only`` runs that arm alone (its decision tables);
``--min-gain G`` applies a group's choice in both arms only when it saves at least ``G``.

    flock /tmp/mrmt-bench.lock python benchmarks/lns_groups.py --steps 300 --write
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import cpu_name, finish  # noqa: E402
from planners.mapf.chip.group_kernels import collide as _collide, cost_of as _cost  # noqa: E402

SECTION = "## Neighbourhood groups of EPIBT on the chip (`epibt-ising`, issue 33)"
ROOT = Path(__file__).resolve().parents[2] / "shared" / "lorr" / "2024-main" / "random.domain"


@numba.njit(cache=True)
def exact_cost(state, members, a, b, ostart, opt) -> int:
    """Least cost of a collision-free choice of the group (depth-first, pruned by collisions and cost)."""
    size = b - a
    cur = np.zeros(size, dtype=np.int64)
    acc = np.zeros(size + 1, dtype=np.int64)
    best = 1 << 60
    d = 0
    cur[0] = -1
    while d >= 0:
        cur[d] += 1
        if cur[d] >= ostart[a + d + 1] - ostart[a + d]:
            d -= 1
            continue
        q = members[a + d]
        c = _cost(state, q, opt[ostart[a + d] + cur[d]])
        if acc[d] + c >= best:
            continue
        ok = True
        for e in range(d):
            if _collide(state, q, opt[ostart[a + d] + cur[d]], members[a + e], opt[ostart[a + e] + cur[e]]):
                ok = False
                break
        if not ok:
            continue
        acc[d + 1] = acc[d] + c
        if d == size - 1:
            best = acc[d + 1]
        else:
            d += 1
            cur[d] = -1
    return best


def run(instance: str, steps: int, executor: str, options: dict, exact: bool, seed: int = 0):
    from agents.lorr.schedulers import make_scheduler
    from mrmt_env.lorr.instance import read_instance
    from mrmt_env.lorr.loop import StepLoop
    from mrmt_env.lorr.sim import LoRRSimulator
    from planners.mapf import make_turning_planner
    from planners.mapf.chip import group_rounds as E  # the group rounds: the host rule's and the chip's decisions

    inst = read_instance(ROOT / f"{instance}.json")
    loop = StepLoop(LoRRSimulator(inst, record=False), make_scheduler("lorr-greedy", seed=seed))
    sim = loop.sim
    if "levels" in options:  # a chip of wider (or narrower) coefficient ranges: a what-if for chip makers
        from ising_backend import ChipSpec, EmulatedChip

        lv = options.pop("levels")
        options["machine"] = EmulatedChip(spec=ChipSpec(h_range=(-lv, lv), j_range=(-lv, lv)), seed=seed)
    ex = make_turning_planner(executor, inst.grid, seed=seed, **options)
    gaps = []  # per decision: host cost, chip cost, optimum, the group's plan now
    fill = [0]
    judged = [0.0]  # seconds spent judging (exact solve, plan cost): not the executor's, taken off its times
    if exact:  # wrap the rounds' host rule and decoder: each decision's host rule, chip and exact costs
        greedy, decode = E.host_choices, E.decode_choices

        def greedy_rec(state, batch, stamp, choice, cost):
            greedy(state, batch, stamp, choice, cost)
            t0 = time.perf_counter()
            src, members, gstart, ostart, opt = state.src, batch.members, batch.gstart, batch.ostart, batch.opt
            for g in range(batch.ng):
                a, b = gstart[g], gstart[g + 1]
                gaps.append([int(cost[g]), None, exact_cost(state, members, a, b, ostart, opt),
                             sum(int(_cost(state, q, src[q])) for q in members[a:b])])
            judged[0] += time.perf_counter() - t0

        def decode_rec(state, batch, spins, choice, cost):
            decode(state, batch, spins, choice, cost)
            for g in range(batch.ng):  # groups are decoded in the order the host rule took them
                gaps[fill[0]][1] = int(cost[g])
                fill[0] += 1

        E.host_choices, E.decode_choices = greedy_rec, decode_rec
    step_s = np.zeros(steps)
    try:
        for t in range(steps):
            loop.propose()
            t0, j0 = time.perf_counter(), judged[0]
            act = ex.actions(sim.pos, sim.orient, loop.goal_cells())
            emul = float(ex.last_compute.emulation_s) + judged[0] - j0
            step_s[t] = time.perf_counter() - t0 - emul + ex.last_compute.chip_time_parallel_s
            loop.advance(act)
    finally:
        if exact:
            E.host_choices, E.decode_choices = greedy, decode
    stats = dict(getattr(ex.machine_step, "stats", {}))  # the group decisions' counts (epibt-ising)
    if "host_s" in stats:
        stats["host_s"] -= judged[0]
    return {"tasks": sim.finished, "errors": len(sim.errors), "p99": float(np.percentile(step_s, 99)),
            "stats": stats, "gaps": gaps}


def per_decision_ms(stats: dict) -> float:
    return 1e3 * stats["host_s"] / max(stats["decisions"], 1)


def decision_tables(g: np.ndarray) -> list[str]:
    """The per-decision tables of ``g`` (rows: host rule cost, chip cost, optimum, the group's plan now; -1: no
    answer), read three ways: the answers themselves; what each decider leaves (its answer where it has one
    cheaper than the plan now, else the plan now: the decision as the executor applies it); the same on the
    decisions whose plan now is not the optimum."""
    host, chip, best, now = g[:, 0], g[:, 1], g[:, 2], g[:, 3]
    ok_h, ok_c = host >= 0, chip >= 0
    denom = np.maximum(np.abs(best), 1)
    better = ok_c & (~ok_h | (chip < host))
    worse = ok_h & (~ok_c | (chip > host))
    hg = np.where(ok_h, (host - best) / denom, np.nan)
    cg = np.where(ok_c, (chip - best) / denom, np.nan)
    left_h = np.where(ok_h & (host < now), host, now)
    left_c = np.where(ok_c & (chip < now), chip, now)
    lh, lc = (left_h - best) / denom, (left_c - best) / denom
    hard = lh >= 0.05
    room = best < now  # decisions where the plan now is not the optimum: something to decide
    return ["Per decision, the answers (chip arm's own trajectory; cost = the group's summed cost-to-go; gaps as "
            "fractions of the optimum over the decisions with an answer; a host rule or chip without a collision-free "
            "answer keeps the plan and counts as no answer):", "",
            "| decisions | chip better | chip worse | host rule no answer | chip no answer | host gap | chip gap | "
            "chip optimal |", "|---:|---:|---:|---:|---:|---:|---:|---:|",
            f"| {len(g):,} | {100 * better.mean():.1f} % | {100 * worse.mean():.1f} % | {100 * (~ok_h).mean():.1f} % | "
            f"{100 * (~ok_c).mean():.1f} % | {100 * np.nanmean(hg):.2f} % | {100 * np.nanmean(cg):.2f} % | "
            f"{100 * (ok_c & (chip == best)).mean():.1f} % |", "",
            "Per decision, what each decider leaves (its answer where it is cheaper than the group's plan now, else "
            "the plan now; every decision counted; gaps to the optimum, which is never above the plan now):", "",
            "| decisions | left better by the chip | left worse by the chip | host gap | chip gap | decisions where the "
            "host rule leaves >= 5 % | chip gap there | host gap there |", "|---:|---:|---:|---:|---:|---:|---:|---:|",
            f"| {len(g):,} | {100 * (left_c < left_h).mean():.1f} % | {100 * (left_c > left_h).mean():.1f} % | "
            f"{100 * lh.mean():.2f} % | {100 * lc.mean():.2f} % | {100 * hard.mean():.1f} % | "
            f"{100 * lc[hard].mean() if hard.any() else 0:.2f} % | {100 * lh[hard].mean() if hard.any() else 0:.2f} % |",
            "", "The same on the decisions where the plan now is not the optimum (something to decide):", "",
            "| decisions | share of all | left better by the chip | left worse by the chip | host leaves the optimum | "
            "chip leaves the optimum | host gap | chip gap |", "|---:|---:|---:|---:|---:|---:|---:|---:|",
            f"| {int(room.sum()):,} | {100 * room.mean():.1f} % | {100 * (left_c < left_h)[room].mean():.1f} % | "
            f"{100 * (left_c > left_h)[room].mean():.1f} % | {100 * (left_h == best)[room].mean():.1f} % | "
            f"{100 * (left_c == best)[room].mean():.1f} % | {100 * lh[room].mean():.2f} % | {100 * lc[room].mean():.2f} % |"]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--instances", default="1,2,3,4,5")
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--groups", type=int, default=64)
    ap.add_argument("--lns", type=int, default=0, help="search iterations of both arms (-1: the executor's default)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the scheduler and the executors (default 0)")
    ap.add_argument("--write", action="store_true")
    ap.add_argument("--save", help="write the per-decision costs (host, chip, optimum, plan now) as a .npy file")
    ap.add_argument("--levels", type=int, default=7, help="the chip arm's coefficient range -L..L (default 7)")
    ap.add_argument("--chip-only", action="store_true", help="run the chip arm alone and print its decision tables")
    ap.add_argument("--min-gain", type=int, default=1, help="both arms' min_gain (default 1: any gain is applied)")
    args = ap.parse_args(argv)
    rows, decisions = [], []
    lv = {} if args.levels == 7 else {"levels": args.levels}
    mg = {} if args.min_gain == 1 else {"min_gain": args.min_gain}
    if args.chip_only:
        lns = {} if args.lns < 0 else {"lns": args.lns}
        g = np.concatenate([np.array(run(f"RANDOM-0{i}", args.steps, "epibt-ising", {
            "decider": "chip", "groups": args.groups, **lns, **lv, **mg}, True, args.seed)["gaps"],
            dtype=np.float64).reshape(-1, 4) for i in [int(x) for x in args.instances.split(",") if x]])
        print(f"chip of -{args.levels}..{args.levels}, instances {args.instances}, {args.steps} steps", *decision_tables(g),
              sep="\n")
        return
    for i in [int(x) for x in args.instances.split(",") if x]:
        name = f"RANDOM-0{i}"
        base = run(name, args.steps, "epibt", {}, False, args.seed)
        lns = {} if args.lns < 0 else {"lns": args.lns}
        arms = {d: run(name, args.steps, "epibt-ising", {"decider": d, "groups": args.groups, **lns, **mg,
                                                         **(lv if d == "chip" else {})},
                       d == "chip", args.seed) for d in ("host", "chip")}
        g = np.array(arms["chip"]["gaps"], dtype=np.float64).reshape(-1, 4)
        decisions.append(g)
        st = arms["chip"]["stats"]
        row = (f"| {name} | {base['tasks']} | {arms['host']['tasks']} | {arms['chip']['tasks']} | "
               f"{100 * (arms['chip']['tasks'] / max(arms['host']['tasks'], 1) - 1):+.1f} % | "
               f"{st['decisions']:,} | {st['applied']:,} / {arms['host']['stats']['applied']:,} | "
               f"{1e3 * arms['host']['p99']:.0f} / {1e3 * arms['chip']['p99']:.0f} | "
               f"{per_decision_ms(arms['host']['stats']):.3f} / {per_decision_ms(st):.3f} | "
               f"{arms['host']['errors'] + arms['chip']['errors'] + base['errors']} |")
        rows.append(row)
        print(row, flush=True)
    g = np.concatenate(decisions)
    if args.save:
        np.save(args.save, g)
    gain = "" if args.min_gain == 1 else f" --min-gain {args.min_gain}"
    lines = [SECTION, "", f"`python benchmarks/lns_groups.py --steps {args.steps} --groups {args.groups} --lns {args.lns}{gain} "
             f"--write` on {cpu_name()}: start kit greedy scheduler, seed {args.seed}, {args.steps} steps per instance; "
             f"`epibt-ising` with {args.groups} groups per step (up to 11 robots x 4 operations; 64 reads, penalty 2: "
             "the defaults) and "
             f"{args.lns} search iterations, the chip deciding or the host rule (the search's greedy) in its place; "
             "`epibt` = EPIBT with its own search (default), the best host configuration.  Step p99: executor host "
             "seconds (emulation excluded) + chip seconds at 50 us a call, parallel dispatch; host ms per decision: "
             "each arm's executor host seconds in the groups (program build, greedy, decode, apply) over its decisions.",
             "", "| instance | epibt tasks | host rule tasks | chip tasks | chip vs host rule | decisions | applied chip / "
             "host | step p99 ms host / chip | host ms per decision host / chip | errors |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|", *rows, "", *decision_tables(g)]
    finish(SECTION, lines, args.write)


if __name__ == "__main__":
    main()
