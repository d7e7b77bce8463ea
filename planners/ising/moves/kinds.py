"""The move kinds of the tour and the fleet search, one file each, and a move row applied by node.

A move row is ``kind, a, b, c`` (nodes): 2-opt ``a, b`` (:mod:`.two_opt`), or-opt ``a, b, c`` and
its reversed form (:mod:`.or_opt`; the fleet's relocation is a one-node or-opt), swap ``a, b``
(:mod:`.swap`), 2-opt* ``a, b`` (:mod:`.two_opt_star`); ``c`` is -1 where unused.  A new kind is a
file with ``gain`` and ``apply``, an id here, and a place in the neighbourhoods that offer it
(:mod:`.route_moves`, :mod:`.granular`).
"""

from __future__ import annotations

import numba

from planners.ising.moves import or_opt, swap, two_opt, two_opt_star

__all__ = ["MOVE_KINDS", "TWO_OPT", "OR_OPT", "OR_OPT_REVERSED", "SWAP", "TWO_OPT_STAR", "apply_move"]

MOVE_KINDS = ("2-opt", "or-opt", "or-opt reversed", "swap", "2-opt*")
TWO_OPT, OR_OPT, OR_OPT_REVERSED, SWAP, TWO_OPT_STAR = range(len(MOVE_KINDS))


@numba.njit(cache=True)
def apply_move(nxt, prv, kind, a, b, c):
    """Apply one move row by node (the linked lists changed in place)."""
    if kind == TWO_OPT:
        two_opt.apply(nxt, prv, a, b)
    elif kind == OR_OPT or kind == OR_OPT_REVERSED:
        or_opt.apply(nxt, prv, a, b, c, kind == OR_OPT_REVERSED)
    elif kind == SWAP:
        swap.apply(nxt, prv, a, b)
    else:
        two_opt_star.apply(nxt, prv, a, b)
