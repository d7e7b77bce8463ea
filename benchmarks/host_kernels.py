"""Per-call host time of the mapping kernels: numpy reference vs compiled (issue 9).

Inputs (realistic, seed 0):

* **patch**: 5x5 patch QUBOs of the pathfinding layer (``build_patch_qubo``, pair
  form, random obstacles and endpoints), as Ising models, merged at scale 16
  (the pathfinding default) with each merge style; decode = 10 reads of one
  merged program, majority;
* **cut n**: anchored split QUBOs of the sharing layer (``split_model`` on the
  BFS distances of a generated 10x10 world) with ``n`` free spins, as Ising
  models, quantized with each rule.

For every operation, the reference (``tests/mapping_reference.py``, the numpy code
the package used before) and the public compiled path (``merge_spins``,
``quantize``, ``MergedModel.decode``) are checked bit-identical, then timed call by
call (``perf_counter_ns``) over the same inputs, taking turns in blocks; the table
reports medians over ``--calls`` calls.  The batch entry points (``merge_styles``:
four styles in one call; ``quantize_stack``: four rules; ``decode_copies``: 4
programs x 10 reads) are timed against the reference doing the same work.

Usage::

    flock /tmp/mrmt-bench.lock python benchmarks/host_kernels.py [--calls 2000] [--write-results]
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse  # noqa: E402
import datetime  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._common import cpu_name, write_results_section  # noqa: E402
from ising_backend import MERGE_STYLES, QUANTIZE_RULES, QuboModel, merge_spins, quantize  # noqa: E402
from ising_backend.mapping._merge_kernel import STYLE_IDS, decode_copies, merge_styles  # noqa: E402
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # the oracles live with the tests
from mapping_reference import decode_ref, merge_spins_ref, quantize_ref  # noqa: E402
from ising_backend.mapping.quantize import quantize_stack  # noqa: E402
from mrmt_env.generation import generate_world  # noqa: E402
from planners.ising.path.qubo import build_patch_qubo, patch_frame  # noqa: E402
from planners.ising.sharing.split_problem import split_model  # noqa: E402

SECTION = "## Issue 9: compiled mapping kernels"
SCALE = 16.0
READS = 10
CUT_SIZES = (10, 20, 30, 40)


def patch_models(count: int, seed: int = 0) -> list:
    """Ising models of random 5x5 patch problems (pair form) that need at least one copy at scale 16."""
    rng = np.random.default_rng(seed)
    frame = patch_frame(5)
    out = []
    while len(out) < count:
        allowed = rng.random(frame.n) >= 0.2
        free = np.flatnonzero(allowed)
        if free.size < 4:
            continue
        start, goal = rng.choice(free, 2, replace=False)
        p = build_patch_qubo(frame, allowed, int(start), int(goal))
        if p.n == 0:
            continue
        model = QuboModel(p.q, p.Q, p.offset).to_ising()
        if merge_spins(model, "overload", scale=SCALE).n_extra > 0:
            out.append(model)
    return out


def cut_models(n_free: int, count: int, seed: int = 0) -> list:
    """Ising models of anchored split QUBOs with ``n_free`` free spins (3 robots, BFS distances)."""
    out = []
    k = 0
    while len(out) < count:
        world = generate_world(seed + k, n_robots=3, n_targets=n_free - 1)
        k += 1
        dist = world.distance_matrix
        if not np.all(np.isfinite(dist)):
            continue
        nodes = np.arange(dist.shape[0])
        _a, _b, _free, q, Q, off = split_model(dist, nodes, 3)
        out.append(QuboModel(q, Q, off).to_ising())
    return out


def _same(x, y) -> bool:
    return x.h.tobytes() == y.h.tobytes() and x.J.tobytes() == y.J.tobytes() and x.offset == y.offset


def median_us(calls: int, inputs: list, *fns, blocks: int = 20) -> list[float]:
    """Median per-call microseconds of each ``fn(x)`` over ``inputs`` (cycled).

    The functions take turns in ``blocks`` blocks of ``calls / blocks`` calls each, so
    slow drifts of the shared machine's load hit all of them alike, while each
    block runs with its own function's caches warm.
    """
    per = -(-calls // blocks)
    for fn in fns:  # warm (compile, first-call set-up)
        for x in inputs[:3]:
            fn(x)
    times = [np.empty(per * blocks) for _ in fns]
    clock = time.perf_counter_ns
    for b in range(blocks):
        for fn, ts in zip(fns, times):
            for c in range(b * per, (b + 1) * per):
                x = inputs[c % len(inputs)]
                t = clock()
                fn(x)
                ts[c] = clock() - t
    return [float(np.median(ts)) / 1e3 for ts in times]


def run(calls: int) -> tuple[list, dict]:
    rows = []  # (operation, input, reference us, compiled us)
    patches = patch_models(64)
    sizes = [m.n for m in patches]
    # ---- merge (4 styles), checked bit-identical first
    for style in MERGE_STYLES:
        for m in patches:
            r, k = merge_spins_ref(m, style, scale=SCALE), merge_spins(m, style, scale=SCALE)
            assert _same(r.physical, k.physical) and all(np.array_equal(a, b) for a, b in zip(r.copies, k.copies))
        ref, new = median_us(calls, patches, lambda m: merge_spins_ref(m, style, scale=SCALE),
                             lambda m: merge_spins(m, style, scale=SCALE))
        rows.append((f"merge_spins `{style}`", "patch", ref, new))
    all_styles = np.array([STYLE_IDS[s] for s in MERGE_STYLES], dtype=np.int64)

    def rounded(m):
        return np.rint(m.h * SCALE).astype(np.int64), np.rint(m.J * SCALE).astype(np.int64)

    ref, new = median_us(calls, patches, lambda m: [merge_spins_ref(m, s, scale=SCALE) for s in MERGE_STYLES],
                         lambda m: merge_styles(*rounded(m), all_styles, 7, 7, 7, 45))
    rows.append(("4 styles: 4 reference calls vs one `merge_styles` (rounding included)", "patch", ref, new))
    # ---- decode (majority, 10 reads)
    rng = np.random.default_rng(1)
    merged = [merge_spins(m, "overload", scale=SCALE) for m in patches]
    samples = [(mm, rng.choice(np.array([-1, 1], dtype=np.int8), (READS, mm.physical.n))) for mm in merged]
    for mm, s in samples:
        a, b = decode_ref(mm.copies, mm.physical.n, s), mm.decode(s)
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    ref, new = median_us(calls, samples, lambda x: decode_ref(x[0].copies, x[0].physical.n, x[1]),
                         lambda x: x[0].decode(x[1]))
    rows.append((f"MergedModel.decode, {READS} reads", "patch", ref, new))
    # decode_copies: the 4 style programs of one patch x 10 reads in one call
    packs = []
    for m in patches:
        status, err, a, n_phys, h, J, off, ptr, idx = merge_styles(
            np.rint(m.h * SCALE).astype(np.int64), np.rint(m.J * SCALE).astype(np.int64), all_styles, 7, 7, 7, 45)
        spins = rng.choice(np.array([-1, 1], dtype=np.int8), (4, READS, h.shape[1]))
        nlog = np.full(4, m.n, dtype=np.int64)
        views = [merge_spins(m, s, scale=SCALE) for s in MERGE_STYLES]
        packs.append((spins, nlog, ptr, idx, views))
    ref, new = median_us(calls, packs, lambda p: [decode_ref(v.copies, v.physical.n, p[0][k, :, :v.physical.n])
                                                  for k, v in enumerate(p[4])],
                         lambda p: decode_copies(p[0], p[1], p[2], p[3], False))
    rows.append((f"4 programs x {READS} reads: 4 reference decodes vs one `decode_copies`", "patch", ref, new))
    # ---- quantize (4 rules) on cut QUBOs
    for n in CUT_SIZES:
        models = cut_models(n, 16)
        for rule in QUANTIZE_RULES:
            for m in models:
                assert _same(quantize_ref(m, rule), quantize(m, rule))
            ref, new = median_us(calls, models, lambda m: quantize_ref(m, rule), lambda m: quantize(m, rule))
            rows.append((f"quantize `{rule}`", f"cut {n}", ref, new))
        ref, new = median_us(calls, models, lambda m: [quantize_ref(m, r) for r in QUANTIZE_RULES], quantize_stack)
        rows.append(("4 rules: 4 reference calls vs one `quantize_stack`", f"cut {n}", ref, new))
    info = {"patch_spins": (min(sizes), int(np.median(sizes)), max(sizes)),
            "patch_copies": (min(mm.n_extra for mm in merged), max(mm.n_extra for mm in merged))}
    return rows, info


def table(rows) -> str:
    lines = ["| operation | input | reference (us) | compiled (us) | speed-up |", "|---|---|---:|---:|---:|"]
    for op, inp, ref, new in rows:
        lines.append(f"| {op} | {inp} | {ref:.1f} | {new:.1f} | {ref / new:.0f}x |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=2000, help="timed calls per operation (median reported)")
    ap.add_argument("--write-results", action="store_true", help="write the section into benchmarks/RESULTS.md")
    args = ap.parse_args()
    if args.calls < 1:
        ap.error(f"--calls = {args.calls} must be >= 1")
    rows, info = run(args.calls)
    when = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    lo, med, hi = info["patch_spins"]
    c0, c1 = info["patch_copies"]
    block = f"""{SECTION}

`flock /tmp/mrmt-bench.lock python benchmarks/host_kernels.py --calls {args.calls} --write-results`
({when}, {platform.machine()}, {cpu_name()}, one thread; the 2 vCPUs are shared with other jobs, so
times carry noise).  Median wall time per call over {args.calls} calls, reference (the numpy
implementation the package used before, kept in `tests/mapping_reference.py`) and compiled path
timed alternately on the same inputs after checking both give bit-identical results.
Patch: 64 random 5x5 pair-form patch QUBOs ({lo}-{hi} spins, median {med}) as Ising models, merged
at scale 16 (the `overload` view uses {c0}-{c1} copies); decode of {READS} reads.  Cut n: 16 anchored
split QUBOs of the sharing layer with n free spins (BFS distances of generated 10x10 worlds).
The public calls (`merge_spins`, `quantize`, `MergedModel.decode`) include their argument checks,
rounding and model construction; the batch rows time the reference doing the same work (one call
per style / rule / program) against one call of the batch kernel.  Reference and compiled calls
take turns in 20 blocks of calls/20 calls each.

{table(rows)}
"""
    print(block)
    if args.write_results:
        write_results_section(SECTION, block)


if __name__ == "__main__":
    main()
