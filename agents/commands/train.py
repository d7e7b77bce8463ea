"""``mrmt train``: train a learned agent on an MRMT env and save it.

    mrmt train --env-id mrmt_env/MRMT-Assign-v0 --out model.zip          # MaskablePPO, pointer policy
    mrmt train --env-id mrmt_env/MRMT-Lifelong-v0 --out ll.zip            # MaskablePPO: an idle robot's next task
    mrmt train --timesteps 100000 --out model.zip [--env-id mrmt_env/MRMT-5x5-v0] [--algo maskable_ppo]

Writes the model, a ``.json`` sidecar and the training curve; evaluate it with ``mrmt compare --controllers
strong,ppo:model.zip``. Design notes: docs/design/cli.md#mrmt-train.
"""

from __future__ import annotations

import argparse
import sys

NAME = "train"
#: stable-baselines3 seeds numpy's global generator (``np.random.seed``), which takes [0, 2**32 - 1].
MAX_TRAIN_SEED = 2**32 - 1
#: Most envs stepped together.
MAX_N_ENVS = 4096
HELP = "train a learned agent (PPO / MaskablePPO) on an MRMT env and save it"


def add_arguments(parser) -> None:
    parser.add_argument("--timesteps", type=int, default=None,
                        help="total env steps (default: 300000 on the plan-level env, about 6.5 min on 2 cores; "
                             "100000 decisions on a lifelong env; 100000 on a grid env)")
    parser.add_argument("--out", required=True, help="model path (.zip is appended unless it ends in .zip)")
    parser.add_argument("--env-id", default="mrmt_env/MRMT-v0", help="Gymnasium env id (default mrmt_env/MRMT-v0)")
    parser.add_argument("--algo", default=None, choices=("ppo", "maskable_ppo"),
                        help="algorithm (default: maskable_ppo on the plan-level env, ppo on a grid env)")
    parser.add_argument("--policy", default=None, help="SB3 policy on a grid env (default MlpPolicy; CnnPolicy for "
                                                       "--observation image)")
    parser.add_argument("--observation", default=None, choices=("binary", "image"), help="grid env observation form")
    parser.add_argument("--dense-reward", type=float, default=None, help="grid env BFS-progress shaping weight")
    parser.add_argument("--robots", type=int, default=None, help="override the env's robot count")
    parser.add_argument("--targets", type=int, default=None, help="override the env's target count")
    parser.add_argument("--seed", type=int, default=0, help="training seed (default 0)")
    parser.add_argument("--n-envs", type=int, default=None,
                        help="envs stepped together (default 16 plan level, 4 lifelong, 1 grid)")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    parser.add_argument("--progress", action="store_true", help=argparse.SUPPRESS)  # the default; kept for old scripts


def _fail(msg: str) -> int:
    print(f"mrmt train: error: {msg}", file=sys.stderr)
    return 2


def run(args) -> int:
    for name in ("timesteps", "n_envs", "robots", "targets"):
        value = getattr(args, name)
        if value is not None and value < 1:
            return _fail(f"--{name.replace('_', '-')} must be >= 1, got {value}")
    if not 0 <= args.seed <= MAX_TRAIN_SEED:
        return _fail(f"--seed must be in [0, 2**32 - 1] (stable-baselines3 seeds numpy's global generator with it), "
                     f"got {args.seed}")
    if args.n_envs is not None and args.n_envs > MAX_N_ENVS:
        return _fail(f"--n-envs must be <= {MAX_N_ENVS}, got {args.n_envs}")
    try:
        import sb3_contrib  # noqa: F401
        import stable_baselines3  # noqa: F401
    except ImportError as exc:
        return _fail(f"training needs the rl extra ({exc.name} is not installed): pip install 'mrmt-ising[rl]'")
    from agents.learned.training import TrainOptions, curve_paths, model_path, sidecar_path, train

    env_kwargs = {}
    for key, value in (("n_robots", args.robots), ("n_targets", args.targets), ("observation", args.observation),
                       ("dense_reward", args.dense_reward)):
        if value is not None:
            env_kwargs[key] = value
    try:
        options = TrainOptions(algo=args.algo, policy=args.policy, seed=args.seed, n_envs=args.n_envs,
                               progress=not args.no_progress)
        train(args.env_id, args.timesteps, out=args.out, options=options, env_kwargs=env_kwargs)
    except (ValueError, TypeError) as exc:
        return _fail(str(exc))
    zpath = model_path(args.out)
    written = [str(p) for p in (zpath, sidecar_path(zpath), *curve_paths(zpath)) if p.exists()]
    print(f"wrote {', '.join(written[:-1])} and {written[-1]}" if len(written) > 1 else f"wrote {written[0]}")
    return 0
