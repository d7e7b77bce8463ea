"""``mrmt watch``: one episode of a planner or learned agent as a GIF.

    mrmt watch --controller strong --env-id mrmt_env/MRMT-Assign-v0 --seed 3 --out episode.gif
    mrmt watch --controller ppo:model.zip --env-id mrmt_env/MRMT-Assign-v0 --out learned.gif

Robots are coloured squares, targets gold rings (pale green once visited);
each robot's route is drawn in its colour: solid where it has driven, faint
where its plan (or, in the plan-level env, its committed decisions) still
goes.  Needs imageio (``pip install 'mrmt-ising[viz]'``).
"""

from __future__ import annotations

import os
import sys

NAME = "watch"
HELP = "write one episode of a planner or learned agent as a GIF"


def add_arguments(parser) -> None:
    parser.add_argument("--controller", default="strong",
                        help="fast, strong, ising, sharing+tour+path or ppo:MODEL.zip (default strong)")
    parser.add_argument("--env-id", default="mrmt_env/MRMT-v0", help="Gymnasium env id (default mrmt_env/MRMT-v0)")
    parser.add_argument("--seed", type=int, default=0, help="world (reset) seed (default 0)")
    parser.add_argument("--out", required=True, help="GIF path (must end in .gif)")
    parser.add_argument("--fps", type=float, default=4.0, help="frames per second (default 4)")
    parser.add_argument("--cell", type=int, default=24, help="pixels per grid cell (default 24)")
    parser.add_argument("--steps", type=int, default=100,
                        help="steps drawn of a lifelong episode (lifelong ids only; default 100)")


def run(args) -> int:
    def fail(msg: str) -> int:
        print(f"mrmt watch: error: {msg}", file=sys.stderr)
        return 2

    if args.seed < 0:
        return fail(f"--seed must be >= 0, got {args.seed}")
    if not args.fps > 0:
        return fail(f"--fps must be > 0, got {args.fps}")
    if not args.out.lower().endswith(".gif"):  # an animation is a GIF; GIF bytes under another suffix mislead
        return fail(f"--out {args.out!r} must end in .gif (the episode is written as an animated GIF)")
    try:
        import imageio  # noqa: F401
    except ImportError:
        return fail("writing a GIF needs imageio: pip install 'mrmt-ising[viz]'")
    from agents.lifelong.evaluation import is_lifelong_id

    if is_lifelong_id(args.env_id):  # a task stream: greedy / pipelines through PIBT (agents.lifelong.watch)
        from agents.animation import write_gif
        from agents.lifelong.watch import lifelong_frames

        try:
            frames, info = lifelong_frames(args.controller, args.env_id, seed=args.seed, steps=args.steps,
                                           cell=args.cell)
            write_gif(frames, args.out, fps=args.fps)
        except (ValueError, OSError) as exc:
            return fail(" ".join(str(exc).split()))
        print(f"wrote {args.out}: {len(frames)} frames, tasks_completed {info['tasks_completed']}, "
              f"conflicts {info['conflicts']}")
        return 0
    from agents.animation import episode_frames, write_gif
    from agents.evaluation import ControllerError, validate_controller_spec

    try:
        validate_controller_spec(args.controller)
        from agents.warmup import warm

        warm([args.controller], jobs=min(2, os.cpu_count() or 1), progress=False)  # a cold install only
        frames, info = episode_frames(args.controller, args.env_id, seed=args.seed, cell=args.cell)
        write_gif(frames, args.out, fps=args.fps)
    except (ControllerError, ValueError, OSError) as exc:
        return fail(str(exc))
    print(f"wrote {args.out}: {len(frames)} frames, route_cost {info['route_cost']}, makespan {info['makespan']}, "
          f"success {bool(info['is_success'])}")
    return 0
