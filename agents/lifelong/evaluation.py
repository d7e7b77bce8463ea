"""Lifelong evaluation: controllers x episodes on a lifelong id, with decision latency and energy per task.

:func:`run_lifelong_episode` times every decision outside the env (host seconds + the chip's parallel time);
:func:`evaluate_lifelong` repeats it over controllers and seeds, :func:`summarize` pools per controller.
``mrmt compare --env-id mrmt_env/MRMT-Lifelong-Warehouse-v0`` runs it (:func:`run_compare`).
Design notes: docs/design/lifelong.md#lifelong-evaluation.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from planners.compute import CPU_WATTS_PER_CORE

__all__ = ["run_lifelong_episode", "evaluate_lifelong", "summarize", "format_summary", "is_lifelong_id",
           "run_compare", "DEFAULT_LIFELONG_STEPS", "SUMMARY_KEYS"]

#: Steps of a lifelong episode in ``mrmt compare`` unless ``--max-steps`` is given.
DEFAULT_LIFELONG_STEPS = 200

SUMMARY_KEYS = ("controller", "episodes", "throughput", "tasks_completed", "service_time_mean", "conflicts",
                "blocked_moves", "decision_latency_p50_s", "decision_latency_p99_s", "chip_calls_per_task",
                "paper_energy_per_task_j", "total_energy_per_task_j")


def is_lifelong_id(env_id: str) -> bool:
    import mrmt_env

    return env_id in mrmt_env.LIFELONG_IDS


_WARM: set = set()


def _warm_up(spec: str, chip, executor: str) -> None:
    """Compile a controller's kernels once per process on a small world (not timed)."""
    if (spec, executor) in _WARM:
        return
    import gymnasium as gym

    from agents.lifelong.controllers import make_lifelong_controller

    env = gym.make("mrmt_env/MRMT-Lifelong-v0")
    obs, _ = env.reset(seed=0)
    ctrl = make_lifelong_controller(spec, seed=0, chip=chip, executor=executor)
    for _ in range(5):
        obs, *_ = env.step(ctrl.act(obs))
    _WARM.add((spec, executor))


def run_lifelong_episode(env_id: str, spec: str, seed: int, steps: int, env_kwargs: dict | None = None, chip=None,
                         executor: str = "pibt", options: dict | None = None) -> dict:
    """One episode of ``steps`` steps; returns its record (metrics, per-decision latencies, energies).
    ``options``: the pipeline assigner's (:func:`agents.lifelong.controllers.make_lifelong_controller`)."""
    import gymnasium as gym

    from agents.lifelong.controllers import make_lifelong_controller

    _warm_up(spec, chip, executor)
    env = gym.make(env_id, max_episode_steps=steps, **(env_kwargs or {}))
    obs, info = env.reset(seed=seed)
    ctrl = make_lifelong_controller(spec, seed=seed, chip=chip, executor=executor, **(options or {}))
    latencies = np.zeros(steps)
    host_s = accel_j = 0.0
    chip_calls = 0
    for t in range(steps):
        t0 = time.perf_counter()
        action = ctrl.act(obs)
        wall = time.perf_counter() - t0
        c = ctrl.last_compute
        host = max(wall - c.emulation_s, 0.0)
        latencies[t] = host + c.chip_time_parallel_s
        host_s += host
        accel_j += c.accelerator_energy_j
        chip_calls += c.chip_calls + c.logical_calls
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            latencies = latencies[:t + 1]
            break
    done = max(info["tasks_completed"], 1)
    host_j = host_s * CPU_WATTS_PER_CORE
    accelerated = ctrl.assigner.accelerated
    return {
        "controller": spec, "executor": executor, "seed": int(seed), "steps": info["steps"],
        "n_robots": ctrl.executor.elapsed.size,
        "throughput": info["throughput"], "tasks_completed": info["tasks_completed"],
        "service_time_mean": info["service_time_mean"], "conflicts": info["conflicts"],
        "blocked_moves": info["blocked_moves"], "replans": ctrl.replans,
        "decision_latency_p50_s": float(np.percentile(latencies, 50)),
        "decision_latency_p99_s": float(np.percentile(latencies, 99)),
        "host_s": host_s, "chip_calls": chip_calls, "host_energy_j": host_j, "accelerator_energy_j": accel_j,
        "paper_energy_per_task_j": (accel_j if accelerated else host_j) / done,
        "total_energy_per_task_j": (host_j + accel_j) / done,
        "latencies": latencies.tolist(),
    }


def evaluate_lifelong(specs, env_id: str, seeds, steps: int, env_kwargs: dict | None = None, chip=None,
                      executor: str = "pibt", progress: bool = False, options: dict | None = None) -> list[dict]:
    """:func:`run_lifelong_episode` for every controller spec and seed (one process: timings are not shared)."""
    rows = []
    jobs = [(s, seed) for s in specs for seed in seeds]
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(jobs), desc="lifelong episodes", file=sys.stderr)
    try:
        for spec, seed in jobs:
            rows.append(run_lifelong_episode(env_id, spec, seed, steps, env_kwargs, chip, executor, options))
            if bar is not None:
                bar.update(1)
    finally:  # closed before an error is printed, not redrawn after it
        if bar is not None:
            bar.close()
    return rows


def summarize(rows: list[dict]) -> list[dict]:
    """One row per controller: mean metrics, latency percentiles over all its decisions, energy per task."""
    out = []
    for spec in dict.fromkeys(r["controller"] for r in rows):
        mine = [r for r in rows if r["controller"] == spec]
        lat = np.concatenate([r["latencies"] for r in mine])
        done = max(sum(r["tasks_completed"] for r in mine), 1)
        accelerated = any(r["accelerator_energy_j"] > 0 for r in mine)
        host = sum(r["host_energy_j"] for r in mine)
        accel = sum(r["accelerator_energy_j"] for r in mine)
        out.append({
            "controller": spec, "episodes": len(mine),
            "throughput": float(np.mean([r["throughput"] for r in mine])),
            "tasks_completed": float(np.mean([r["tasks_completed"] for r in mine])),
            "service_time_mean": float(np.mean([r["service_time_mean"] for r in mine])),
            "conflicts": int(sum(r["conflicts"] for r in mine)),
            "blocked_moves": int(sum(r["blocked_moves"] for r in mine)),
            "decision_latency_p50_s": float(np.percentile(lat, 50)),
            "decision_latency_p99_s": float(np.percentile(lat, 99)),
            "chip_calls_per_task": sum(r["chip_calls"] for r in mine) / done,
            "paper_energy_per_task_j": (accel if accelerated else host) / done,
            "total_energy_per_task_j": (host + accel) / done,
        })
    return out


def format_summary(summary: list[dict]) -> str:
    """The summary as a fixed-width text table."""
    head = ("controller", "throughput", "tasks", "service", "conflicts", "lat_p50_ms", "lat_p99_ms", "chip/task",
            "paper_J/task", "total_J/task")
    lines = ["  ".join(f"{h:>12}" for h in head)]
    for s in summary:
        vals = (s["controller"], f"{s['throughput']:.3f}", f"{s['tasks_completed']:.1f}",
                f"{s['service_time_mean']:.1f}", str(s["conflicts"]), f"{1e3 * s['decision_latency_p50_s']:.2f}",
                f"{1e3 * s['decision_latency_p99_s']:.2f}", f"{s['chip_calls_per_task']:.1f}",
                f"{s['paper_energy_per_task_j']:.2e}", f"{s['total_energy_per_task_j']:.2e}")
        lines.append("  ".join(f"{v:>12}" for v in vals))
    return "\n".join(lines)


def run_compare(args) -> int:
    """``mrmt compare`` on a lifelong id: ``--worlds`` episodes from ``--seed`` per controller, of
    ``--max-steps`` steps (default :data:`DEFAULT_LIFELONG_STEPS`); ``--out DIR`` writes
    ``lifelong.csv`` and ``lifelong.json`` (one row per episode)."""
    from agents.commands.options import check_positive, check_seed
    from agents.errors import ControllerError
    from agents.lifelong.controllers import LIFELONG_CONTROLLERS

    specs = [s.strip() for s in str(args.controllers).split(",") if s.strip()]
    bad = [s for s in specs if s not in LIFELONG_CONTROLLERS and not (s.count("+") == 1 and all(s.split("+")))
           and not (s.startswith("ppo:") and len(s) > 4)]
    problem = (f"unknown lifelong controller {bad[0]!r}; expected {', '.join(LIFELONG_CONTROLLERS)}, a "
               "sharing+tour pair (e.g. ssa+3opt) or ppo:MODEL.zip") if bad else None
    problem = problem or (None if specs else f"no controller named in {args.controllers!r}")
    problem = problem or check_positive(args, ("worlds", "robots", "targets", "height", "width", "max-steps"))
    problem = problem or check_seed("--seed", args.seed, args.worlds)
    if problem:
        print(f"mrmt compare: error: {problem}", file=sys.stderr)
        return 2
    given = {"n_robots": args.robots, "n_targets": args.targets, "height": args.height, "width": args.width,
             "obstacle_density": args.density, "placement": args.placement, "layout": args.layout}
    env_kwargs = {k: v for k, v in given.items() if v is not None}
    steps = args.max_steps or DEFAULT_LIFELONG_STEPS
    try:
        from agents.commands.options import chip_from_args
        from agents.env_ids import check_worlds
        from agents.lifelong.controllers import make_lifelong_controller

        chip = chip_from_args(args)  # --chip spec fields and --sampler
        # before the progress bar: a world the env cannot hold, a model file or a layer name that cannot be used
        check_worlds(args.env_id, env_kwargs, range(args.seed, args.seed + args.worlds))
        for spec in specs:
            make_lifelong_controller(spec, seed=args.seed, chip=chip)
        rows = evaluate_lifelong(specs, args.env_id, range(args.seed, args.seed + args.worlds), steps, env_kwargs,
                                 chip=chip, progress=not args.no_progress)
    except (ValueError, TypeError, ControllerError) as exc:
        print(f"mrmt compare: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    print(format_summary(summarize(rows)))
    if args.out:
        import csv
        import json
        from pathlib import Path

        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        flat = [{k: v for k, v in r.items() if k != "latencies"} for r in rows]
        with open(out / "lifelong.csv", "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=list(flat[0]))
            writer.writeheader()
            writer.writerows(flat)
        (out / "lifelong.json").write_text(json.dumps(rows, indent=1))
        print(f"wrote {out / 'lifelong.csv'} and {out / 'lifelong.json'}", file=sys.stderr)
    return 0
