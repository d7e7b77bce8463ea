"""Soak: a million env steps per registered id and ten thousand Ising plans in one process.

Checks, in one long-lived process:

* nothing crashes (every id through ``gymnasium.make``, with its wrappers; random actions --
  masked ones mostly legal on the plan-level id -- and a reset after every episode end);
* memory stays flat: the resident set size (RSS) at the end is within ``--rss-slack`` of the RSS
  after the first fifth of the run (the warm-up: imports, numba caches, allocator pools);
* the same seeds give the same results at the end as at the start: a fixed probe (episodes from
  fixed reset seeds and action streams; plans of fixed worlds with fixed seeds) is fingerprinted
  before the soak and again after it, on the long-lived object and on a fresh one.

Usage (full size; smaller ``--steps`` / ``--plans`` for a quick run)::

    python benchmarks/soak.py [--steps 1000000] [--plans 10000] [--write-results]

Exit code 1 if a check fails.  ``--write-results`` replaces the "Soak" section of
``benchmarks/RESULTS.md``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import resource
import sys
import time

import numpy as np

import gymnasium as gym
import mrmt_env
from mrmt_env import generate_world
from planners.pipeline import make_pipeline

try:
    from _common import cpu_name, write_results_section  # run as a script: python benchmarks/<name>.py
except ImportError:  # pragma: no cover - imported as benchmarks.soak
    from benchmarks._common import cpu_name, write_results_section

SECTION = "## Soak: 10^6 env steps per id and 10^4 Ising plans in one process"
ALL_IDS = sorted(mrmt_env.GYM_IDS) + sorted(mrmt_env.ASSIGN_IDS)
PROBE_STEPS = 2000
PROBE_PLANS = 30


def rss_mib() -> float:
    """Resident set size now (MiB), from ``/proc/self/statm``; peak RSS where there is no /proc."""
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
    except OSError:  # pragma: no cover - not Linux
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


class Actor:
    """Random actions from a seeded stream: uniform moves on a grid id (drawn 4096 at a time); on the
    plan-level id a legal target 95 % of the time, else any action (a forbidden one is a counted no-op)."""

    def __init__(self, env, seed: int) -> None:
        self.env = env.unwrapped
        self.assign = self.env.spec.id in mrmt_env.ASSIGN_IDS
        self.rng = np.random.default_rng(seed)
        self.shape = env.action_space.shape
        self.buf, self.i = None, 0

    def __call__(self):
        if self.assign:
            mask = self.env.action_masks()
            if self.rng.random() < 0.95:
                legal = np.flatnonzero(mask)
                return int(legal[self.rng.integers(legal.size)])
            return int(self.rng.integers(mask.size))
        if self.buf is None or self.i == len(self.buf):
            self.buf, self.i = self.rng.integers(0, 5, size=(4096,) + self.shape), 0
        self.i += 1
        return self.buf[self.i - 1]


def env_probe(env) -> str:
    """Fingerprint of ``PROBE_STEPS`` steps from fixed reset seeds and a fixed action stream."""
    h = hashlib.sha256()
    act = Actor(env, 7)
    obs, info = env.reset(seed=12345)
    episode = 0
    for _ in range(PROBE_STEPS):
        obs, reward, term, trunc, info = env.step(act())
        h.update(np.ascontiguousarray(obs).tobytes())
        h.update(repr((float(reward), bool(term), bool(trunc),
                       sorted((k, np.asarray(v).tolist()) for k, v in info.items()))).encode())
        if term or trunc:
            episode += 1
            obs, info = env.reset(seed=12345 + episode)
    return h.hexdigest()[:16]


def soak_env(env_id: str, steps: int, checkpoints: int = 20) -> dict:
    env = gym.make(env_id)
    start = env_probe(env)
    act = Actor(env, 2024)
    step = env.step
    env.reset(seed=0)
    episodes, cost, rss = 0, 0, []
    t0 = time.perf_counter()
    every = max(1, steps // checkpoints)
    for t in range(steps):
        _, _, term, trunc, info = step(act())
        if term or trunc:
            episodes += 1
            cost += info["route_cost"]
            env.reset(seed=episodes)
        if (t + 1) % every == 0:
            rss.append(rss_mib())
    wall = time.perf_counter() - t0
    end = env_probe(env)
    fresh = env_probe(gym.make(env_id))
    env.close()
    return {"id": env_id, "steps": steps, "episodes": episodes, "mean_route_cost": cost / max(episodes, 1),
            "wall_s": wall, "steps_per_s": steps / wall, "rss_mib": rss, "probe_start": start, "probe_end": end,
            "probe_fresh": fresh}


def plan_probe(pipeline) -> str:
    h = hashlib.sha256()
    for i in range(PROBE_PLANS):
        plan = pipeline.plan(generate_world(100_000 + i), seed=[7, i])
        c = plan.compute
        h.update(repr((plan.route_cost, plan.makespan, plan.success, c.chip_calls, c.logical_calls,
                       [r.targets for r in plan.routes], [r.path.tolist() for r in plan.routes])).encode())
    return h.hexdigest()[:16]


def soak_plans(n: int, checkpoints: int = 20) -> dict:
    pipeline = make_pipeline("ising")
    start = plan_probe(pipeline)
    rss, costs, failures, calls = [], [], 0, 0
    every = max(1, n // checkpoints)
    t0 = time.perf_counter()
    for i in range(n):
        plan = pipeline.plan(generate_world(i), seed=[1, i])
        costs.append(plan.route_cost)
        failures += not plan.success
        calls += plan.compute.chip_calls
        if (i + 1) % every == 0:
            rss.append(rss_mib())
    wall = time.perf_counter() - t0
    end = plan_probe(pipeline)
    fresh = plan_probe(make_pipeline("ising"))
    return {"id": "ising pipeline", "plans": n, "failures": failures, "median_route_cost": float(np.median(costs)),
            "chip_calls": calls, "wall_s": wall, "plans_per_s": n / wall, "rss_mib": rss, "probe_start": start,
            "probe_end": end, "probe_fresh": fresh}


def check(result: dict, slack_mib: float, slack_frac: float) -> list[str]:
    problems = []
    rss = result["rss_mib"]
    if len(rss) >= 5:
        base = rss[len(rss) // 5 - 1]
        growth = rss[-1] - base
        result["rss_after_warmup_mib"], result["rss_end_mib"], result["rss_growth_mib"] = base, rss[-1], growth
        if growth > max(slack_mib, slack_frac * base):
            problems.append(f"{result['id']}: RSS grew {growth:.1f} MiB after the warm-up ({base:.1f} -> "
                            f"{rss[-1]:.1f} MiB; allowed {max(slack_mib, slack_frac * base):.1f})")
    if not result["probe_start"] == result["probe_end"] == result["probe_fresh"]:
        problems.append(f"{result['id']}: the probe changed: start {result['probe_start']}, end "
                        f"{result['probe_end']}, fresh {result['probe_fresh']}")
    if result.get("failures"):
        problems.append(f"{result['id']}: {result['failures']} failed plans")
    return problems


def markdown(results: list[dict], args, total_s: float) -> str:
    lines = [
        SECTION,
        "",
        f"`python benchmarks/soak.py --steps {args.steps} --plans {args.plans}` "
        f"({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {cpu_name()}, Python {platform.python_version()}, "
        f"one process, {total_s / 60:.1f} min; 2 shared cores, so the rates are indicative).  Every id through "
        "`gymnasium.make` with random actions (on the plan-level id mostly legal, 5 % forbidden), a reset after "
        "every episode end; then the `ising` pipeline on worlds `generate_world(0 .. N-1)`.  RSS is sampled 20 "
        "times per run; *growth* is the end minus the value after the first fifth (warm-up).  The probe "
        f"({PROBE_STEPS} steps from fixed seeds and actions; {PROBE_PLANS} plans of fixed worlds and seeds) is "
        "fingerprinted before the run, after it on the same object, and on a fresh one.",
        "",
        "| run | steps / plans | episodes | rate | RSS after warm-up | RSS at end | growth | probe start = end = fresh |",
        "|---|---:|---:|---:|---:|---:|---:|---|",
    ]
    for r in results:
        n = r.get("steps", r.get("plans"))
        rate = f"{r['steps_per_s']:,.0f} steps/s" if "steps" in r else f"{r['plans_per_s']:.1f} plans/s"
        same = r["probe_start"] == r["probe_end"] == r["probe_fresh"]
        lines.append(f"| `{r['id']}` | {n:,} | {r.get('episodes', '-') if 'episodes' in r else '-'} | {rate} | "
                     f"{r.get('rss_after_warmup_mib', float('nan')):.1f} MiB | {r.get('rss_end_mib', float('nan')):.1f} MiB"
                     f" | {r.get('rss_growth_mib', float('nan')):+.1f} MiB | {'yes' if same else 'NO'} "
                     f"(`{r['probe_start']}`) |")
    plans = [r for r in results if "plans" in r]
    for r in plans:
        lines += ["", f"Ising plans: {r['failures']} failed of {r['plans']:,}, median route cost "
                      f"{r['median_route_cost']:g}, {r['chip_calls']:,} chip calls."]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1_000_000, help="env steps per id (default 10^6)")
    parser.add_argument("--plans", type=int, default=10_000, help="Ising plans (default 10^4)")
    parser.add_argument("--ids", default=",".join(ALL_IDS), help="comma-separated env ids (default: all)")
    parser.add_argument("--rss-slack", type=float, default=8.0, help="allowed RSS growth after warm-up, MiB")
    parser.add_argument("--rss-slack-frac", type=float, default=0.05, help="... or this share of the RSS")
    parser.add_argument("--json", default=None, help="write the raw results here")
    parser.add_argument("--write-results", action="store_true", help="replace the Soak section of RESULTS.md")
    args = parser.parse_args(argv)
    if args.steps < 0 or args.plans < 0:
        parser.error(f"--steps and --plans must be >= 0, got {args.steps} and {args.plans}")
    ids = [i.strip() for i in args.ids.split(",") if i.strip()]
    unknown = [i for i in ids if i not in ALL_IDS]
    if unknown:
        parser.error(f"unknown env id(s) {unknown}; registered: {', '.join(ALL_IDS)}")
    t0 = time.perf_counter()
    results, problems = [], []
    for env_id in ids if args.steps else []:
        r = soak_env(env_id, args.steps)
        problems += check(r, args.rss_slack, args.rss_slack_frac)
        results.append(r)
        print(f"{env_id}: {r['steps']:,} steps, {r['episodes']:,} episodes, {r['steps_per_s']:,.0f} steps/s, "
              f"RSS {r.get('rss_after_warmup_mib', 0):.1f} -> {r.get('rss_end_mib', 0):.1f} MiB, probe "
              f"{r['probe_start']}/{r['probe_end']}/{r['probe_fresh']}", file=sys.stderr, flush=True)
    if args.plans:
        r = soak_plans(args.plans)
        problems += check(r, args.rss_slack, args.rss_slack_frac)
        results.append(r)
        print(f"ising plans: {r['plans']:,} plans, {r['failures']} failed, {r['plans_per_s']:.1f} plans/s, RSS "
              f"{r.get('rss_after_warmup_mib', 0):.1f} -> {r.get('rss_end_mib', 0):.1f} MiB, probe "
              f"{r['probe_start']}/{r['probe_end']}/{r['probe_fresh']}", file=sys.stderr, flush=True)
    total = time.perf_counter() - t0
    text = markdown(results, args, total)
    print(text)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"results": results, "problems": problems, "total_s": total}, fh, indent=1)
    if args.write_results:
        write_results_section(SECTION, text)
    for p in problems:
        print(f"soak: FAILED: {p}", file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
