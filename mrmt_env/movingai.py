"""MovingAI benchmark files: ``.map`` grids and ``.scen`` scenarios, read and written.

The format and the letters are documented in ``docs/world_format.md``; files are data only,
refused beyond :data:`~mrmt_env.io.MAX_FILE_BYTES` and :data:`~mrmt_env.generation.MAX_GRID_CELLS`.
``world_from_movingai`` turns a map and scenario rows into a :class:`~mrmt_env.world.World`.
"""

from __future__ import annotations

import heapq
import math
import numbers
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mrmt_env.distances import bfs_distance_field
from mrmt_env.generation import MAX_GRID_CELLS, _largest_component
from mrmt_env.io import _short, grid_from_rows, grid_to_rows, read_text
from mrmt_env.world import World, WorldError

__all__ = ["Scenario", "map_header", "read_movingai_map", "read_movingai_scen", "world_from_movingai", "write_movingai_map",
           "write_movingai_scen", "octile_distance_field"]


def map_header(lines: list[str], path, error=WorldError) -> tuple[dict[str, tuple[int, str]], int]:
    """The header of a MovingAI map's ``lines``: ``({key: (line number, value)}, index of the first map
    row)``; a bad line or no ``map`` line raises ``error`` naming the file and the line."""
    header: dict[str, tuple[int, str]] = {}
    i = 0
    while i < len(lines):
        line = lines[i].strip()
        i += 1
        if not line:
            continue
        if line.lower() == "map":
            return header, i
        parts = line.split(None, 1)
        if len(parts) != 2:
            raise error(f"{path} line {i}: bad header line {_short(line)} (expected 'type octile', 'height H', "
                        "'width W', 'map')")
        header[parts[0].lower()] = (i, parts[1].strip())
    raise error(f"{path}: no 'map' line ending the header")


def read_movingai_map(path) -> np.ndarray:
    """Read a MovingAI ``.map`` file as a bool obstacle grid ``(H, W)``."""
    text = read_text(path, "map file")
    lines = (text[:-1] if text.endswith("\n") else text).split("\n")
    numbered, i = map_header(lines, path)
    header = {key: value for key, (_n, value) in numbered.items()}
    try:
        height = int(header["height"])
        width = int(header["width"])
    except KeyError as exc:
        raise WorldError(f"{path}: header lacks {exc.args[0]!r}") from None
    except ValueError:
        raise WorldError(f"{path}: height/width must be integers, got {_short(header.get('height'), 40)}/"
                         f"{_short(header.get('width'), 40)}") from None
    if height < 1 or width < 1:
        raise WorldError(f"{path}: height and width must be >= 1, got {height}x{width}")
    if height * width > MAX_GRID_CELLS:
        raise WorldError(f"{path}: {height}x{width} = {height * width} cells; a map read from a file may hold at "
                         f"most {MAX_GRID_CELLS} (MAX_GRID_CELLS)")
    rows = lines[i: i + height]
    if len(rows) != height:
        raise WorldError(f"{path}: header says height {height} but the map has {len(rows)} rows")
    for k, row in enumerate(rows):
        if len(row) != width:
            raise WorldError(f"{path}: map row {k} has {len(row)} cells, header says width {width}")
    extra = [n for n, line in enumerate(lines[i + height:], start=i + height + 1) if line.strip()]
    if extra:
        raise WorldError(f"{path} line {extra[0]}: text after the {height} map rows the header announces")
    return grid_from_rows(rows, where=str(path))


@dataclass(frozen=True)
class Scenario:
    """One line of a MovingAI ``.scen`` file (cells as ``(row, col)``)."""

    bucket: int
    map: str
    width: int
    height: int
    start: tuple[int, int]
    goal: tuple[int, int]
    optimal_length_8conn: float

    def bfs_length(self, grid: np.ndarray) -> int:
        """Shortest 4-neighbour path length from start to goal on ``grid``.

        Raises:
            WorldError: the grid's shape is not the scenario's, start or goal
                is on an obstacle, or the goal is unreachable.
        """
        grid = np.asarray(grid, dtype=bool)
        if grid.shape != (self.height, self.width):
            raise WorldError(f"scenario is for a {self.height}x{self.width} map, grid is {grid.shape[0]}x{grid.shape[1]}")
        for name, (r, c) in (("start", self.start), ("goal", self.goal)):
            if not (0 <= r < self.height and 0 <= c < self.width):
                raise WorldError(f"scenario {name} {[r, c]} is out of bounds for a {self.height}x{self.width} map")
            if grid[r, c]:
                raise WorldError(f"scenario {name} {[r, c]} is on an obstacle")
        d = int(bfs_distance_field(grid, self.start)[self.goal])
        if d < 0:
            raise WorldError(f"scenario goal {list(self.goal)} is unreachable from start {list(self.start)}")
        return d


def read_movingai_scen(path) -> list[Scenario]:
    """Read a MovingAI ``.scen`` file (``version`` line optional)."""
    out = []
    for n, line in enumerate(read_text(path, "scenario file").split("\n"), start=1):
        s = line.strip()
        if not s or s.lower().startswith("version"):
            continue
        parts = s.split("\t") if "\t" in s else s.split()
        if len(parts) != 9:
            raise WorldError(f"{path} line {n}: expected 9 columns (bucket map w h sx sy gx gy optimal), got {len(parts)}")
        names = ("bucket", "map", "width", "height", "start_x", "start_y", "goal_x", "goal_y", "optimal_length")
        col = {}
        for k in (0, 2, 3, 4, 5, 6, 7):
            try:
                col[names[k]] = int(parts[k])
            except ValueError:
                raise WorldError(f"{path} line {n}: {names[k]} must be an integer, got {_short(parts[k], 40)}") from None
        bucket, w, h = col["bucket"], col["width"], col["height"]
        sx, sy, gx, gy = col["start_x"], col["start_y"], col["goal_x"], col["goal_y"]
        try:
            opt = float(parts[8])
        except ValueError:
            opt = float("nan")
        if not (np.isfinite(opt) and opt >= 0):
            raise WorldError(f"{path} line {n}: optimal_length must be a finite number >= 0, got {_short(parts[8], 40)}")
        if w < 1 or h < 1:
            raise WorldError(f"{path} line {n}: width and height must be >= 1, got {w}x{h}")
        out.append(Scenario(bucket, parts[1].strip(), w, h, (sy, sx), (gy, gx), opt))
    return out


def world_from_movingai(
    map_path,
    scen_path=None,
    *,
    n_robots: int = 1,
    n_targets: int | None = None,
    robots=None,
    targets=None,
    seed: int | np.random.Generator | None = None,
) -> World:
    """A :class:`World` on a MovingAI map.

    Robots and targets, in order of precedence:

    1. ``robots`` / ``targets`` given explicitly as ``[[row, col], ...]``;
    2. with ``scen_path``: robot ``k`` starts at scenario ``k``'s start and the
       targets are the goals of scenarios ``0 .. n_targets - 1`` (default: as
       many as there are scenarios; a goal repeated in the file is a
       duplicate-target error);
    3. otherwise drawn with ``seed``: uniformly without replacement from the
       largest 4-connected free component (``n_targets`` defaults to 10).
    """
    grid = read_movingai_map(map_path)
    for name, value, low in (("n_robots", n_robots, 1), ("n_targets", n_targets, 0)):
        if value is None and name == "n_targets":
            continue
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral) or value < low:
            raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    scen = None
    if scen_path is not None and (robots is None or targets is None):
        scen = read_movingai_scen(scen_path)
        for s in scen:
            if (s.height, s.width) != grid.shape:
                raise WorldError(
                    f"{scen_path}: scenario for a {s.height}x{s.width} map, {map_path} is {grid.shape[0]}x{grid.shape[1]}"
                )
    if scen is not None:
        if robots is None:
            if n_robots > len(scen):
                raise ValueError(f"n_robots={n_robots} but {scen_path} has only {len(scen)} scenarios")
            robots = [s.start for s in scen[:n_robots]]
        if targets is None:
            k = len(scen) if n_targets is None else n_targets
            if k > len(scen):
                raise ValueError(f"n_targets={k} but {scen_path} has only {len(scen)} scenarios")
            targets = [s.goal for s in scen[:k]]
    if robots is None or targets is None:
        k_t = 10 if n_targets is None else n_targets
        comp = _largest_component(grid)
        cells = np.argwhere(comp)
        need = (n_robots if robots is None else 0) + (k_t if targets is None else 0)
        if need > len(cells):
            raise ValueError(f"need {need} distinct cells but the largest free component of {map_path} has {len(cells)}")
        try:
            rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"seed = {seed!r} is not a numpy seed (None, an integer >= 0 or a Generator): "
                             f"{exc}") from None
        chosen = cells[rng.choice(len(cells), size=need, replace=False)]
        if robots is None:
            robots, chosen = chosen[:n_robots], chosen[n_robots:]
        if targets is None:
            targets = chosen[:k_t]
    return World(grid, np.asarray(robots, dtype=np.int64).reshape(-1, 2), np.asarray(targets, dtype=np.int64).reshape(-1, 2))


def write_movingai_map(grid, path) -> None:
    """Write an obstacle grid as a MovingAI ``.map`` file (``type octile``; ``.`` free, ``@`` obstacle)."""
    grid = np.asarray(grid, dtype=bool)
    rows = grid_to_rows(grid)
    text = f"type octile\nheight {grid.shape[0]}\nwidth {grid.shape[1]}\nmap\n" + "\n".join(rows) + "\n"
    Path(path).write_text(text, encoding="utf-8")


def octile_distance_field(grid, start) -> np.ndarray:
    """``(H, W)`` float64 shortest 8-neighbour path lengths from ``start`` (``inf``: unreachable).

    MovingAI's rule: a straight move costs 1, a diagonal one sqrt(2) and needs
    both cells it passes between free (no corner cutting).
    """
    grid = np.asarray(grid, dtype=bool)
    h, w = grid.shape
    dist = np.full((h, w), np.inf)
    r0, c0 = int(start[0]), int(start[1])
    dist[r0, c0] = 0.0
    heap = [(0.0, r0, c0)]
    steps = [(dr, dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1) if dr or dc]
    while heap:
        d, r, c = heapq.heappop(heap)
        if d > dist[r, c]:
            continue
        for dr, dc in steps:
            nr, nc = r + dr, c + dc
            if not (0 <= nr < h and 0 <= nc < w) or grid[nr, nc]:
                continue
            if dr and dc and (grid[r + dr, c] or grid[r, c + dc]):
                continue
            nd = d + (math.sqrt(2.0) if dr and dc else 1.0)
            if nd < dist[nr, nc]:
                dist[nr, nc] = nd
                heapq.heappush(heap, (nd, nr, nc))
    return dist


def write_movingai_scen(world: World, path, map_name: str) -> None:
    """Write a world's robots and targets as a MovingAI ``.scen`` file that
    :func:`world_from_movingai` reads back (``n_robots=R, n_targets=N``).

    Scenario ``i`` (``max(R, N)`` of them) runs from robot ``i mod R``'s start
    to target ``i`` (``i mod N``; its own start when there are no targets);
    ``optimal_length`` is the 8-neighbour length of :func:`octile_distance_field`
    and ``bucket`` its quarter, rounded down, as in MovingAI's files.
    """
    fields = {}
    lines = ["version 1"]
    for i in range(max(world.n_robots, world.n_targets)):
        start = tuple(int(v) for v in world.robots[i % world.n_robots])
        goal = tuple(int(v) for v in world.targets[i % world.n_targets]) if world.n_targets else start
        if start not in fields:
            fields[start] = octile_distance_field(world.grid, start)
        opt = float(fields[start][goal])
        lines.append("\t".join([str(int(opt // 4)), map_name, str(world.width), str(world.height), str(start[1]),
                                str(start[0]), str(goal[1]), str(goal[0]), f"{opt:.8f}"]))
    Path(path).write_text("\n".join(lines) + "\n", encoding="utf-8")
