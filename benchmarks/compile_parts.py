"""The compile notice's reference seconds: each warm-up part alone, and the speed probe, on this machine.

    flock /tmp/mrmt-bench.lock python benchmarks/compile_parts.py [--parts P,P,...] [--probes 5]

Each part of :data:`agents.warmup.PART_SECONDS` is compiled alone in a fresh process with an empty numba cache
(its own ``NUMBA_CACHE_DIR``), timed in wall seconds from the process's start, its kernels counted (numba's
compile events, :func:`agents.warmup.count_compiles`); then
:func:`agents.warmup.probe_seconds` runs ``--probes`` times.  Prints the measured seconds beside the table's and the
lines to paste into ``agents/warmup.py`` (``PART_SECONDS``, ``PART_KERNELS``, ``PROBE_REF_S``: the probes' median) when this machine
becomes the reference.  Run it on a quiet machine, alone.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def part_seconds(part: str) -> tuple[float, int]:
    """Wall seconds of a fresh process compiling ``part`` with an empty numba cache, and the kernels it compiled."""
    with tempfile.TemporaryDirectory(prefix="mrmt-parts-") as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        code = ("from agents.warmup import compile_part, count_compiles\nnames = []\n"
                f"with count_compiles(names.append):\n    compile_part({part!r})\nprint(len(names))")
        t0 = time.perf_counter()
        out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, check=True, capture_output=True,
                             text=True)
        return time.perf_counter() - t0, int(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    from agents.warmup import PART_KERNELS, PART_SECONDS, PROBE_REF_S, probe_seconds

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default=",".join(PART_SECONDS), help="comma-separated parts (default: all)")
    parser.add_argument("--probes", type=int, default=5, help="runs of the speed probe (default 5)")
    args = parser.parse_args(argv)
    parts = [p.strip() for p in args.parts.split(",") if p.strip()]
    unknown = [p for p in parts if p not in PART_SECONDS]
    if unknown or args.probes < 1:
        print(f"compile_parts: error: {'unknown part ' + repr(unknown[0]) if unknown else '--probes must be >= 1'}"
              f" (parts: {', '.join(PART_SECONDS)})", file=sys.stderr)
        return 2
    measured, kernels = {}, {}
    for part in parts:
        measured[part], kernels[part] = part_seconds(part)
        print(f"{part:24s} {measured[part]:6.1f} s   (table: {PART_SECONDS[part]} s)   {kernels[part]:4d} kernels "
              f"(table: {PART_KERNELS.get(part, '-')})", flush=True)
    probes = [probe_seconds() for _ in range(args.probes)]
    if any(p is None for p in probes):
        print("compile_parts: error: the speed probe did not run", file=sys.stderr)
        return 1
    probe = statistics.median(probes)
    print(f"probe {probe:.3f} s (runs {', '.join(f'{p:.3f}' for p in probes)}; table: {PROBE_REF_S} s); "
          f"pace against the table's reference: {probe / PROBE_REF_S:.2f}x")
    print("PART_SECONDS = {" + ", ".join(f'"{p}": {round(s)}' for p, s in measured.items()) + "}")
    print("PART_KERNELS = {" + ", ".join(f'"{p}": {n}' for p, n in kernels.items()) + "}")
    print(f"PROBE_REF_S = {probe:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
