"""One choice per robot on an Ising chip: a reference option as all spins down (at-most-one encoding).

:func:`reduce_to_reference` substitutes each robot's reference option by ``1 - sum of its other options`` (the
reference takes no spin; ``amo`` keeps at most one spin up); :func:`read_option` and :func:`read_choices` decode
reads of the reduced program.
Design notes: docs/design/lifelong_turning.md#one-choice-per-robot-the-reference-reduction.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["reduce_to_reference", "reduced_index", "read_option", "read_choices"]


@numba.njit(cache=True, nogil=True, inline="always")
def reduced_index(starts, ref, t, x) -> int:
    """Spin of local option ``x`` of robot ``t`` (``starts[t] <= x < starts[t + 1]``, not its reference) in the
    reduced program; -1 for the reference."""
    r = starts[t] + ref[t]
    if x == r:
        return -1
    return x - t - (1 if x > r else 0)


@numba.njit(cache=True, nogil=True, inline="always")
def _coef(starts, ref, t, x, w) -> int:
    """Option ``x`` of robot ``t`` as a sum over the reduced spins: the coefficient of option ``w``'s spin
    (``x`` itself for an option with a spin; ``1 - `` the robot's other options for its reference)."""
    if starts[t] + ref[t] != x:
        return 1 if w == x else 0
    return 0 if w == x else -1


@numba.njit(cache=True, nogil=True)
def reduce_to_reference(q, starts, ref, amo, out) -> int:
    """``out[:m, :m]`` (upper triangular, ``m`` returned: the options less one per robot) from the one-hot
    objective ``q[:n, :n]`` (upper triangular, no one-hot penalty; ``n = starts[-1]``), robot ``t``'s options
    ``starts[t]:starts[t + 1]``, its reference option ``starts[t] + ref[t]`` as all its spins down, ``amo`` on
    each pair of one robot's spins.  On a one-hot assignment ``x`` (reduced: ``y``) ``y out y`` equals
    ``x q x`` minus the objective of the all-reference assignment; pairs of one robot's options in ``q`` (a
    one-hot assignment never sets two) are left out.  Each option is written as a sum over the spins
    (:func:`_coef`: constant 1 for a reference) and every term of ``q`` expanded; constants are dropped."""
    size = starts.shape[0] - 1
    n = starts[size]
    m = n - size
    out[:m, :m] = 0
    t = 0
    for x in range(n):
        while x >= starts[t + 1]:
            t += 1
        cx = 1 if starts[t] + ref[t] == x else 0
        for w in range(starts[t], starts[t + 1]):  # the linear term
            a = _coef(starts, ref, t, x, w)
            if a != 0:
                sw = reduced_index(starts, ref, t, w)
                out[sw, sw] += a * q[x, x]
        t2 = t
        for y in range(x + 1, n):
            while y >= starts[t2 + 1]:
                t2 += 1
            v = q[x, y]
            if v == 0 or t2 == t:
                continue
            cy = 1 if starts[t2] + ref[t2] == y else 0
            for w in range(starts[t], starts[t + 1]):  # v (cx + sum a_w) (cy + sum b_u)
                a = _coef(starts, ref, t, x, w)
                if a == 0:
                    continue
                sw = reduced_index(starts, ref, t, w)
                out[sw, sw] += v * a * cy
                for u in range(starts[t2], starts[t2 + 1]):
                    b = _coef(starts, ref, t2, y, u)
                    if b != 0:
                        su = reduced_index(starts, ref, t2, u)
                        out[min(sw, su), max(sw, su)] += v * a * b
            if cx:
                for u in range(starts[t2], starts[t2 + 1]):
                    b = _coef(starts, ref, t2, y, u)
                    if b != 0:
                        su = reduced_index(starts, ref, t2, u)
                        out[su, su] += v * b
    for t in range(size):
        for x in range(starts[t], starts[t + 1]):
            sx = reduced_index(starts, ref, t, x)
            if sx < 0:
                continue
            for y in range(x + 1, starts[t + 1]):
                sy = reduced_index(starts, ref, t, y)
                if sy >= 0:
                    out[sx, sy] += amo
    return m


@numba.njit(cache=True, nogil=True)
def read_option(read, starts, ref, t) -> int:
    """Robot ``t``'s local option in a read of the reduced program: its one spin up, its reference when none
    is; -1 when more than one is."""
    pick = ref[t]
    cnt = 0
    for x in range(starts[t], starts[t + 1]):
        s = reduced_index(starts, ref, t, x)
        if s >= 0 and read[s] > 0:
            cnt += 1
            pick = x - starts[t]
    return -1 if cnt > 1 else pick


@numba.njit(cache=True, nogil=True)
def read_choices(spins, starts):
    """``(reads, robots)`` local options of the reads ``spins`` of a program whose every robot's reference is its
    option 0 (robot ``t``'s options ``starts[t]:starts[t + 1]``): a robot with no spin up, or more than one, on 0."""
    size = starts.shape[0] - 1
    ref = np.zeros(size, dtype=np.int64)
    out = np.empty((spins.shape[0], size), dtype=np.int64)
    for rd in range(spins.shape[0]):
        for t in range(size):
            out[rd, t] = max(0, read_option(spins[rd], starts, ref, t))
    return out
