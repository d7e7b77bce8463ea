"""Move kind 2-opt*: the tails after node ``a`` and after node ``b`` (two routes) swap."""

from __future__ import annotations

import numba

from planners.ising.moves.routes import edge

__all__ = ["gain", "apply"]


@numba.njit(cache=True, inline="always")
def gain(d, a, an, b, bn):
    """Route cost saved, ``an = nxt[a]``, ``bn = nxt[b]`` (-1: the open end)."""
    return edge(d, a, an) + edge(d, b, bn) - edge(d, a, bn) - edge(d, b, an)


@numba.njit(cache=True)
def apply(nxt, prv, a, b):
    an, bn = nxt[a], nxt[b]
    nxt[a] = bn
    if bn >= 0:
        prv[bn] = a
    nxt[b] = an
    if an >= 0:
        prv[an] = b
