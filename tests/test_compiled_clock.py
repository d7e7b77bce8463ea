"""ising_backend._clock: the compiled loops' monotonic clock measures what Python's clock does."""

import sys
import time

import numba

from ising_backend._clock import COMPILED_CLOCK, clock_ns


@numba.njit(cache=True)
def _span_ns(spin):
    """Readings around a busy loop of ``spin`` steps, and the readings' order."""
    t0 = clock_ns()
    x = 0
    for i in range(spin):
        x ^= i * 2654435761
    t1 = clock_ns()
    return t1 - t0, x


def test_clock_is_monotonic_and_in_nanoseconds():
    assert COMPILED_CLOCK == (sys.platform in ("linux", "darwin"))  # there: clock_gettime, no objmode
    _span_ns(1)
    readings = []
    for _ in range(5):
        outer0 = time.perf_counter_ns()
        inner, _x = _span_ns(3_000_000)
        time.sleep(0.002)
        inner2, _x = _span_ns(10)
        outer = time.perf_counter_ns() - outer0
        readings.append((inner, inner2, outer))
    for inner, inner2, outer in readings:
        assert 0 <= inner <= outer and 0 <= inner2 <= outer
    a = clock_ns()
    time.sleep(0.01)
    b = clock_ns()
    assert 5_000_000 <= b - a <= 5_000_000_000  # a 10 ms sleep, in nanoseconds
