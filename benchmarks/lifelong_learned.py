"""The learned lifelong controller (MaskablePPO task choice) against greedy, strong and ising.

Trains a model as ``mrmt train --env-id mrmt_env/MRMT-Lifelong-v0 --timesteps
T --seed S`` does (or takes ``--model``), then runs ``greedy``, ``strong``,
``ising`` and ``ppo:model`` through PIBT on held-out seeds (from 1000) of
``mrmt_env/MRMT-Lifelong-v0`` (10 x 10, 3 robots, 10 open tasks) and, with
the same model, of ``mrmt_env/MRMT-Lifelong-Warehouse-v0`` (100 robots), beside
a model trained on the warehouse id (``--warehouse-timesteps``).
Same seeds, same worlds and task streams for every controller; throughput
ratios to greedy's are episode by episode.  Writes the RESULTS.md section.

    flock /tmp/mrmt-bench.lock python benchmarks/lifelong_learned.py
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from _common import cpu_name, write_results_section  # noqa: E402

SMALL_ID = "mrmt_env/MRMT-Lifelong-v0"
WAREHOUSE_ID = "mrmt_env/MRMT-Lifelong-Warehouse-v0"
SECTION = "## Issue 25: learned lifelong controller (MaskablePPO task choice)"
FIRST_SEED = 1000


def _evaluate(env_id: str, specs: list[str], episodes: int, steps: int) -> list[dict]:
    from agents.lifelong.evaluation import evaluate_lifelong, summarize

    seeds = range(FIRST_SEED, FIRST_SEED + episodes)
    rows = evaluate_lifelong(specs, env_id, seeds, steps)
    greedy = {r["seed"]: r["throughput"] for r in rows if r["controller"] == "greedy"}
    out = summarize(rows)
    for s in out:
        mine = [r for r in rows if r["controller"] == s["controller"]]
        s["vs_greedy"] = float(np.mean([r["throughput"] / greedy[r["seed"]] for r in mine]))
        s["wins"] = sum(r["throughput"] > greedy[r["seed"]] for r in mine)
        s["losses"] = sum(r["throughput"] < greedy[r["seed"]] for r in mine)
        print(f"{env_id} {s['controller']:12.12s} throughput {s['throughput']:8.3f}  vs greedy {s['vs_greedy']:.4f} "
              f"({s['wins']} better, {s['losses']} worse)  p99 {1e3 * s['decision_latency_p99_s']:.2f} ms", flush=True)
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--timesteps", type=int, default=150_000, help="training decisions (default 150000)")
    p.add_argument("--seed", type=int, default=0, help="training seed (default 0)")
    p.add_argument("--model", default=None, help="evaluate this model instead of training one")
    p.add_argument("--episodes", type=int, default=16, help="episodes on the small id (default 16)")
    p.add_argument("--steps", type=int, default=500, help="steps per small-id episode (default 500)")
    p.add_argument("--warehouse-episodes", type=int, default=2, help="episodes on the warehouse id (default 2)")
    p.add_argument("--warehouse-steps", type=int, default=200, help="steps per warehouse episode (default 200)")
    p.add_argument("--warehouse-timesteps", type=int, default=1_500_000,
                   help="also train a model on the warehouse id for this many decisions (0: do not; default 1500000)")
    p.add_argument("--no-write", action="store_true", help="do not write RESULTS.md")
    args = p.parse_args(argv)
    t_start = time.perf_counter()
    tmp = tempfile.TemporaryDirectory()
    train_s = None
    if args.model is None:
        from agents.learned.training import TrainOptions, train

        model = str(Path(tmp.name) / "lifelong_ppo.zip")
        t0 = time.perf_counter()
        train(SMALL_ID, args.timesteps, model, options=TrainOptions(seed=args.seed, curve=False))
        train_s = time.perf_counter() - t0
        print(f"trained {args.timesteps} decisions in {train_s:.0f} s", flush=True)
    else:
        model = args.model
    ware_model, ware_s = None, None
    if args.warehouse_timesteps:
        from agents.learned.training import TrainOptions, train

        ware_model = str(Path(tmp.name) / "lifelong_warehouse_ppo.zip")
        t0 = time.perf_counter()
        train(WAREHOUSE_ID, args.warehouse_timesteps, ware_model, options=TrainOptions(seed=args.seed, curve=False))
        ware_s = time.perf_counter() - t0
        print(f"trained {args.warehouse_timesteps} warehouse decisions in {ware_s:.0f} s", flush=True)
    specs = ["greedy", "strong", "ising", f"ppo:{model}"]
    small = _evaluate(SMALL_ID, specs, args.episodes, args.steps)
    ware = _evaluate(WAREHOUSE_ID, specs + ([f"ppo:{ware_model}"] if ware_model else []), args.warehouse_episodes,
                     args.warehouse_steps)
    how = (f"trained in the same run (`mrmt train --env-id {SMALL_ID} --timesteps {args.timesteps} --seed {args.seed}`"
           f", {train_s:.0f} s)" if train_s is not None else f"`{args.model}`")
    if ware_model:
        how += (f"; `ppo (trained on the warehouse)`: `mrmt train --env-id {WAREHOUSE_ID} --timesteps "
                f"{args.warehouse_timesteps} --seed {args.seed}` in the same run ({ware_s:.0f} s)")
    lines = [SECTION, "",
             f"`flock /tmp/mrmt-bench.lock python benchmarks/lifelong_learned.py --timesteps {args.timesteps} "
             f"--seed {args.seed} --episodes {args.episodes} --steps {args.steps} --warehouse-episodes "
             f"{args.warehouse_episodes} --warehouse-steps {args.warehouse_steps} --warehouse-timesteps "
             f"{args.warehouse_timesteps}` on {cpu_name()} (shared machine, "
             f"2 cores, one process). `ppo`: MaskablePPO (`LifelongTaskPolicy`: one shared MLP scores each candidate) choosing each idle robot's next task "
             f"among its 8 nearest unclaimed ones (`agents/lifelong/choice.py`), model {how}; the first model on "
             f"both ids. Every controller moves through PIBT; seeds {FIRST_SEED}.. (not seen in training), the "
             "same worlds and task streams for every controller. `vs greedy`: mean of the per-episode throughput "
             "ratios; better / worse: episodes above / below greedy's throughput. Latency: host (+ chip) time "
             "of one step's decision, inference included.", ""]
    for env_id, rows, eps, steps in ((SMALL_ID, small, args.episodes, args.steps),
                                     (WAREHOUSE_ID, ware, args.warehouse_episodes, args.warehouse_steps)):
        lines += [f"`{env_id}`, {eps} episodes of {steps} steps:", "",
                  "| controller | throughput (tasks/step) | vs greedy | better / worse | service (steps) | "
                  "conflicts | latency p50 (ms) | latency p99 (ms) | paper J / task | total J / task |",
                  "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
        for s in rows:
            name = s["controller"]
            if name.startswith("ppo:"):
                name = "ppo (trained on the warehouse)" if name == f"ppo:{ware_model}" else "ppo"
            lines.append(f"| {name} | {s['throughput']:.3f} | {s['vs_greedy']:.4f} | {s['wins']} / {s['losses']} | "
                         f"{s['service_time_mean']:.2f} | {s['conflicts']} | {1e3 * s['decision_latency_p50_s']:.2f} | "
                         f"{1e3 * s['decision_latency_p99_s']:.2f} | {s['paper_energy_per_task_j']:.2e} | "
                         f"{s['total_energy_per_task_j']:.2e} |")
        lines.append("")
    lines.append(f"Run time {time.perf_counter() - t_start:.0f} s.")
    text = "\n".join(lines) + "\n"
    print(text)
    if not args.no_write:
        write_results_section(SECTION, text)
    tmp.cleanup()
    return 0


if __name__ == "__main__":
    sys.exit(main())
