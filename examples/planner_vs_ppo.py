"""Planners versus a learned allocator on the same worlds, scored by one evaluator.

Trains sb3-contrib MaskablePPO (pointer policy) briefly on the plan-level env
``mrmt_env/MRMT-Assign-v0`` (the paper's 10x10 world, 3 robots, 10 targets:
an idle robot picks its next target), then runs the strong classical
pipeline, the Ising pipeline and the learned agent on the same unseen worlds
and prints the evaluator's table (route cost, success, latency, energy).
``mrmt train --env-id mrmt_env/MRMT-Assign-v0``'s default budget (300k steps,
a few minutes) brings the learned route cost within a few percent of the
strong pipeline's (benchmarks/RESULTS.md); this example's 20k steps get
within about 10 %.

    python examples/planner_vs_ppo.py [--timesteps 20000] [--worlds 20]
"""

import argparse
import tempfile
from pathlib import Path

from agents.evaluation import evaluate
from agents.learned.training import ASSIGN_ENV_ID, TrainOptions, train
from agents.runner import RunConfig


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timesteps", type=int, default=20000, help="MaskablePPO training steps")
    parser.add_argument("--worlds", type=int, default=20, help="evaluation worlds")
    parser.add_argument("--jobs", type=int, default=2, help="evaluation worker processes")
    args = parser.parse_args(argv)

    with tempfile.TemporaryDirectory() as tmp:
        model = Path(tmp) / "ppo_small.zip"
        print(f"training MaskablePPO for {args.timesteps} steps on {ASSIGN_ENV_ID} ...")
        train(ASSIGN_ENV_ID, args.timesteps, out=model, options=TrainOptions(seed=0))
        # unseen worlds: training draws worlds from seed 0's stream, evaluation uses seeds 10_000+
        result = evaluate(
            ["strong", "ising", f"ppo:{model}"],
            n_worlds=args.worlds,
            world_seed=10_000,
            env_id=ASSIGN_ENV_ID,
            run=RunConfig.from_jobs(args.jobs),
        )
    print(result.format_summary())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
