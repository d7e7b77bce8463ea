"""Lifelong operation: a warehouse fleet serving a task stream, collision-free through PIBT.

    python examples/lifelong_warehouse.py --robots 100 --steps 200
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym

import mrmt_env  # noqa: F401  (registers the ids)
from agents.lifelong.controllers import make_lifelong_controller


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--robots", type=int, default=100)
    p.add_argument("--steps", type=int, default=200)
    p.add_argument("--size", type=int, default=64, help="warehouse side (default 64)")
    p.add_argument("--controllers", default="greedy,strong,ising")
    args = p.parse_args()
    for spec in args.controllers.split(","):
        env = gym.make("mrmt_env/MRMT-Lifelong-Warehouse-v0", height=args.size, width=args.size,
                       n_robots=args.robots, n_targets=3 * args.robots // 2, max_episode_steps=args.steps)
        obs, info = env.reset(seed=0)
        controller = make_lifelong_controller(spec, seed=0)  # executor: PIBT
        chip_calls, t0 = 0, time.perf_counter()
        for _ in range(args.steps):
            obs, reward, terminated, truncated, info = env.step(controller.act(obs))
            chip_calls += controller.last_compute.chip_calls + controller.last_compute.logical_calls
            if truncated:
                break
        print(f"{spec:>7}: {info['tasks_completed']} tasks in {info['steps']} steps, throughput "
              f"{info['throughput']:.2f}/step, service {info['service_time_mean']:.1f} steps, conflicts "
              f"{info['conflicts']}, blocked {info['blocked_moves']}, chip calls {chip_calls}, "
              f"wall {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
