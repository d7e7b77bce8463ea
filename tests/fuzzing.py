"""Shared pieces of the fuzz tests: the budget, a hang guard and junk values."""

from __future__ import annotations

import contextlib
import os
import signal

import numpy as np
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import array_shapes, arrays

_SUPPRESS = [HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much]


def fuzz_settings(examples: int):
    """A modest budget (``examples``) in the normal suite; under ``HYPOTHESIS_PROFILE=fuzz`` the profile's."""
    if os.environ.get("HYPOTHESIS_PROFILE") == "fuzz":
        return settings(deadline=None, suppress_health_check=_SUPPRESS)
    return settings(max_examples=examples, deadline=None, suppress_health_check=_SUPPRESS)


@contextlib.contextmanager
def no_hang(seconds: float = 60.0):
    """Fail (``TimeoutError``) instead of hanging when one example runs longer than ``seconds``."""
    if not hasattr(signal, "setitimer"):  # pragma: no cover - not POSIX
        yield
        return

    def _alarm(signum, frame):
        raise TimeoutError(f"example ran longer than {seconds} s")

    old = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def one_line(exc: BaseException) -> str:
    """The exception's message, asserted to be one non-empty line."""
    msg = str(exc)
    assert msg and "\n" not in msg, repr(msg)
    return msg


_DTYPES = st.sampled_from([np.int8, np.int16, np.int64, np.uint8, np.uint64, np.float32, np.float64, np.bool_,
                           np.complex64, "U3", object])


def _array(dtype):
    elements = {
        object: st.one_of(st.integers(-(2**70), 2**70), st.none(), st.text(max_size=2), st.floats()),
        "U3": st.text(st.characters(blacklist_characters="\x00"), max_size=3),
    }.get(dtype)
    return arrays(dtype, array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=4), elements=elements)


#: Values that are not a good action, index or count anywhere (and a few that are, by chance).
junk = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(2**70), 2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=4),
    st.lists(st.one_of(st.integers(-10, 10), st.floats(), st.booleans(), st.none()), max_size=5),
    st.lists(st.lists(st.integers(-3, 6), max_size=3), max_size=3),
    st.dictionaries(st.text(max_size=3), st.integers(), max_size=2),
    _DTYPES.flatmap(_array),
)
