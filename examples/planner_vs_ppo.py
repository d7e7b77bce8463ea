"""Planners versus a learned agent (PPO) on the same worlds, scored by one evaluator.

Trains PPO (stable-baselines3) briefly on the small registered world
``mrmt_env/MRMT-5x5-v0`` (2 robots, 3 targets), then runs the strong
classical pipeline, the Ising pipeline and the PPO agent on the same unseen
worlds and prints the evaluator's table (route cost, success, latency, energy).
A few thousand steps of PPO do not solve the task; see benchmarks/RESULTS.md
for what longer training reaches.

    python examples/planner_vs_ppo.py [--timesteps 20000] [--worlds 20]
"""

import argparse
import tempfile
from pathlib import Path

from agents.evaluation import evaluate
from agents.learned import SMALL_ENV_ID, train_ppo


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timesteps", type=int, default=20000, help="PPO training steps")
    parser.add_argument("--worlds", type=int, default=20, help="evaluation worlds")
    parser.add_argument("--jobs", type=int, default=2, help="evaluation worker processes")
    args = parser.parse_args(argv)

    with tempfile.TemporaryDirectory() as tmp:
        model = Path(tmp) / "ppo_small.zip"
        print(f"training PPO for {args.timesteps} steps on {SMALL_ENV_ID} ...")
        train_ppo(args.timesteps, out=model, env_id=SMALL_ENV_ID, seed=0)
        # unseen worlds: training draws worlds from seed 0's stream, evaluation uses seeds 10_000+
        result = evaluate(
            ["strong", "ising", f"ppo:{model}"],
            n_worlds=args.worlds,
            world_seed=10_000,
            env_id=SMALL_ENV_ID,
            n_jobs=args.jobs,
        )
    print(result.format_summary())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
