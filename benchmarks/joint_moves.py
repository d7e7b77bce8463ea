"""Joint next moves on the Ising chip vs PIBT's priority order (issue 33, item 3), measured.

``decisions``: groups sampled from LoRR runs driven by the host rule (start kit greedy scheduler,
``pibt``), each solved three ways under one objective (planners/mapf/chip/joint_moves.py): the host
rule's answer, the chip's (best decoded read, repaired), the exact optimum (branch and bound).
``e2e``: the same run loop with ``pibt`` and with ``pibt-ising`` as the executor, same seeds and the
same lane guidance (``--guidance``, default 0).

    flock /tmp/mrmt-bench.lock python benchmarks/joint_moves.py decisions --steps 200
    flock /tmp/mrmt-bench.lock python benchmarks/joint_moves.py e2e --steps 300
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2] / "shared" / "lorr" / "2024-main" / "random.domain"


def sample_decisions(path, steps, seed=0, per_instance=400, **options):
    """Groups of the host rule's own run: ``(problems, host rule seconds per step, group seconds per step,
    groups per step)``; ``per_instance`` problems drawn uniformly (seeded) from all steps."""
    from agents.lorr.schedulers import make_scheduler
    from mrmt_env.lorr.instance import read_instance
    from mrmt_env.lorr.loop import StepLoop
    from mrmt_env.lorr.sim import LoRRSimulator
    from planners.mapf import make_turning_planner

    inst = read_instance(path)
    loop = StepLoop(LoRRSimulator(inst, record=False), make_scheduler("lorr-greedy", seed=seed))
    sim = loop.sim
    ex = make_turning_planner("pibt-ising", inst.grid, seed=seed, accept="host", **options)
    ref = make_turning_planner("pibt", inst.grid, seed=seed, guidance=0)  # the host rule alone, on the same states
    chip = ex.machine_step  # the joint moves' step (JointMovesStep): collects the groups instead of deciding
    chip.sample = []
    host_s, group_s, groups = [], [], []
    for _ in range(steps):
        loop.propose()
        goals = loop.goal_cells()
        t0 = time.perf_counter()
        a_ref = ref.actions(sim.pos, sim.orient, goals)
        t1 = time.perf_counter()
        n0 = len(chip.sample)
        act = ex.actions(sim.pos, sim.orient, goals)
        t2 = time.perf_counter()
        assert np.array_equal(act, a_ref)
        host_s.append(t1 - t0)
        group_s.append(max((t2 - t1) - (t1 - t0), 0.0))
        groups.append(len(chip.sample) - n0)
        loop.advance(act)
    rng = np.random.default_rng(seed)
    pick = np.sort(rng.choice(len(chip.sample), min(per_instance, len(chip.sample)), replace=False))
    return [chip.sample[i] for i in pick], np.array(host_s), np.array(group_s), np.array(groups), sim.finished


def solve_problems(problems, machine, num_reads=8, penalty=None, chunk=64, seed=0):
    """Per problem: ``(host, chip, exact, not_one_hot, conflict, host seconds of build + decode)``."""
    from ising_backend import integer_program
    from planners.mapf.chip.joint_moves import build_qubo, decode_reads, group_spread, objective, solve_exact

    out = []
    for c0 in range(0, len(problems), chunk):
        batch = problems[c0:c0 + chunk]
        n = max(int(p[1][-1]) for p in batch)
        H = np.zeros((len(batch), n), dtype=np.int64)
        J = np.zeros((len(batch), n, n), dtype=np.int64)
        q = np.empty((n, n), dtype=np.int64)
        build = []
        for g, (pos, ostart, opt, host) in enumerate(batch):
            t0 = time.perf_counter()
            size = len(pos)
            mem = np.arange(size)
            pen = 1 + group_spread(0, size, ostart, opt) if penalty is None else penalty
            k = build_qubo(pos, mem, 0, size, ostart, opt, pen, pen, q)
            integer_program(q, k, H[g, :k], J[g, :k, :k], (7, 7))
            build.append(time.perf_counter() - t0)
        spins, _ = machine.anneal_batch(H, J, num_reads=num_reads, seed=seed + c0)
        for g, (pos, ostart, opt, host) in enumerate(batch):
            size = len(pos)
            mem = np.arange(size)
            choice = np.empty(size, dtype=np.int64)
            stats = np.zeros(2, dtype=np.int64)
            t0 = time.perf_counter()
            e_chip = decode_reads(pos, mem, 0, size, ostart, opt, host, spins[g], choice, stats)
            t1 = time.perf_counter()
            e_host = objective(0, size, ostart, opt, host)
            e_opt = solve_exact(pos, mem, 0, size, ostart, opt, choice)
            out.append((e_host, e_chip, e_opt, stats[0], stats[1], build[g] + t1 - t0))
    return np.array(out, dtype=float)


def summary(res):
    h, c, e = res[:, 0], res[:, 1], res[:, 2]
    den = np.maximum(np.abs(e), 1)
    return {"decisions": len(res), "chip_better": float((c < h).mean()), "chip_worse": float((c > h).mean()),
            "host_suboptimal": float((e < h).mean()), "chip_optimal": float((c == e).mean()),
            "gap_host": float(((h - e) / den).mean()), "gap_chip": float(((c - e) / den).mean()),
            "gap_host_sum": float((h - e).sum() / np.abs(e).sum()), "gap_chip_sum": float((c - e).sum() / np.abs(e).sum())}


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("mode", choices=["decisions", "e2e"])
    ap.add_argument("--instances", default="1,2,3,4,5")
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--per-instance", type=int, default=400)
    ap.add_argument("--reads", type=int, default=32)
    ap.add_argument("--penalty", type=int, default=10)
    ap.add_argument("--levels", type=int, default=3)
    ap.add_argument("--push", type=int, default=2)
    ap.add_argument("--max-robots", type=int, default=11)
    ap.add_argument("--accept", default="better")
    ap.add_argument("--guidance", type=int, default=0,
                    help="lane guidance of both executors in e2e (the same for the chip and the host rule)")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    from ising_backend import EmulatedChip

    names = [f"RANDOM-0{i}" for i in args.instances.split(",")]
    rows = []
    if args.mode == "decisions":
        allres = []
        for name in names:
            probs, host_s, group_s, groups, _ = sample_decisions(ROOT / f"{name}.json", args.steps,
                                                                 per_instance=args.per_instance, levels=args.levels, push=args.push,
                                                                 max_robots=args.max_robots)
            res = solve_problems(probs, EmulatedChip(seed=0), num_reads=args.reads, penalty=args.penalty)
            allres.append(res)
            per = max(groups.sum(), 1)
            row = {"instance": name, **summary(res), "groups_per_step": float(groups.mean()),
                   "host_rule_ms_per_step": 1e3 * host_s.mean(), "host_rule_ms_per_decision": 1e3 * host_s.sum() / per,
                   "chip_host_ms_per_decision": 1e3 * (group_s.sum() / per + res[:, 5].mean()),
                   "not_one_hot_reads": float(res[:, 3].sum() / (len(res) * args.reads)),
                   "conflict_repaired_reads": float(res[:, 4].sum() / (len(res) * args.reads))}
            rows.append(row)
            print(json.dumps(row), flush=True)
        print(json.dumps({"instance": "all", **summary(np.concatenate(allres))}), flush=True)
    else:
        from agents.lorr.run import run_lorr
        from agents.lorr.spec import PlannerSpec
        from planners.mapf import TURNING_PLANNERS
        from planners.mapf.chip.joint_executor import JointMovesOptions, JointMovesStep

        made = []  # the variant's machine steps, the last one the latest run's

        def machine_step(o, machine, seed, site):
            step = JointMovesStep(o.part(JointMovesOptions), machine, seed, len(site.cell_of))
            made.append(step)
            return step

        # the variant: pibt-ising's parts with a machine step of its own, which keeps each run's step for its counts
        variant = TURNING_PLANNERS["pibt-ising"]._replace(name="pibt-ising-bench", machine_step=machine_step)
        TURNING_PLANNERS[variant.name] = variant
        own = dict(levels=args.levels, push=args.push, penalty=args.penalty, num_reads=args.reads,
                   max_robots=args.max_robots, accept=args.accept, guidance=args.guidance)
        for name in names:
            for seed in range(args.seeds):
                for ex in ("pibt", "pibt-ising-bench"):
                    planner = PlannerSpec.of(ex, {"guidance": args.guidance} if ex == "pibt" else own)
                    rec, sim, step_s = run_lorr(ROOT / f"{name}.json", "lorr-greedy", planner, steps=args.steps,
                                                seed=seed)
                    row = {k: rec[k] for k in ("instance", "executor", "seed", "tasks_finished", "errors",
                                               "step_p50_s", "step_p99_s")}
                    if ex != "pibt":
                        e = made[-1]
                        row.update(decisions=e.decisions, changed=e.changed, chip_calls=e.ledger.physical_calls,
                                   chip_parallel_s=e.ledger.chip_time_parallel_s, emulation_s=e.ledger.emulation_s,
                                   host_ms_per_decision=1e3 * e.host_s / max(e.decisions, 1))
                    rows.append(row)
                    print(json.dumps(row), flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
