"""Move kind swap: nodes ``a`` and ``b`` of two routes trade places."""

from __future__ import annotations

import numba

from planners.ising.moves.routes import edge

__all__ = ["gain", "apply"]


@numba.njit(cache=True, inline="always")
def gain(d, pa, a, na, pb, b, nb):
    """Route cost saved (``pa`` / ``na``, ``pb`` / ``nb``: the nodes around ``a`` and ``b``)."""
    old = d[pa, a] + edge(d, a, na) + d[pb, b] + edge(d, b, nb)
    new = d[pa, b] + edge(d, b, na) + d[pb, a] + edge(d, a, nb)
    return old - new


@numba.njit(cache=True)
def apply(nxt, prv, a, b):
    pa, na, pb, nb = prv[a], nxt[a], prv[b], nxt[b]
    nxt[pa] = b
    prv[b] = pa
    nxt[b] = na
    if na >= 0:
        prv[na] = b
    nxt[pb] = a
    prv[a] = pb
    nxt[a] = nb
    if nb >= 0:
        prv[nb] = a
