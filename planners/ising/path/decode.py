"""Decoding of patch samples into local paths (paper 5.1): :func:`~.kernels.extract_path` per sample."""

from __future__ import annotations

import numpy as np

from planners.ising.path.kernels import extract_path, neighbour_table
from planners.ising.path.qubo import PatchFrame, PatchQubo

__all__ = ["decode_paths"]


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
