"""Grid-level learning on the paper's 10x10 world: MaskablePPO with masks, dense reward, MLP or CNN.

Trains sb3-contrib MaskablePPO on ``mrmt_env/MRMT-v0`` (3 robots, 10
targets) with action masks for blocked moves and the BFS-progress dense
reward, either ``MlpPolicy`` on the binary channels or ``CnnPolicy`` on the
image observation, then scores it with the strong planner on unseen worlds
(reset seeds 10_000 + i) through the evaluation runner (greedy actions), and
once more with actions sampled from the policy (seeded); writes its RESULTS.md
row (section "Issue 11: grid-level PPO").

    flock /tmp/mrmt-bench.lock python benchmarks/grid_ppo.py --policy cnn --timesteps 1000000
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, cpu_name, write_results_section  # noqa: E402

ENV_ID = "mrmt_env/MRMT-v0"
SECTION = "## Issue 11: grid-level PPO on the paper's 10x10 world"
HYPER = dict(n_steps=256, batch_size=512, n_epochs=4, learning_rate=3e-4, gamma=0.99, gae_lambda=0.95, ent_coef=0.01)


def _sampled(model_path, worlds: int) -> tuple[float, float]:
    """Success rate and mean share of targets visited with actions sampled from the policy (seeded)."""
    import gymnasium as gym

    from agents.learned.training import load_policy

    policy = load_policy(model_path)
    policy.model.set_random_seed(0)
    env = gym.make(ENV_ID)
    ok, frac = [], []
    for i in range(worlds):
        obs, info = env.reset(seed=10_000 + i)
        done = False
        while not done:
            action, _ = policy.predict(obs, deterministic=False, action_masks=env.unwrapped.action_masks())
            obs, _, term, trunc, info = env.step(action)
            done = term or trunc
        ok.append(bool(info["is_success"]))
        frac.append(info["targets_visited"] / info["n_targets"])
    return float(np.mean(ok)), float(np.mean(frac))


def main(argv=None) -> int:
    from agents.evaluation import evaluate
    from agents.learned.training import TrainOptions, train
    from agents.runner import RunConfig

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--policy", choices=("mlp", "cnn"), default="cnn")
    p.add_argument("--timesteps", type=int, default=1_000_000)
    p.add_argument("--dense-reward", type=float, default=1.0)
    p.add_argument("--n-envs", type=int, default=16)
    p.add_argument("--worlds", type=int, default=100)
    p.add_argument("--out", default="results/grid_ppo")
    p.add_argument("--no-results", action="store_true")
    p.add_argument("--skip-train", action="store_true", help="evaluate the model already in --out (train_s from its sidecar)")
    args = p.parse_args(argv)

    env_kwargs = {"dense_reward": args.dense_reward}
    if args.policy == "cnn":
        env_kwargs["observation"] = "image"
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    model = out / f"grid_{args.policy}.zip"
    if args.skip_train:
        meta = json.loads(model.with_suffix(".json").read_text())
        train_s, args.timesteps = meta["train_wall_s"], meta["timesteps"]
    else:
        t0 = time.perf_counter()
        options = TrainOptions(algo="maskable_ppo", n_envs=args.n_envs, seed=0, reward_scale=0.01)
        train(ENV_ID, args.timesteps, out=model, options=options, env_kwargs=env_kwargs, **HYPER)
        train_s = time.perf_counter() - t0
    print(f"trained {args.timesteps} steps in {train_s:.0f} s")
    res = evaluate(["strong", f"ppo:{model}"], n_worlds=args.worlds, world_seed=10_000, env_id=ENV_ID,
                   run=RunConfig.from_jobs(2, progress=False))
    print(res.format_summary())
    rows = res.by_controller(f"ppo:{model}")
    sampled_success, sampled_frac = _sampled(model, args.worlds)
    record = {
        "policy": args.policy, "timesteps": args.timesteps, "train_s": train_s, "dense_reward": args.dense_reward,
        "success_rate": float(np.mean([r["is_success"] for r in rows])),
        "targets_visited_frac": float(np.mean([r["targets_visited"] / r["n_targets"] for r in rows])),
        "median_route_cost_success": float(np.median([r["route_cost"] for r in rows if r["is_success"]]))
        if any(r["is_success"] for r in rows) else None,
        "strong_median_route_cost": res.summary()[0]["route_cost"],
        "sampled_success_rate": sampled_success, "sampled_targets_visited_frac": sampled_frac,
    }
    (out / f"grid_{args.policy}.eval.json").write_text(json.dumps(record, indent=1))  # beside the sidecar
    print(json.dumps(record))
    if not args.no_results:
        head = [
            SECTION, "",
            "MaskablePPO (sb3-contrib), action masks for blocked moves, dense reward (BFS progress, weight "
            f"{args.dense_reward}), rewards x 0.01, {args.n_envs} envs of the native vector env, hyper-parameters "
            f"{HYPER}; evaluated on {args.worlds} unseen worlds (reset seeds 10000..). {cpu_name()}, 2 shared cores. "
            "Command: `python benchmarks/grid_ppo.py --policy P --timesteps N`.", "",
            "Greedy = the evaluation runner (deterministic actions); sampled = actions drawn from the policy.", "",
            "| policy | env steps | train time | success greedy / sampled | targets visited greedy / sampled "
            "| median cost (greedy successes) | strong |",
            "|---|---:|---:|---:|---:|---:|---:|",
        ]
        cost = "-" if record["median_route_cost_success"] is None else f"{record['median_route_cost_success']:.1f}"
        row = (f"| {args.policy} | {args.timesteps} | {train_s / 60:.1f} min | {100 * record['success_rate']:.0f} % / "
               f"{100 * sampled_success:.0f} % | {100 * record['targets_visited_frac']:.0f} % / {100 * sampled_frac:.0f} % "
               f"| {cost} | {record['strong_median_route_cost']:.1f} |")
        text = RESULTS.read_text() if RESULTS.exists() else ""
        m = re.search(re.escape(SECTION) + r"\n.*?(?=^## |\Z)", text, re.S | re.M)
        old_rows = [ln for ln in (m.group(0).splitlines() if m else []) if ln.startswith("| ") and
                    ln.count("|") == 8 and "/" in ln and not ln.startswith("| policy")
                    and not ln.startswith(f"| {args.policy} | {args.timesteps} |")]
        write_results_section(SECTION, "\n".join(head + old_rows + [row]) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
