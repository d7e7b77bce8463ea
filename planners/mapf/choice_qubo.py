"""One choice per robot on an Ising chip: a reference option as all spins down (at-most-one encoding).

A group decision in which each robot takes one of its options is written first as a QUBO over one binary
per option with no constraint: its energy on a one-hot assignment is the decision's objective.  With one
spin per option and a one-hot penalty, a chip of few levels spends them on the constraint: in Ising form the
penalty over ``k`` options puts a field of ``(k - 2)`` times its coupling on every spin, every pairwise term
adds to both spins' fields, and the largest field sets the scale (measured on ``lns_groups``:
docs/design/lifelong_turning.md).  :func:`reduce_to_reference` substitutes each robot's *reference* option
(the host rule's answer, or the plan now) by ``1 - sum of its other options``: the reference takes no spin,
the objective changes by a constant on every one-hot assignment, and ``amo`` on each pair of one robot's
spins keeps at most one up.  :func:`read_option` decodes a robot in a read of the reduced program.
"""

from __future__ import annotations

import numba

__all__ = ["reduce_to_reference", "reduced_index", "read_option"]


@numba.njit(cache=True, nogil=True, inline="always")
def reduced_index(starts, ref, t, x) -> int:
    """Spin of local option ``x`` of robot ``t`` (``starts[t] <= x < starts[t + 1]``, not its reference) in the
    reduced program; -1 for the reference."""
    r = starts[t] + ref[t]
    if x == r:
        return -1
    return x - t - (1 if x > r else 0)


@numba.njit(cache=True, nogil=True)
def reduce_to_reference(q, starts, ref, amo, out) -> int:
    """``out[:m, :m]`` (upper triangular, ``m`` returned: the options less one per robot) from the one-hot
    objective ``q[:n, :n]`` (upper triangular, no one-hot penalty; ``n = starts[-1]``), robot ``t``'s options
    ``starts[t]:starts[t + 1]``, its reference option ``starts[t] + ref[t]`` as all its spins down, ``amo`` on
    each pair of one robot's spins.  On a one-hot assignment ``x`` (reduced: ``y``) ``y out y`` equals
    ``x q x`` minus the objective of the all-reference assignment; pairs of one robot's options in ``q`` (a
    one-hot assignment never sets two) are left out."""
    size = starts.shape[0] - 1
    n = starts[size]
    m = n - size
    out[:m, :m] = 0
    rob = 0
    for x in range(n):
        while x >= starts[rob + 1]:
            rob += 1
        sx = reduced_index(starts, ref, rob, x)
        # linear term of option x: on its spin, or (x the reference) minus it on each other option's spin
        if sx >= 0:
            out[sx, sx] += q[x, x]
        else:
            for w in range(starts[rob], starts[rob + 1]):
                sw = reduced_index(starts, ref, rob, w)
                if sw >= 0:
                    out[sw, sw] -= q[x, x]
        rob2 = rob
        for y in range(x + 1, n):
            while y >= starts[rob2 + 1]:
                rob2 += 1
            v = q[x, y]
            if v == 0 or rob2 == rob:
                continue
            sy = reduced_index(starts, ref, rob2, y)
            if sx >= 0 and sy >= 0:
                out[min(sx, sy), max(sx, sy)] += v
                continue
            # one or both references: x_ref = 1 - sum of the robot's other options
            fx_lo, fx_hi = (starts[rob], starts[rob + 1]) if sx < 0 else (x, x + 1)
            fy_lo, fy_hi = (starts[rob2], starts[rob2 + 1]) if sy < 0 else (y, y + 1)
            if sx < 0 and sy < 0:  # v (1 - X)(1 - Y): -v X - v Y + v X Y
                for w in range(fx_lo, fx_hi):
                    sw = reduced_index(starts, ref, rob, w)
                    if sw >= 0:
                        out[sw, sw] -= v
                for w in range(fy_lo, fy_hi):
                    sw = reduced_index(starts, ref, rob2, w)
                    if sw >= 0:
                        out[sw, sw] -= v
                sign = 1
            else:  # v (1 - X) y: v y - v X y
                keep = sy if sx < 0 else sx
                out[keep, keep] += v
                sign = -1
            for w in range(fx_lo, fx_hi):
                sw = reduced_index(starts, ref, rob, w) if sx < 0 else sx
                if sw < 0:
                    continue
                for u in range(fy_lo, fy_hi):
                    su = reduced_index(starts, ref, rob2, u) if sy < 0 else sy
                    if su >= 0:
                        out[min(sw, su), max(sw, su)] += sign * v
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
