"""Watch a planner and a learned agent on the same world: two GIFs.

Trains a MaskablePPO allocator briefly on the plan-level env
``mrmt_env/MRMT-Assign-v0`` (the default budget of ``mrmt train`` is
300k steps; a few thousand already give a usable agent), then writes one GIF
of the strong pipeline and one of the learned agent on the same unseen world.
Robots are coloured squares; each route is solid where driven and faint
where still to go.

    python examples/watch_episode.py [--timesteps 20000] [--seed 10000] [--out DIR]

Without ``--out`` the GIFs go to a new temporary directory (printed), never into the
working tree.
"""

import argparse
import tempfile
from pathlib import Path

from agents.animation import episode_frames, write_gif
from agents.learned.training import ASSIGN_ENV_ID, TrainOptions, train


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timesteps", type=int, default=20000, help="MaskablePPO training steps")
    parser.add_argument("--seed", type=int, default=10_000, help="world (reset) seed of the episode")
    parser.add_argument("--out", default=None, help="directory for the GIFs (default: a new temporary directory)")
    args = parser.parse_args(argv)

    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="mrmt-episodes-"))
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        model = Path(tmp) / "allocator.zip"
        print(f"training MaskablePPO for {args.timesteps} steps on {ASSIGN_ENV_ID} ...")
        train(ASSIGN_ENV_ID, args.timesteps, out=model, options=TrainOptions(seed=0))
        for name, controller in (("strong", "strong"), ("learned", f"ppo:{model}")):
            frames, info = episode_frames(controller, ASSIGN_ENV_ID, seed=args.seed)
            path = out / f"{name}.gif"
            write_gif(frames, path)
            print(f"{name}: route cost {info['route_cost']}, makespan {info['makespan']} -> {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
