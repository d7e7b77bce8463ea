"""Quickstart: one episode of the MRMT Gymnasium env driven by the Ising planner.

The planner policy rebuilds the world from the observation, plans once with
the Ising pipeline (Ising target sharing and tours on the emulated 45-spin chip,
legs along the BFS fields the host already holds; ``ising-paper`` adds the
paper's patch-sliding chip paths), then emits one joint move per step.  The opt-in wrapper adds the episode's compute, latency
and energy to ``info`` when the episode ends.

    python examples/quickstart.py [--seed 0] [--pipeline ising|strong|fast]
"""

import argparse

import gymnasium as gym

import mrmt_env  # noqa: F401  (registers mrmt_env/MRMT-v0)
from agents.policy import PlannerPolicy
from agents.wrappers import ComputeInfoWrapper


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0, help="world seed")
    parser.add_argument("--pipeline", default="ising", help="planner preset: ising, strong or fast")
    args = parser.parse_args(argv)

    policy = PlannerPolicy(args.pipeline, seed=args.seed)
    env = ComputeInfoWrapper(gym.make("mrmt_env/MRMT-v0", render_mode="ansi"), controller=policy)

    obs, info = env.reset(seed=args.seed)
    print(env.render())
    done, start = False, True
    while not done:
        action, _ = policy.predict(obs, episode_start=start)
        start = False
        obs, reward, terminated, truncated, info = env.step(action)
        done = terminated or truncated
    print(env.render())

    plan = policy.episode_plans()[0]
    print(f"pipeline {args.pipeline}: success={info['is_success']} route_cost={info['route_cost']} "
          f"(plan: {plan.route_cost}) makespan={info['makespan']} steps={info['steps']}")
    print(f"chip calls {info['chip_calls']} (+{info['logical_calls']} projected logical), "
          f"chip time {1e3 * info['chip_time_s']:.2f} ms sequential / {1e3 * info['chip_time_parallel_s']:.2f} ms on 8 cores")
    print(f"accelerator energy {1e6 * info['accelerator_energy_j']:.1f} uJ, host CPU {1e3 * info['host_cpu_s']:.2f} ms "
          f"= {1e3 * info['host_energy_j']:.1f} mJ at 15 W")
    print(f"(one-off warm-up before the first plan, kernel compile or cache load, not counted above: "
          f"{info['warmup_s']:.2f} s)")
    return 0 if info["is_success"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
