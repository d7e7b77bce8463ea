"""The MAPF_T action model of the League of Robot Runners (start kit ``src/ActionModel.cpp``).

A robot is a flat cell and an orientation (0 east, 1 south, 2 west, 3 north).  Actions:
:data:`FORWARD` (one cell ahead), :data:`CLOCKWISE`, :data:`COUNTER` (turn in place),
:data:`WAIT`.  A joint action is valid when no robot leaves the map (a row end does not wrap)
or enters a blocked cell, no two robots end in one cell, and no two robots swap cells.  The
first offending robot in index order is reported as the start kit reports it (one error per
step: ``(message, robot, other robot or -1)``).  Vectorised numpy, O(R log R) per step.
"""

from __future__ import annotations

import numpy as np

__all__ = ["FORWARD", "CLOCKWISE", "COUNTER", "WAIT", "TIMEOUT", "ACTION_LETTERS", "ORIENT_LETTERS", "N_ACTIONS",
           "ACTION_MODELS", "n_actions", "next_states", "next_cells_four", "first_error", "parse_actions"]

FORWARD, CLOCKWISE, COUNTER, WAIT = 0, 1, 2, 3
#: A step the entry's decision was late for (start kit ``Action::NA``, written ``T``): the robot does not move.
TIMEOUT = -1
N_ACTIONS = 4
#: ``MAPF_T`` (the rules) or ``MAPF`` (the package's four-direction model: 0 stay, 1 up, 2 down,
#: 3 left, 4 right, orientation unused; the same conflicts).
ACTION_MODELS = ("MAPF_T", "MAPF")
#: Output letters of the actions (start kit ``actualPaths``), :data:`TIMEOUT` last (``T``).
ACTION_LETTERS = "FRCWT"
#: Orientation letters of the output's ``start`` (0 east, 1 south, 2 west, 3 north).
ORIENT_LETTERS = "ESWN"


def next_states(pos: np.ndarray, orient: np.ndarray, actions: np.ndarray, width: int):
    """``(next_pos, next_orient)`` before any validity check; a forward move off a row end or off
    the map gives a cell that :func:`first_error` refuses (``-1`` past the top or bottom)."""
    fw = actions == FORWARD
    step = np.array([1, width, -1, -width], dtype=np.int64)[orient]
    nxt = np.where(fw, pos + step, pos)
    col = pos % width
    off = fw & (((orient == 0) & (col == width - 1)) | ((orient == 2) & (col == 0)))
    nxt = np.where(off, -1, nxt)
    turn = np.where(actions == CLOCKWISE, 1, np.where(actions == COUNTER, 3, 0))
    return nxt, (orient + turn) % 4


def n_actions(model: str) -> int:
    """Actions per robot of an action model."""
    if model not in ACTION_MODELS:
        raise ValueError(f"action_model must be one of {', '.join(ACTION_MODELS)}, got {model!r}")
    return N_ACTIONS if model == "MAPF_T" else 5


def next_cells_four(pos: np.ndarray, actions: np.ndarray, width: int) -> np.ndarray:
    """The four-direction model's next cells (``-1`` for a move off a row end or the top)."""
    step = np.array([0, -width, width, -1, 1], dtype=np.int64)[actions]
    col = pos % width
    off = ((actions == 3) & (col == 0)) | ((actions == 4) & (col == width - 1))
    return np.where(off, -1, pos + step)


def first_error(pos: np.ndarray, nxt: np.ndarray, blocked: np.ndarray):
    """The start kit's first error of a joint move ``pos -> nxt`` (flat cells; ``blocked`` the flat
    grid), or ``None``: ``("unallowed move", i, -1)``, ``("vertex conflict", i, j)``,
    ``("edge conflict", i, j)`` with ``j < i`` the robot met first."""
    r = len(pos)
    n = blocked.shape[0]
    idx = np.arange(r)
    bad = (nxt < 0) | (nxt >= n)
    bad[~bad] = blocked[nxt[~bad]]
    # vertex: an earlier robot ends in the same cell
    order = np.argsort(nxt, kind="stable")
    sorted_next = nxt[order]
    starts = np.r_[True, sorted_next[1:] != sorted_next[:-1]]
    first_of_run = order[np.maximum.accumulate(np.where(starts, np.arange(r), 0))]
    holder = np.empty(r, dtype=np.int64)
    holder[order] = first_of_run
    vertex = holder < idx
    # edge: an earlier robot went nxt_i -> pos_i (the start kit keys edges by (next, prev))
    keys = nxt * n + pos
    query = pos * n + nxt
    korder = np.argsort(keys, kind="stable")
    skeys = keys[korder]
    at = np.searchsorted(skeys, query)
    found = (at < r) & (skeys[np.minimum(at, r - 1)] == query) & (pos != nxt)
    other = np.where(found, korder[np.minimum(at, r - 1)], r)
    edge = found & (other < idx)
    fail = bad | vertex | edge
    if not fail.any():
        return None
    i = int(np.argmax(fail))
    if bad[i]:
        return ("unallowed move", i, -1)
    if vertex[i]:
        return ("vertex conflict", i, int(holder[i]))
    return ("edge conflict", i, int(other[i]))


def parse_actions(text: str, where: str) -> np.ndarray:
    """One robot's ``actualPaths`` string (``F,R,C,W,T``) as action codes (``T``: :data:`TIMEOUT`)."""
    if not text:
        return np.zeros(0, dtype=np.int8)
    letters = text.split(",")
    table = {"F": FORWARD, "R": CLOCKWISE, "C": COUNTER, "W": WAIT, "T": TIMEOUT}
    out = np.empty(len(letters), dtype=np.int8)
    for k, a in enumerate(letters):
        code = table.get(a.strip())
        if code is None:
            raise ValueError(f"{where}: action {k} is {a[:10]!r}; actions are F, R, C, W (or T)")
        out[k] = code
    return out
