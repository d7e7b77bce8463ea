"""Environment throughput: env steps per second with random actions.

Set-up: the paper's worlds (10x10, obstacle density 0.2, 3 robots, 10
targets, uniform placement), actions pre-sampled uniformly from ``0..4``
(so sampling is not timed), episodes of at most 200 steps with the reset
(a fresh generated world) inside the timed loop, one process on one core.

Measured:

* Gymnasium ``MRMTEnv`` unwrapped (self-truncating at 200 steps);
* Gymnasium ``gym.make("mrmt_env/MRMT-v0")`` (TimeLimit, OrderEnforcing and
  the passive env checker, as users get it);
* PettingZoo parallel env (one joint step = one env step; per-agent
  observation dicts built each step);
* PettingZoo AEC env (one joint step = R agent turns).

Run under the shared benchmark lock::

    flock /tmp/mrmt-bench.lock python benchmarks/env_throughput.py --write-results

``--write-results`` replaces the "Issue 2: environments" section of
``benchmarks/RESULTS.md`` (other sections are kept).
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np

import gymnasium as gym
import mrmt_env
from mrmt_env import MRMTEnv

try:
    from _common import cpu_name, write_results_section  # run as a script: python benchmarks/<name>.py
except ImportError:  # imported as benchmarks.<name>
    from benchmarks._common import cpu_name, write_results_section

SECTION = "## Issue 2: environments"
RESULTS = Path(__file__).with_name("RESULTS.md")
KW = dict(height=10, width=10, obstacle_density=0.2, n_robots=3, n_targets=10)
EPISODE = 200


def bench_gym(env, actions: np.ndarray) -> float:
    env.reset(seed=0)
    step = env.step
    reset = env.reset
    t0 = time.perf_counter()
    for a in actions:
        _, _, term, trunc, _ = step(a)
        if term or trunc:
            reset()
    return len(actions) / (time.perf_counter() - t0)


def bench_parallel(env, actions: np.ndarray) -> float:
    names = [f"robot_{k}" for k in range(actions.shape[1])]
    dicts = [dict(zip(names, row)) for row in actions.tolist()]
    env.reset(seed=0)
    step = env.step
    t0 = time.perf_counter()
    for d in dicts:
        step(d)
        if not env.agents:
            env.reset()
    return len(dicts) / (time.perf_counter() - t0)


def bench_aec(env, actions: np.ndarray) -> float:
    flat = actions.reshape(-1).tolist()
    env.reset(seed=0)
    t0 = time.perf_counter()
    i = 0
    n = len(flat)
    while i < n:
        for agent in env.agent_iter():
            if env.terminations[agent] or env.truncations[agent]:
                env.step(None)
                continue
            env.step(flat[i])
            i += 1
            if i >= n:
                break
        else:
            env.reset()
    return len(actions) / (time.perf_counter() - t0)


def run(steps: int, repeats: int) -> dict[str, tuple[float, float, float]]:
    rng = np.random.default_rng(0)
    actions = rng.integers(0, 5, size=(steps, KW["n_robots"]), dtype=np.int64)
    makers = {
        "gymnasium MRMTEnv (unwrapped)": lambda: bench_gym(MRMTEnv(**KW, max_episode_steps=EPISODE), actions),
        "gymnasium gym.make('mrmt_env/MRMT-v0')": lambda: bench_gym(
            gym.make("mrmt_env/MRMT-v0", max_episode_steps=EPISODE), actions
        ),
        "pettingzoo parallel_env": lambda: bench_parallel(mrmt_env.parallel_env(**KW, max_cycles=EPISODE), actions),
        "pettingzoo env (AEC, per joint step)": lambda: bench_aec(
            mrmt_env.env(**KW, max_cycles=EPISODE), actions[: max(1, steps // 4)]
        ),
    }
    bench_gym(MRMTEnv(**KW, max_episode_steps=EPISODE), actions[:5000])  # warm-up (numba cache, imports)
    out = {}
    for name, fn in makers.items():
        fn_runs = [fn() for _ in range(repeats)]
        out[name] = (float(np.median(fn_runs)), float(min(fn_runs)), float(max(fn_runs)))
        print(f"{name:45s} median {out[name][0]:>10,.0f} steps/s   runs {[round(x) for x in fn_runs]}", flush=True)
    return out


def write_section(results: dict[str, tuple[float, float, float]], steps: int, repeats: int) -> None:
    cpu = cpu_name()
    lines = [
        SECTION,
        "",
        f"`benchmarks/env_throughput.py` ({time.strftime('%Y-%m-%d', time.gmtime())}; {cpu}; Python "
        f"{platform.python_version()}; one process, one core; {steps:,} pre-sampled random joint actions "
        f"per run, median of {repeats} runs; episodes of at most {EPISODE} steps with the reset, which "
        "generates a fresh world, inside the timed loop).",
        "World: 10x10, obstacle density 0.2, 3 robots, 10 targets. Goal: >= 50,000 steps/s for the "
        "Gymnasium env (POGEMA reports about 15,000).",
        "",
        "| env | env steps / s (median) | min .. max of runs |",
        "|---|---:|---:|",
    ]
    for name, (med, lo, hi) in results.items():
        lines.append(f"| {name} | {med:,.0f} | {lo:,.0f} .. {hi:,.0f} |")
    lines += [
        "",
        "The machine's 2 cores are shared with other jobs, so runs vary; the median is reported.",
        "",
        "Reproduce: `flock /tmp/mrmt-bench.lock python benchmarks/env_throughput.py --write-results`",
        "",
    ]
    write_results_section(SECTION, "\n".join(lines), RESULTS)
    print(f"wrote section {SECTION!r} of {RESULTS}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=200_000, help="joint actions per run (default 200000)")
    ap.add_argument("--repeats", type=int, default=3, help="runs per env, median reported (default 3)")
    ap.add_argument("--write-results", action="store_true", help="update benchmarks/RESULTS.md")
    args = ap.parse_args()
    if args.steps < 1 or args.repeats < 1:
        ap.error("--steps and --repeats must be >= 1")
    if hasattr(os, "sched_setaffinity"):
        try:
            os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
        except OSError:
            pass
    results = run(args.steps, args.repeats)
    if args.write_results:
        write_section(results, args.steps, args.repeats)


if __name__ == "__main__":
    main()
