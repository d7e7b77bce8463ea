"""Load a MovingAI benchmark map and plan on it.

Reads ``examples/data/warehouse.map`` (a 12x16 warehouse with shelves, in
the MovingAI ``.map`` format: ``type``/``height``/``width``/``map`` header,
``.`` free, ``@``/``T`` blocked) and its ``.scen`` file (robot ``k`` starts at
scenario ``k``'s start; the targets are the scenarios' goals), builds a fixed
world, and drives the Gymnasium env with a planner -- the same loop works on
any MovingAI map (https://movingai.com/benchmarks/).

    python examples/movingai_map.py [--robots 3] [--targets 8] [--pipeline strong]
"""

import argparse
from pathlib import Path

from agents.policy import PlannerPolicy
from mrmt_env.grid.env import MRMTEnv
from mrmt_env.movingai import read_movingai_map, read_movingai_scen, world_from_movingai

DATA = Path(__file__).resolve().parent / "data"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--map", default=str(DATA / "warehouse.map"), help="MovingAI .map file")
    parser.add_argument("--scen", default=str(DATA / "warehouse.scen"), help="MovingAI .scen file")
    parser.add_argument("--robots", type=int, default=3)
    parser.add_argument("--targets", type=int, default=8)
    parser.add_argument("--pipeline", default="strong", help="planner preset: fast, strong or ising")
    args = parser.parse_args(argv)

    grid = read_movingai_map(args.map)
    for s in read_movingai_scen(args.scen)[: args.targets]:
        print(f"scenario {s.start} -> {s.goal}: 4-neighbour shortest path {s.bfs_length(grid)} moves")
    world = world_from_movingai(args.map, args.scen, n_robots=args.robots, n_targets=args.targets)
    env = MRMTEnv(world=world, max_episode_steps=4 * world.height * world.width, render_mode="ansi")
    policy = PlannerPolicy(args.pipeline, seed=0)

    obs, info = env.reset(seed=0)
    print(env.render())
    done, start = False, True
    while not done:
        action, _ = policy.predict(obs, episode_start=start)
        start = False
        obs, _, terminated, truncated, info = env.step(action)
        done = terminated or truncated
    print(env.render())
    plan = policy.episode_plans()[0]
    print(f"{world.height}x{world.width} map, {world.n_robots} robots, {world.n_targets} targets, "
          f"pipeline {args.pipeline}: success={info['is_success']} route_cost={info['route_cost']} "
          f"(plan {plan.route_cost}) makespan={info['makespan']}, planning CPU {1e3 * plan.compute.cpu_s:.2f} ms, "
          f"chip calls {plan.compute.chip_calls}")
    return 0 if info["is_success"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
