"""Lifelong operation: throughput and decision latency against fleet size, and the env's speed.

On the 64 x 64 warehouse of ``mrmt_env/MRMT-Lifelong-Warehouse-v0`` (refill
stream with ``K = 1.5 R`` open tasks on pick cells, collisions blocked) each
controller (``greedy``, ``strong``, ``ising`` through PIBT; ``greedy`` also
through the windowed planner) runs ``--steps`` steps per robot count and
seed.  Decision latency = host + chip seconds of one step's decision,
measured outside the env (:mod:`agents.lifelong.evaluation`), p50 / p99 over every
decision.  Then the env itself: robot-moves per second of the single env
and of the native vector env under random actions at 100 robots.  Writes
the RESULTS.md section and ``docs/lifelong.png``.

    flock /tmp/mrmt-bench.lock python benchmarks/lifelong.py
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from _common import cpu_name, write_results_section  # noqa: E402

ENV_ID = "mrmt_env/MRMT-Lifelong-Warehouse-v0"
SECTION = "## Issue 25: lifelong operation (warehouse, PIBT execution)"
#: (label, spec, executor, assigner options)
CONTROLLERS = (("greedy", "greedy", "pibt", {}), ("strong", "strong", "pibt", {}), ("ising", "ising", "pibt", {}),
               ("strong+fill", "strong", "pibt", {"fill": True}), ("ising+fill", "ising", "pibt", {"fill": True}),
               ("greedy+windowed", "greedy", "windowed", {}))


def _fleet(robots: int, steps: int, seeds, controllers) -> list[dict]:
    from agents.lifelong.evaluation import evaluate_lifelong, summarize

    kwargs = {"n_robots": robots, "n_targets": (3 * robots) // 2}
    out = []
    for label, spec, executor, options in controllers:
        rows = evaluate_lifelong([spec], ENV_ID, seeds, steps, kwargs, executor=executor, options=options)
        s = summarize(rows)[0]
        s.update(robots=robots, executor=executor, label=label)
        out.append(s)
        print(f"R={robots:4d} {s['label']:16s} throughput {s['throughput']:7.3f}  p50 "
              f"{1e3 * s['decision_latency_p50_s']:8.2f} ms  p99 {1e3 * s['decision_latency_p99_s']:8.2f} ms  "
              f"conflicts {s['conflicts']}", flush=True)
    return out


def _env_speed(robots: int, seconds: float, num_envs: int) -> tuple[float, float, float]:
    import gymnasium as gym

    env = gym.make(ENV_ID, n_robots=robots)
    acts = np.random.default_rng(0).integers(0, 5, size=(256, robots))
    env.reset(seed=0)
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        for i in range(256):
            *_, trunc, _ = env.step(acts[i])
            n += 1
            if trunc:
                env.reset()
    single = n * robots / (time.perf_counter() - t0)
    vector = []
    for copy in (True, False):  # copy=False hands out the batch's observation buffer (valid until the next step)
        venv = gym.make_vec(ENV_ID, num_envs=num_envs, vectorization_mode="vector_entry_point", n_robots=robots,
                            copy=copy)
        vacts = np.random.default_rng(0).integers(0, 5, size=(64, num_envs, robots))
        venv.reset(seed=0)
        n, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            for i in range(64):
                venv.step(vacts[i])
                n += 1
        vector.append(n * num_envs * robots / (time.perf_counter() - t0))
    return single, vector[0], vector[1]


def _figure(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    greedy = {r["robots"]: r["throughput"] for r in rows if r["label"] == "greedy"}
    for label in dict.fromkeys(r["label"] for r in rows):
        mine = [r for r in rows if r["label"] == label]
        x = [r["robots"] for r in mine]
        a.plot(x, [r["throughput"] / greedy[r["robots"]] for r in mine], marker="o", label=label)
        b.plot(x, [1e3 * r["decision_latency_p99_s"] for r in mine], marker="o", label=label)
    b.axhline(100, color="grey", ls="--", lw=0.8)
    b.axhline(1000, color="grey", ls=":", lw=0.8)
    a.set(xlabel="robots", ylabel="throughput / greedy's", xscale="log", title="throughput, 64x64 warehouse")
    b.set(xlabel="robots", ylabel="decision latency p99 (ms)", xscale="log", yscale="log",
          title="decision latency (host + chip per step)")
    a.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--robots", default="10,50,100,200,500", help="robot counts (default 10,50,100,200,500)")
    p.add_argument("--steps", type=int, default=200, help="steps per episode (default 200)")
    p.add_argument("--seeds", type=int, default=1, help="episodes per point (default 1)")
    p.add_argument("--env-seconds", type=float, default=3.0, help="seconds per env speed measurement")
    p.add_argument("--no-write", action="store_true", help="do not write RESULTS.md and the figure")
    args = p.parse_args(argv)
    counts = [int(v) for v in args.robots.split(",")]
    t_start = time.perf_counter()
    rows = []
    for robots in counts:
        rows.extend(_fleet(robots, args.steps, range(args.seeds), CONTROLLERS))
    single, vector, view = _env_speed(100, args.env_seconds, 16)
    lines = [SECTION, "",
             f"`flock /tmp/mrmt-bench.lock python benchmarks/lifelong.py --robots {args.robots} --steps {args.steps} "
             f"--seeds {args.seeds}` on {cpu_name()} (shared machine, 2 cores, one process). `{ENV_ID}` map "
             f"(64 x 64, 1800 pick cells), refill stream with K = 1.5 R open tasks, `collisions=\"block\"`, "
             f"{args.steps} steps per episode, {args.seeds} episode(s) per point. Decision latency: host + chip "
             "seconds of one step's decision (assignment on events + one PIBT / windowed step), measured outside "
             "the env; energy per task: paper convention (chip energy for `ising`, CPU x 15 W otherwise) and "
             "total (host + chip).", "",
             "| robots | controller | throughput (tasks/step) | tasks | service (steps) | conflicts | "
             "latency p50 (ms) | latency p99 (ms) | chip calls / task | paper J / task | total J / task |",
             "|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['robots']} | {r['label']} | {r['throughput']:.3f} | {r['tasks_completed']:.0f} | "
                     f"{r['service_time_mean']:.1f} | {r['conflicts']} | {1e3 * r['decision_latency_p50_s']:.2f} | "
                     f"{1e3 * r['decision_latency_p99_s']:.2f} | {r['chip_calls_per_task']:.1f} | "
                     f"{r['paper_energy_per_task_j']:.2e} | {r['total_energy_per_task_j']:.2e} |")
    lines += ["", f"Env speed at 100 robots, random actions, collisions blocked: single env "
              f"{single / 1e6:.2f} M robot-moves/s; native vector env (16 envs) {vector / 1e6:.2f} M robot-moves/s "
              f"({vector / single:.1f}x) with observations copied, {view / 1e6:.2f} M ({view / single:.1f}x) with "
              "`copy=False`. The observation is (2 + R) x H x W bytes (418 kB per env at 100 robots): copying it "
              "bounds both.", "",
              f"Figure: `docs/lifelong.png`. Run time {time.perf_counter() - t_start:.0f} s."]
    text = "\n".join(lines) + "\n"
    print(text)
    if not args.no_write:
        root = Path(__file__).resolve().parents[1]
        _figure(rows, root / "docs" / "lifelong.png")
        write_results_section(SECTION, text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
