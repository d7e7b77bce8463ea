"""Move kind 2-opt: the segment ``nxt[a] .. b`` of one route reversed (edges ``a -> nxt[a]`` and
``b -> nxt[b]`` become ``a -> b`` and ``nxt[a] -> nxt[b]``)."""

from __future__ import annotations

import numba

from planners.ising.moves.routes import edge, turn

__all__ = ["gain", "apply"]


@numba.njit(cache=True, inline="always")
def gain(d, a, an, b, bn):
    """Route cost saved, ``an = nxt[a]`` and ``bn = nxt[b]`` (-1: the open end)."""
    return d[a, an] + edge(d, b, bn) - d[a, b] - edge(d, an, bn)


@numba.njit(cache=True)
def apply(nxt, prv, a, b):
    an, bn = nxt[a], nxt[b]
    turn(nxt, prv, an, b)
    nxt[a] = b
    prv[b] = a
    nxt[an] = bn
    if bn >= 0:
        prv[bn] = an
