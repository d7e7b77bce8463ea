"""Learned allocator (MaskablePPO, pointer policy) against the planners on the plan-level env.

Trains with ``mrmt train``'s defaults on ``mrmt_env/MRMT-Assign-v0`` (worlds
drawn from the training seed's stream), evaluates the model at checkpoints on
*unseen* worlds (reset seeds 10_000 + i) and, at the end, runs the model and
the planners (fast, strong, Ising, exact = exact min-sum sharing + Held-Karp
tours) through the evaluation runner on the same unseen worlds.  Writes the
figure (success and route cost against training steps, planners as reference
lines), a JSON file and the RESULTS.md section.

    flock /tmp/mrmt-bench.lock python benchmarks/learned_vs_planners.py [--timesteps N] [--out results/learned]
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import cpu_name, write_results_section  # noqa: E402

ENV_ID = "mrmt_env/MRMT-Assign-v0"
UNSEEN = 10_000
PLANNERS = ("fast", "strong", "ising", "exact+brute+astar")
FIGURE = Path(__file__).resolve().parent.parent / "docs" / "learned" / "fig_learned_vs_planners.png"


def _episodes(model, seeds) -> tuple[float, float, float]:
    """Success rate, median and mean route cost of the model on reset seeds ``seeds`` (deterministic)."""
    import gymnasium as gym

    env = gym.make(ENV_ID)
    costs, ok = [], []
    for s in seeds:
        obs, info = env.reset(seed=int(s))
        done = False
        while not done:
            action, _ = model.predict(obs, action_masks=info["action_mask"], deterministic=True)
            obs, _, term, trunc, info = env.step(int(action))
            done = term or trunc
        ok.append(bool(info["is_success"]))
        if info["is_success"]:
            costs.append(info["route_cost"])
    return float(np.mean(ok)), float(np.median(costs)) if costs else float("nan"), float(np.mean(costs)) if costs else float("nan")


def _checkpoint_callback(every: int, seeds):
    from stable_baselines3.common.callbacks import BaseCallback

    class Checkpoints(BaseCallback):
        def __init__(self):
            super().__init__()
            self.rows, self.eval_s, self.next, self.t0 = [], 0.0, every, None

        def _on_training_start(self) -> None:
            self.t0 = time.perf_counter()

        def _on_step(self) -> bool:
            if self.num_timesteps >= self.next:
                self.next += every
                t = time.perf_counter()
                success, med, mean = _episodes(self.model, seeds)
                self.eval_s += time.perf_counter() - t
                self.rows.append({"timesteps": int(self.num_timesteps),
                                  "train_s": time.perf_counter() - self.t0 - self.eval_s,
                                  "success_rate": success, "median_route_cost": med, "mean_route_cost": mean})
            return True

    return Checkpoints()


def _figure(rows, refs, path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = [r["timesteps"] for r in rows]
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.6))
    a.plot(t, [100 * r["success_rate"] for r in rows], "o-", label="MaskablePPO (pointer)")
    b.plot(t, [r["mean_route_cost"] for r in rows], "o-", label="MaskablePPO (pointer)")
    b.plot(t, [r["median_route_cost"] for r in rows], "s", ms=3, alpha=0.5, color="tab:blue",
           label="MaskablePPO, median")
    colours = {"fast": "tab:gray", "strong": "tab:green", "ising": "tab:purple", "exact+brute+astar": "black"}
    styles = {"fast": ":", "strong": "--", "ising": "-.", "exact+brute+astar": ":"}
    for name, ref in refs.items():
        a.axhline(100 * ref["success_rate"], color=colours.get(name), ls=styles.get(name), lw=1)
        b.axhline(ref["mean_route_cost"], color=colours.get(name), ls=styles.get(name), lw=1.2,
                  label=f"{name}: {ref['mean_route_cost']:.2f}")
    a.set_ylim(-2, 102)
    a.set_ylabel("success on unseen worlds (%)")
    b.set_ylabel("mean route cost on unseen worlds")
    for ax in (a, b):
        ax.set_xlabel("training env steps")
        ax.grid(alpha=0.3)
    b.legend(fontsize=7)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    from agents.evaluation import evaluate
    from agents.learned.training import DEFAULT_TIMESTEPS, TrainOptions, train
    from agents.runner import RunConfig

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--timesteps", type=int, default=DEFAULT_TIMESTEPS["assign"])
    p.add_argument("--checkpoints", type=int, default=10)
    p.add_argument("--curve-worlds", type=int, default=100, help="unseen worlds per checkpoint")
    p.add_argument("--worlds", type=int, default=200, help="unseen worlds of the final comparison")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="results/learned")
    p.add_argument("--figure", default=str(FIGURE))
    p.add_argument("--no-results", action="store_true", help="do not write RESULTS.md")
    args = p.parse_args(argv)

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    model_path = out / "assign_model.zip"
    curve_seeds = range(UNSEEN, UNSEEN + args.curve_worlds)
    cb = _checkpoint_callback(max(1, args.timesteps // args.checkpoints), curve_seeds)
    t0 = time.perf_counter()
    train(ENV_ID, args.timesteps, out=model_path, options=TrainOptions(seed=args.seed), callback=cb)
    wall = time.perf_counter() - t0
    train_s = wall - cb.eval_s
    print(f"trained {args.timesteps} steps in {train_s:.0f} s (+{cb.eval_s:.0f} s of checkpoint evaluation)")

    res = evaluate(list(PLANNERS) + [f"ppo:{model_path}", f"ppo-ms:{model_path}"], n_worlds=args.worlds,
                   world_seed=UNSEEN, env_id=ENV_ID, run=RunConfig.from_jobs(2, progress=False))
    print(res.format_summary())
    summary = {s["controller"]: s for s in res.summary()}
    ppo_name, ms_name = f"ppo:{model_path}", f"ppo-ms:{model_path}"
    by = {name: {r["world_seed"]: r for r in res.by_controller(name)} for name in summary}

    def per_world(name):
        return [by[name][w]["route_cost"] / by["strong"][w]["route_cost"] for w in by["strong"]
                if by[name][w]["is_success"] and by["strong"][w]["route_cost"] > 0]

    ratios, ms_ratios = per_world(ppo_name), per_world(ms_name)
    refs_curve = evaluate(list(PLANNERS), n_worlds=args.curve_worlds, world_seed=UNSEEN, env_id=ENV_ID,
                          run=RunConfig.from_jobs(2, progress=False))
    refs = {s["controller"]: dict(s, mean_route_cost=float(np.mean(
        [r["route_cost"] for r in refs_curve.by_controller(s["controller"]) if r["is_success"]])))
        for s in refs_curve.summary()}
    title = (f"MaskablePPO + pointer policy on {ENV_ID} (3 robots, 10 targets, 10x10); "
             f"{args.curve_worlds} unseen worlds per checkpoint")
    _figure(cb.rows, refs, Path(args.figure), title)

    record = {
        "env_id": ENV_ID, "timesteps": args.timesteps, "seed": args.seed, "train_s": train_s,
        "cpu": cpu_name(), "python": platform.python_version(), "checkpoints": cb.rows,
        "final": {k: {kk: v[kk] for kk in ("episodes", "success_rate", "route_cost", "route_cost_all", "host_cpu_s")}
                  for k, v in summary.items()},
        "ppo_over_strong_per_world": {"median": float(np.median(ratios)), "mean": float(np.mean(ratios))},
        "ppo_ms_over_strong_per_world": {"median": float(np.median(ms_ratios)), "mean": float(np.mean(ms_ratios))},
    }
    (out / "learned_vs_planners.json").write_text(json.dumps(record, indent=1, default=float))
    print(json.dumps(record["final"], default=float))
    if not args.no_results:
        strong = summary["strong"]["route_cost"]
        lines = [
            "## Issue 11: learned allocator against the planners (plan-level env)",
            "",
            f"`python benchmarks/learned_vs_planners.py` (defaults: `mrmt train --env-id {ENV_ID}`'s budget of "
            f"{args.timesteps} steps, seed {args.seed}); {cpu_name()}, 2 cores shared with other work, torch 1 thread.",
            f"Training took **{train_s / 60:.1f} min** (checkpoint evaluations excluded). Final comparison on "
            f"{args.worlds} unseen worlds (reset seeds {UNSEEN}..{UNSEEN + args.worlds - 1}); cost = median route cost "
            "over successful episodes; host = median host time per episode (planning, or inference over the "
            "episode's decisions).",
            "",
            "| controller | success | median cost | mean cost | median / strong | host time |",
            "|---|---:|---:|---:|---:|---:|",
        ]
        for name, s in summary.items():
            rows = res.by_controller(name)
            mean_cost = float(np.mean([r["route_cost"] for r in rows if r["is_success"]]))
            label = {ppo_name: "MaskablePPO (pointer), greedy", ms_name: "MaskablePPO (pointer), multi-start"}.get(name, name)
            lines.append(f"| {label} | {100 * s['success_rate']:.1f} % | {s['route_cost']:.1f} | {mean_cost:.2f} | "
                         f"{s['route_cost'] / strong:.3f} | {1e3 * s['host_cpu_s']:.2f} ms |")
        lines += [
            "",
            f"Per world, the learned route costs {np.median(ratios):.3f}x (median) / {np.mean(ratios):.3f}x (mean) "
            f"the strong pipeline's with greedy decoding (`ppo:`), {np.median(ms_ratios):.3f}x / "
            f"{np.mean(ms_ratios):.3f}x with multi-start decoding (`ppo-ms:`: one greedy rollout per legal first "
            "decision, the cheapest kept; its host time includes the search). Checkpoints (greedy; unseen worlds "
            f"{UNSEEN}..{UNSEEN + args.curve_worlds - 1}; figure `docs/learned/fig_learned_vs_planners.png`):",
            "",
            "| env steps | train time | success | median cost | mean cost |",
            "|---:|---:|---:|---:|---:|",
        ]
        for r in cb.rows:
            lines.append(f"| {r['timesteps']} | {r['train_s']:.0f} s | {100 * r['success_rate']:.0f} % | "
                         f"{r['median_route_cost']:.1f} | {r['mean_route_cost']:.2f} |")
        write_results_section(lines[0], "\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
