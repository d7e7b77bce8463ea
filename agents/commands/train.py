"""``mrmt train``: train a PPO agent (stable-baselines3) on the MRMT env.

    mrmt train --timesteps 100000 --out model.zip [--env-id mrmt_env/MRMT-5x5-v0] [--seed 0]

Writes the model ``.zip`` and a ``.json`` sidecar (env id, kwargs, seed,
timesteps, training wall time).  Evaluate it with
``mrmt compare --controllers strong,ppo:model.zip`` on the same world size
and robot count.
"""

from __future__ import annotations

import sys

NAME = "train"
HELP = "train a PPO agent (stable-baselines3) on the MRMT env and save it"


def add_arguments(parser) -> None:
    parser.add_argument("--timesteps", type=int, required=True, help="total env steps of training")
    parser.add_argument("--out", required=True, help="model path (.zip)")
    parser.add_argument("--env-id", default="mrmt_env/MRMT-v0", help="Gymnasium env id (default mrmt_env/MRMT-v0)")
    parser.add_argument("--robots", type=int, default=None, help="override the env's robot count")
    parser.add_argument("--targets", type=int, default=None, help="override the env's target count")
    parser.add_argument("--seed", type=int, default=0, help="training seed (default 0)")
    parser.add_argument("--n-envs", type=int, default=1, help="parallel envs in the rollout (default 1)")
    parser.add_argument("--progress", action="store_true", help="show SB3's progress bar")


def run(args) -> int:
    if args.timesteps < 1:
        print(f"mrmt train: error: --timesteps must be >= 1, got {args.timesteps}", file=sys.stderr)
        return 2
    try:
        from agents.learned import train_ppo
    except ImportError as exc:  # pragma: no cover
        print(f"mrmt train: error: {exc}", file=sys.stderr)
        return 2
    env_kwargs = {}
    if args.robots is not None:
        env_kwargs["n_robots"] = args.robots
    if args.targets is not None:
        env_kwargs["n_targets"] = args.targets
    try:
        import stable_baselines3  # noqa: F401
    except ImportError:
        print("mrmt train: error: stable-baselines3 is not installed (pip install 'mrmt-ising[rl]')", file=sys.stderr)
        return 2
    try:
        train_ppo(
            args.timesteps,
            out=args.out,
            env_id=args.env_id,
            env_kwargs=env_kwargs,
            seed=args.seed,
            n_envs=args.n_envs,
            progress=args.progress,
        )
    except (ValueError, TypeError) as exc:
        print(f"mrmt train: error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {args.out}")
    return 0
