"""Move kind or-opt: the segment ``a .. b`` of a route (one node when ``a == b``: a relocation), reversed
or not, moved to right after node ``c`` (on its route or another); ``c`` is outside the segment and
not the node before it."""

from __future__ import annotations

import numba

from planners.ising.moves.routes import edge, insert_after, turn, unlink

__all__ = ["gain", "apply"]


@numba.njit(cache=True, inline="always")
def gain(d, pa, a, b, nb, c, cn, rev):
    """Route cost saved, ``pa = prv[a]``, ``nb = nxt[b]``, ``cn = nxt[c]`` (-1: the open end)."""
    first, last = (b, a) if rev else (a, b)
    return d[pa, a] + edge(d, b, nb) - edge(d, pa, nb) + edge(d, c, cn) - d[c, first] - edge(d, last, cn)


@numba.njit(cache=True)
def apply(nxt, prv, a, b, c, rev):
    unlink(nxt, prv, a, b)
    if rev:
        turn(nxt, prv, a, b)
        insert_after(nxt, prv, b, a, c)
    else:
        insert_after(nxt, prv, a, b, c)
