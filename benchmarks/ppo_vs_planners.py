"""How far does plain PPO on the grid env get against the planners?  (Issue 6's baseline.)

Trains stable-baselines3 PPO (MlpPolicy, SB3 defaults, no masks, sparse
reward; see agents/learned/training.py) on a grid env id for ``--timesteps`` steps,
then evaluates it with the planners on the same *unseen* worlds (reset seeds
10_000 + i) through the evaluation runner, and prints the table plus a JSON
line.  The learnable set-ups are benchmarks/grid_ppo.py (masks, dense
reward, CNN) and benchmarks/learned_vs_planners.py (the plan-level env).

    flock /tmp/mrmt-bench.lock python benchmarks/ppo_vs_planners.py \
        --env-id mrmt_env/MRMT-5x5-v0 --timesteps 100000 --model results/ppo/ppo_5x5.zip
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from agents.evaluation import evaluate
from agents.runner import RunConfig
from agents.learned.training import train_ppo


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env-id", default="mrmt_env/MRMT-5x5-v0")
    p.add_argument("--timesteps", type=int, default=100_000)
    p.add_argument("--model", default="results/ppo/ppo.zip")
    p.add_argument("--skip-train", action="store_true", help="evaluate an existing --model")
    p.add_argument("--worlds", type=int, default=100)
    p.add_argument("--controllers", default="fast,strong,ising")
    p.add_argument("--jobs", type=int, default=2)
    args = p.parse_args(argv)

    train_s = None
    if not args.skip_train:
        t0 = time.perf_counter()
        train_ppo(args.timesteps, out=args.model, env_id=args.env_id, seed=0)
        train_s = time.perf_counter() - t0
        print(f"trained {args.timesteps} steps on {args.env_id} in {train_s:.0f} s -> {args.model}")
    specs = [s for s in args.controllers.split(",") if s] + [f"ppo:{args.model}"]
    res = evaluate(specs, n_worlds=args.worlds, world_seed=10_000, env_id=args.env_id,
                   run=RunConfig.from_jobs(args.jobs))
    print(res.format_summary())
    ppo_rows = res.by_controller(f"ppo:{args.model}")
    out = {
        "env_id": args.env_id,
        "timesteps": args.timesteps,
        "train_s": train_s,
        "worlds": args.worlds,
        "summary": res.summary(),
        "ppo_mean_targets_visited": sum(r["targets_visited"] for r in ppo_rows) / len(ppo_rows),
        "ppo_mean_steps": sum(r["steps"] for r in ppo_rows) / len(ppo_rows),
    }
    strong = {r["world_seed"]: r for r in res.by_controller("strong")} if "strong" in specs else {}
    paired = [r["route_cost"] - strong[r["world_seed"]]["route_cost"] for r in ppo_rows
              if r["is_success"] and r["world_seed"] in strong and strong[r["world_seed"]]["is_success"]]
    if paired:
        import numpy as np

        out["ppo_minus_strong_cost_on_ppo_successes"] = {
            "n": len(paired), "median": float(np.median(paired)), "mean": float(np.mean(paired)),
        }
    print(json.dumps(out, default=float))
    Path(args.model).with_suffix(".eval.json").write_text(json.dumps(out, indent=1, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
