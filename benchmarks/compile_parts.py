"""The compile notice's reference seconds: each warm-up part alone, and the speed probe, on this machine.

    flock /tmp/mrmt-bench.lock python benchmarks/compile_parts.py [--parts P,P,...] [--probes 5]

Each part of :data:`agents.warmup.PART_SECONDS` is compiled alone in a fresh process with an empty numba cache
(its own ``NUMBA_CACHE_DIR``), timed in wall seconds from the process's start; then
:func:`agents.warmup.probe_seconds` runs ``--probes`` times.  Prints the measured seconds beside the table's and the
lines to paste into ``agents/warmup.py`` (``PART_SECONDS``, ``PROBE_REF_S``: the probes' median) when this machine
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


def part_seconds(part: str) -> float:
    """Wall seconds of a fresh process compiling ``part`` with an empty numba cache."""
    with tempfile.TemporaryDirectory(prefix="mrmt-parts-") as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        code = f"from agents.warmup import compile_part; compile_part({part!r})"
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, check=True, capture_output=True)
        return time.perf_counter() - t0


def main(argv=None) -> int:
    from agents.warmup import PART_SECONDS, PROBE_REF_S, probe_seconds

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
    measured = {}
    for part in parts:
        measured[part] = part_seconds(part)
        print(f"{part:24s} {measured[part]:6.1f} s   (table: {PART_SECONDS[part]} s)", flush=True)
    probes = [probe_seconds() for _ in range(args.probes)]
    if any(p is None for p in probes):
        print("compile_parts: error: the speed probe did not run", file=sys.stderr)
        return 1
    probe = statistics.median(probes)
    print(f"probe {probe:.3f} s (runs {', '.join(f'{p:.3f}' for p in probes)}; table: {PROBE_REF_S} s); "
          f"pace against the table's reference: {probe / PROBE_REF_S:.2f}x")
    print("PART_SECONDS = {" + ", ".join(f'"{p}": {round(s)}' for p, s in measured.items()) + "}")
    print(f"PROBE_REF_S = {probe:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
