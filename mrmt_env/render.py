"""Text and image renderers (pure numpy: no display, no pygame).

``ansi``: one character per cell (``@`` obstacle, ``.`` free, ``o`` / ``x`` target unvisited / visited, robots by
index, ``+`` shared); ``rgb_array``: ``(H * cell, W * cell, 3)`` uint8.
Design notes (the legend and colours): docs/design/envs.md#renderers.
"""

from __future__ import annotations

import numpy as np

__all__ = ["robot_char", "render_ansi", "render_rgb", "PALETTE"]

_ROBOT_CHARS = "0123456789abcdefghijklmnopqrstuvwxyz"

#: Robot colours (matplotlib's tab10), by robot index modulo 10.
PALETTE = np.array(
    [
        [31, 119, 180], [255, 127, 14], [44, 160, 44], [214, 39, 40], [148, 103, 189],
        [140, 86, 75], [227, 119, 194], [127, 127, 127], [188, 189, 34], [23, 190, 207],
    ],
    dtype=np.uint8,
)
_FREE = np.array([255, 255, 255], np.uint8)
_LINE = np.array([220, 220, 220], np.uint8)
_OBSTACLE = np.array([60, 60, 60], np.uint8)
_TARGET = np.array([120, 90, 0], np.uint8)
_VISITED = np.array([200, 235, 200], np.uint8)


def robot_char(k: int) -> str:
    return _ROBOT_CHARS[k] if k < len(_ROBOT_CHARS) else "#"


def render_ansi(grid: np.ndarray, targets: np.ndarray, visited, positions: np.ndarray, header: str = "") -> str:
    """The world as text (see the module legend), optionally under a header line."""
    rows = [["@" if b else "." for b in row] for row in np.asarray(grid).tolist()]
    for (r, c), v in zip(np.asarray(targets).tolist(), visited):
        rows[r][c] = "x" if v else "o"
    seen: dict[tuple[int, int], int] = {}
    for k, (r, c) in enumerate(np.asarray(positions).tolist()):
        seen[(r, c)] = seen.get((r, c), 0) + 1
        rows[r][c] = robot_char(k) if seen[(r, c)] == 1 else "+"
    text = "\n".join("".join(row) for row in rows)
    return (header + "\n" + text + "\n") if header else text + "\n"


def render_rgb(grid: np.ndarray, targets: np.ndarray, visited, positions: np.ndarray, cell: int = 16) -> np.ndarray:
    """The world as an RGB image ``(H * cell, W * cell, 3)`` uint8."""
    if int(cell) != cell or cell < 4:
        raise ValueError(f"cell must be an integer >= 4 pixels, got {cell!r}")
    grid = np.asarray(grid, dtype=bool)
    h, w = grid.shape
    img = np.empty((h, w, 3), dtype=np.uint8)
    img[:] = _FREE
    img[grid] = _OBSTACLE
    img = np.repeat(np.repeat(img, cell, axis=0), cell, axis=1)
    lines = np.zeros(img.shape[:2], dtype=bool)
    lines[::cell, :] = True
    lines[:, ::cell] = True
    img[lines & ~np.repeat(np.repeat(grid, cell, axis=0), cell, axis=1)] = _LINE
    m = max(1, cell // 8)
    t = max(1, cell // 8)
    for (r, c), v in zip(np.asarray(targets).tolist(), visited):
        y, x = r * cell, c * cell
        if v:  # visited: pale green cell
            img[y + 1: y + cell, x + 1: x + cell] = _VISITED
        else:  # unvisited: a gold ring around the cell's centre
            img[y + m: y + cell - m, x + m: x + cell - m] = _TARGET
            img[y + m + t: y + cell - m - t, x + m + t: x + cell - m - t] = _FREE
    seen: set[tuple[int, int]] = set()
    q = cell // 4
    for k, (r, c) in enumerate(np.asarray(positions).tolist()):
        y, x = r * cell, c * cell
        if (r, c) in seen:
            d = max(1, cell // 8)
            mid = cell // 2
            img[y + mid - d: y + mid + d, x + mid - d: x + mid + d] = 0
            continue
        seen.add((r, c))
        img[y + q: y + cell - q, x + q: x + cell - q] = PALETTE[k % len(PALETTE)]
    return img
