"""Benchmark the emulated chip's kernel against dwave-samplers (issue 3).

200 random dense 45-spin programs with integer coefficients in [-7, 7]
(seed 0).  Measured in one run, one thread:

* JIT warm-up: first ``anneal_batch`` call in a fresh process with an empty
  numba cache (compile) and with the on-disk cache (load);
* ``EmulatedChip.anneal_batch`` wall time per call (program x read), amortized
  over the whole stack, best of several repeats after warm-up, for the default
  spec (5 % coupling mismatch) and the noise-free spec;
* ``dwave.samplers.SimulatedAnnealingSampler`` through dimod at the same number
  of sweeps (one ``sample`` per program, default beta range), per call;
* hit rate: fraction of calls whose energy equals the best known energy of the
  program (best over long runs of both annealers and the logical tabu solver).

Usage::

    flock /tmp/mrmt-bench.lock python benchmarks/chip_speed.py [--write]

``--write`` replaces the "Issue 3: emulated chip" section of benchmarks/RESULTS.md.
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse  # noqa: E402
import platform  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

SECTION = "## Issue 3: emulated chip"
N_PROGRAMS = 200
N_SPINS = 45
SWEEPS = 50


def programs(seed: int = 0):
    rng = np.random.default_rng(seed)
    h = rng.integers(-7, 8, (N_PROGRAMS, N_SPINS)).astype(np.int64)
    J = np.triu(rng.integers(-7, 8, (N_PROGRAMS, N_SPINS, N_SPINS)), 1).astype(np.int64)
    return h, J


_WARMUP_SNIPPET = """
import time, numpy as np
t = time.perf_counter()
from ising_backend import EmulatedChip
chip = EmulatedChip(seed=0)
t_import = time.perf_counter() - t
h = np.zeros((1, 45), dtype=np.int64); J = np.zeros((1, 45, 45), dtype=np.int64)
t = time.perf_counter(); chip.anneal_batch(h, J); print(t_import, time.perf_counter() - t)
"""


def warmup_seconds(cache_dir: str | None) -> tuple[float, float]:
    env = dict(os.environ)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    out = subprocess.run([sys.executable, "-c", _WARMUP_SNIPPET], env=env, capture_output=True, text=True, check=True)
    a, b = out.stdout.split()
    return float(a), float(b)


def time_chip(chip, h, J, reads, repeats=5):
    chip.anneal_batch(h[:2], J[:2], num_reads=reads, seed=0)  # warm
    best = best_cpu = np.inf
    energies = None
    for rep in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        _, e = chip.anneal_batch(h, J, num_reads=reads, seed=1000 + rep)
        best = min(best, time.perf_counter() - t)
        best_cpu = min(best_cpu, time.process_time() - c)
        if energies is None:
            energies = e
    calls = h.shape[0] * reads
    return (best / calls, best_cpu / calls), energies


def time_dwave(h, J, reads):
    import dimod
    from dwave.samplers import SimulatedAnnealingSampler

    sampler = SimulatedAnnealingSampler()
    iu = np.triu_indices(N_SPINS, 1)
    bqms = [dimod.BQM.from_ising(dict(enumerate(h[b].astype(float))),
                                 {(int(i), int(j)): float(J[b, i, j]) for i, j in zip(*iu)})
            for b in range(h.shape[0])]
    sampler.sample(bqms[0], num_reads=reads, num_sweeps=SWEEPS, seed=0)  # warm
    energies = np.empty((h.shape[0], reads))
    t, c = time.perf_counter(), time.process_time()
    for b, bqm in enumerate(bqms):
        ss = sampler.sample(bqm, num_reads=reads, num_sweeps=SWEEPS, seed=b)
        energies[b] = ss.record.energy
    dt, dc = time.perf_counter() - t, time.process_time() - c
    calls = h.shape[0] * reads
    return (dt / calls, dc / calls), energies, bqms


def best_known(h, J, bqms):
    from dwave.samplers import SimulatedAnnealingSampler

    from ising_backend import ChipSpec, EmulatedChip, LogicalIsingSolver

    long_chip = EmulatedChip(ChipSpec(sweeps=2000).noise_free(), seed=0)
    _, e1 = long_chip.anneal_batch(h, J, num_reads=10, seed=7)
    sol = LogicalIsingSolver(restarts=20, seed=0)
    _, e2 = sol.anneal_batch(h.astype(float), J.astype(float), num_reads=2, seed=3)
    sa = SimulatedAnnealingSampler()
    e3 = np.array([sa.sample(b, num_reads=10, num_sweeps=2000, seed=11).first.energy for b in bqms])
    return np.minimum(np.minimum(e1.min(axis=1), e2.min(axis=1)), e3)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="write the section into benchmarks/RESULTS.md")
    ap.add_argument("--reads", type=int, default=10, help="reads per program for the timing runs")
    args = ap.parse_args(argv)

    with tempfile.TemporaryDirectory() as tmp:
        imp_cold, jit_cold = warmup_seconds(tmp)
    imp_warm, jit_warm = warmup_seconds(None)

    from ising_backend import ChipSpec, EmulatedChip

    h, J = programs(0)
    R = args.reads
    t_def1, e_def1 = time_chip(EmulatedChip(ChipSpec(), seed=0), h, J, 1)
    t_defR, e_defR = time_chip(EmulatedChip(ChipSpec(), seed=0), h, J, R)
    t_cln1, e_cln1 = time_chip(EmulatedChip(ChipSpec().noise_free(), seed=0), h, J, 1)
    t_clnR, e_clnR = time_chip(EmulatedChip(ChipSpec().noise_free(), seed=0), h, J, R)
    t_dw1, e_dw1, bqms = time_dwave(h, J, 1)
    t_dwR, e_dwR, _ = time_dwave(h, J, R)
    best = best_known(h, J, bqms)
    improved = 0
    for e in (e_def1, e_defR, e_cln1, e_clnR, e_dw1, e_dwR):  # a short run may beat the long ones: keep the best seen
        improved += int(np.sum(e.min(axis=1) < best - 1e-9))
        best = np.minimum(best, e.min(axis=1))

    def hit(e):
        return float(np.mean(e <= best[:, None] + 1e-9))

    def gap(e):
        return float(np.mean(e - best[:, None]))

    rows = [
        ("EmulatedChip.anneal_batch, default spec (5 % mismatch)", 1, t_def1, e_def1),
        ("EmulatedChip.anneal_batch, default spec (5 % mismatch)", R, t_defR, e_defR),
        ("EmulatedChip.anneal_batch, noise-free spec", 1, t_cln1, e_cln1),
        ("EmulatedChip.anneal_batch, noise-free spec", R, t_clnR, e_clnR),
        ("dwave-samplers SimulatedAnnealingSampler via dimod", 1, t_dw1, e_dw1),
        ("dwave-samplers SimulatedAnnealingSampler via dimod", R, t_dwR, e_dwR),
    ]

    cpu = platform.processor() or platform.machine()
    lines = [
        SECTION,
        "",
        f"`flock /tmp/mrmt-bench.lock python benchmarks/chip_speed.py --write` "
        f"({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {cpu}, one thread, NUMBA_NUM_THREADS=1; "
        "the 2 vCPUs are shared with other jobs, so wall times carry noise; CPU time = process time of "
        "the one thread).",
        "",
        f"{N_PROGRAMS} random dense {N_SPINS}-spin programs, integer h, J uniform in [-7, 7] (seed 0), "
        f"{SWEEPS} sweeps. Per-call time = wall time / (programs x reads), best of 5 repeats after warm-up. "
        "Hit rate = share of calls reaching the best known energy (best of 2000-sweep runs of both annealers "
        "and the logical tabu solver, and of every measured call); gap = mean energy above it. "
        f"Programs whose best known energy came from a 50-sweep call: {improved}.",
        "",
        "| solver | reads / program | wall us / call | CPU us / call | hit rate | mean gap |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for name, reads, (tw, tc), e in rows:
        lines.append(f"| {name} | {reads} | {tw * 1e6:.1f} | {tc * 1e6:.1f} | {hit(e):.3f} | {gap(e):.1f} |")
    lines += [
        "",
        f"Speed-up over dwave-samplers at 1 read per call (one chip call = one dimod call): "
        f"**{t_dw1[0] / t_def1[0]:.0f}x** wall, {t_dw1[1] / t_def1[1]:.0f}x CPU (default spec); "
        f"{t_dw1[0] / t_cln1[0]:.0f}x wall (noise-free). "
        f"At {R} reads per dimod call (dwave amortizes its ~ms set-up over the reads): "
        f"{t_dwR[0] / t_defR[0]:.0f}x wall, {t_dwR[1] / t_defR[1]:.0f}x CPU (default spec).",
        "",
        "Issue goal: <= 15 us per call and >= 50x faster than dwave-samplers at an equal or better hit rate. "
        f"Measured: {min(t_defR[1], t_clnR[1]) * 1e6:.0f}-{max(t_def1[1], t_cln1[1]) * 1e6:.0f} us CPU per call "
        f"({'meets' if max(t_def1[1], t_cln1[1]) <= 15e-6 else 'misses'} the 15 us goal on this shared VM); "
        f"speed-up at one read per call {'meets' if t_dw1[1] / t_def1[1] >= 50 else 'misses'} the 50x goal; "
        f"hit rate noise-free {hit(e_cln1):.3f} vs dwave {hit(e_dw1):.3f} at 1 read "
        f"({'equal or better' if hit(e_cln1) >= hit(e_dw1) else 'lower'}); the default spec's 5 % coupling "
        f"mismatch costs hit rate ({hit(e_def1):.3f}): it anneals a slightly different program than the one scored.",
        "",
        f"JIT warm-up (first `anneal_batch` in a fresh process): {jit_cold:.2f} s with an empty numba cache "
        f"(compile), {jit_warm:.3f} s with the on-disk cache; package import {imp_warm:.2f} s.",
        "",
    ]
    text = "\n".join(lines)
    print(text)
    if args.write:
        path = Path(__file__).with_name("RESULTS.md")
        old = path.read_text() if path.exists() else "# Benchmark results\n"
        if SECTION in old:
            start = old.index(SECTION)
            nxt = old.find("\n## ", start + len(SECTION))
            new = old[:start] + text + ("\n" + old[nxt + 1:] if nxt >= 0 else "")
        else:
            new = old.rstrip("\n") + "\n\n" + text
        path.write_text(new)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
