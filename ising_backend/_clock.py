"""A monotonic clock for compiled code: :func:`clock_ns` (numba, ``cache=True``).

Contract: on Linux and macOS :func:`clock_ns` reads the C library's ``clock_gettime(CLOCK_MONOTONIC)``
from compiled code, elsewhere ``time.perf_counter`` in an ``objmode`` block; only differences of its
readings mean anything.  Callers' numba caches do not track this file: after editing it, clear them.
Design notes: docs/design/host_path.md ("A compiled clock"; numba's cache).
"""

from __future__ import annotations

import sys
import time

import numba
from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic

__all__ = ["clock_ns", "COMPILED_CLOCK"]

#: ``CLOCK_MONOTONIC`` of the platforms whose C library the compiled clock calls
_MONOTONIC = {"linux": 1, "darwin": 6}.get(sys.platform)

#: whether :func:`clock_ns` reads the clock without leaving compiled code
COMPILED_CLOCK = _MONOTONIC is not None


@intrinsic
def _clock_gettime_ns(typingctx):
    """``clock_gettime(CLOCK_MONOTONIC)`` in nanoseconds (``struct timespec``: two 64-bit words)."""

    def codegen(context, builder, sig, args):
        i64, i32 = ir.IntType(64), ir.IntType(32)
        timespec = ir.LiteralStructType([i64, i64])
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(i32, [i32, timespec.as_pointer()]),
                                            "clock_gettime")
        ts = cgutils.alloca_once(builder, timespec)
        builder.call(fn, [ir.Constant(i32, _MONOTONIC), ts])
        sec = builder.load(cgutils.gep_inbounds(builder, ts, 0, 0))
        nsec = builder.load(cgutils.gep_inbounds(builder, ts, 0, 1))
        return builder.add(builder.mul(sec, ir.Constant(i64, 1_000_000_000)), nsec)

    return types.int64(), codegen


if COMPILED_CLOCK:

    @numba.njit(cache=True)
    def clock_ns():
        """Monotonic nanoseconds (compiled code)."""
        return _clock_gettime_ns()

else:  # pragma: no cover - platforms without clock_gettime

    @numba.njit(cache=True)
    def clock_ns():
        """Monotonic nanoseconds (compiled code; an ``objmode`` reading of ``time.perf_counter_ns``)."""
        with numba.objmode(t="int64"):
            t = time.perf_counter_ns()
        return t
