"""Native vector envs against the single env: env steps per second on one process.

For each id, the single env (``gymnasium.make(id)``, its wrappers included,
resets included) and the native vector env
(``gymnasium.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``,
gymnasium's default next-step autoreset, observation copied each step) are
stepped for ``--seconds`` each.  Actions: uniform random joint moves on the
grid env (pre-drawn); the first legal target on the plan-level env (an
``argmax`` over the mask, the same work in both).  Writes the RESULTS.md
section.

    flock /tmp/mrmt-bench.lock python benchmarks/vector_env_throughput.py
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import cpu_name, write_results_section  # noqa: E402

IDS = ("mrmt_env/MRMT-v0", "mrmt_env/MRMT-Assign-v0")


def _single(env_id: str, seconds: float) -> float:
    import gymnasium as gym

    env = gym.make(env_id)
    assign = "Assign" in env_id
    acts = np.random.default_rng(0).integers(0, 5, size=(1024,) + env.action_space.shape)
    obs, info = env.reset(seed=0)
    n, t0 = 0, time.perf_counter()
    while True:
        for _ in range(256):
            a = int(np.argmax(info["action_mask"])) if assign else acts[n % 1024]
            obs, r, term, trunc, info = env.step(a)
            n += 1
            if term or trunc:
                obs, info = env.reset()
        if time.perf_counter() - t0 >= seconds:
            return n / (time.perf_counter() - t0)


def _vector(env_id: str, num_envs: int, seconds: float) -> float:
    import gymnasium as gym

    env = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point")
    assign = "Assign" in env_id
    acts = np.random.default_rng(0).integers(0, 5, size=(64,) + env.action_space.shape)
    obs, info = env.reset(seed=0)
    for j in range(20):  # warm-up (compiled kernels load from cache)
        obs, r, term, trunc, info = env.step(np.argmax(info["action_mask"], axis=1) if assign else acts[j % 64])
    n, j, t0 = 0, 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        a = np.argmax(info["action_mask"], axis=1) if assign else acts[j % 64]
        obs, r, term, trunc, info = env.step(a)
        n += num_envs
        j += 1
    return n / (time.perf_counter() - t0)


def main(argv=None) -> int:
    import mrmt_env  # noqa: F401

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=4.0)
    p.add_argument("--sizes", default="1,16,256,1024")
    p.add_argument("--no-results", action="store_true")
    args = p.parse_args(argv)
    sizes = [int(s) for s in args.sizes.split(",")]
    rows = []
    for env_id in IDS:
        single = _single(env_id, args.seconds)
        row = {"env_id": env_id, "single": single}
        for n in sizes:
            row[n] = _vector(env_id, n, args.seconds)
        rows.append(row)
        print(env_id, {k: (f"{v:,.0f}" if isinstance(v, float) else v) for k, v in row.items()}, flush=True)
    if not args.no_results:
        lines = [
            "## Issue 11: native vector envs (env steps per second, one process)",
            "",
            f"`python benchmarks/vector_env_throughput.py` on {cpu_name()} (2 cores shared with other work; one "
            "process). Single = `gymnasium.make(id)` with its wrappers, resets included; vector = "
            "`gymnasium.make_vec(id, num_envs=N, vectorization_mode=\"vector_entry_point\")`, next-step autoreset, "
            "observations copied. Grid: random joint moves (episodes end at the 200-step limit); plan level: "
            "the first legal target (13 decisions per episode, so world generation -- the same random draws as "
            "`generate_world` -- is a large share).",
            "",
            "| env id | single | " + " | ".join(f"N = {n}" for n in sizes) + " | N = 256 / single |",
            "|---|---:|" + "---:|" * len(sizes) + "---:|",
        ]
        for r in rows:
            cells = " | ".join(f"{r[n] / 1e3:,.0f}k" for n in sizes)
            ratio = r[256] / r["single"] if 256 in r else float("nan")
            lines.append(f"| `{r['env_id']}` | {r['single'] / 1e3:,.0f}k | {cells} | {ratio:.1f}x |")
        write_results_section(lines[0], "\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
