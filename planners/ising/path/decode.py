"""Decoding of patch samples into local paths, and loop cutting of the committed walk (paper 5.1)."""

from __future__ import annotations

import numpy as np

from planners.ising.path.kernels import extract_path, neighbour_table
from planners.ising.path.qubo import PatchFrame, PatchQubo

__all__ = ["decode_paths", "cut_loops"]


def decode_paths(frame: PatchFrame, problem: PatchQubo, x: np.ndarray) -> list:
    """Decode 0/1 assignments ``x`` (``(S, n)``) into local paths.

    Returns, per sample, the ordered patch-frame cell indices from ``start`` to
    ``goal`` if the selected cells plus the two endpoints form exactly one
    simple 4-connected path (induced: every selected cell has exactly two
    selected 4-neighbours, each endpoint exactly one, and everything is
    reached walking from ``start``), else ``None``.
    """
    x = np.asarray(x).astype(bool)
    x = x.reshape(x.shape[0] if x.ndim > 1 else 1, problem.n)
    nbr = neighbour_table(frame)
    cells = np.asarray(problem.cells, dtype=np.int64)
    out: list = []
    for row in x:
        path = extract_path(row, cells, int(problem.start), int(problem.goal), nbr)
        out.append([int(i) for i in path] if len(path) else None)
    return out


def cut_loops(cells: list) -> list:
    """Remove every closed loop from a walk (cells as ``(r, c)`` tuples): a simple path.

    Walking the robot's own committed walk, a revisit of cell ``c`` drops the
    cells between the two visits.  Every step of the result is a step of the
    walk, so no new move is invented (bookkeeping, not repair).
    """
    out: list = []
    where: dict = {}
    for cell in cells:
        if cell in where:
            k = where[cell]
            for dropped in out[k + 1:]:
                del where[dropped]
            del out[k + 1:]
        else:
            where[cell] = len(out)
            out.append(cell)
    return out

