"""A League of Robot Runners instance in the Gymnasium loop: the env's scheduler assigns tasks,
PIBT with turning moves the robots, and the run is written in the competition's output format.

    python examples/lorr_instance.py                       # the small instance shipped with the package
    python examples/lorr_instance.py path/to/RANDOM-01.json --steps 600
"""

from __future__ import annotations

import argparse

import gymnasium as gym

import mrmt_env  # noqa: F401  (registers the ids)
from mrmt_env.lorr.output import write_output
from planners.mapf import make_turning_planner


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("instance", nargs="?", default=None, help="a LoRR instance JSON (default: the shipped one)")
    p.add_argument("--steps", type=int, default=None, help="steps (default: the instance's simulation time)")
    p.add_argument("--out", default=None, help="write the start kit's output file here")
    args = p.parse_args()
    env = gym.make("mrmt_env/LoRR-v0", instance=args.instance, steps=args.steps)  # scheduler: the start kit's greedy
    obs, info = env.reset(seed=0)
    executor = make_turning_planner("pibt", env.unwrapped.instance.grid, seed=0)
    done = False
    while not done:
        goals = obs["goal"].copy()
        idle = goals < 0
        goals[idle] = obs["position"][idle]  # a robot without a task holds its cell
        obs, reward, terminated, truncated, info = env.step(executor.actions(obs["position"], obs["orientation"], goals))
        done = terminated or truncated
    inst = env.unwrapped.instance
    print(f"{inst.name}: {info['tasks_finished']} tasks finished in {info['step']} steps by {inst.team_size} robots, "
          f"{info['errands_reached']} errands, {info['errors']} invalid joint actions")
    if args.out:
        print("wrote", write_output(env.unwrapped.sim, args.out))


if __name__ == "__main__":
    main()
