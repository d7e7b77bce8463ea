"""World files: JSON, JSON Lines, and the MovingAI ``.map`` / ``.scen`` formats.

World JSON (one object)::

    {"grid": ["..@.", "....", ...], "robots": [[r, c], ...], "targets": [[r, c], ...]}

``grid`` rows are strings of equal length.  Passable letters: ``.`` ``G``
``S``; impassable: ``@`` ``O`` ``T`` ``W`` (the MovingAI letters; MovingAI's
swamp ``S`` counts as passable and water ``W`` as impassable because this
model has unit-cost 4-neighbour moves only).  We write ``.`` and ``@``.
A JSON Lines file holds one such object per line (blank lines are skipped).

MovingAI benchmark files (https://movingai.com/benchmarks/formats.html):

* ``.map``: header lines ``type octile``, ``height H``, ``width W``, ``map``,
  then ``H`` rows of ``W`` letters;
* ``.scen``: a ``version`` line, then tab- or space-separated columns
  ``bucket map width height start_x start_y goal_x goal_y optimal_length``
  where ``x`` is the column and ``y`` the row.  The optimal length is for
  8-connected moves with diagonal cost sqrt(2); :meth:`Scenario.bfs_length`
  recomputes it for this model's 4-neighbour moves.
"""

from __future__ import annotations

import json
import numbers
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mrmt_env.distances import bfs_distance_field
from mrmt_env.generation import _largest_component
from mrmt_env.world import World, WorldError

__all__ = [
    "PASSABLE",
    "IMPASSABLE",
    "Scenario",
    "grid_from_rows",
    "grid_to_rows",
    "world_to_dict",
    "world_from_dict",
    "read_world",
    "write_world",
    "read_worlds",
    "iter_world_lines",
    "write_worlds",
    "read_movingai_map",
    "read_movingai_scen",
    "world_from_movingai",
]

PASSABLE = frozenset(".GS")
IMPASSABLE = frozenset("@OTW")


# --------------------------------------------------------------------- grids
def grid_from_rows(rows, where: str = "grid") -> np.ndarray:
    """Bool obstacle grid from a list of equal-length strings of map letters."""
    if isinstance(rows, str) or not isinstance(rows, (list, tuple)):
        raise WorldError(f"{where} must be a list of strings, got {type(rows).__name__}")
    if len(rows) == 0:
        raise WorldError(f"{where} has no rows")
    width = None
    out = []
    for i, row in enumerate(rows):
        if not isinstance(row, str):
            raise WorldError(f"{where} row {i} must be a string, got {type(row).__name__}")
        if width is None:
            width = len(row)
            if width == 0:
                raise WorldError(f"{where} row 0 is empty")
        elif len(row) != width:
            raise WorldError(f"{where} row {i} has {len(row)} cells, row 0 has {width}")
        cells = []
        for j, ch in enumerate(row):
            if ch in PASSABLE:
                cells.append(False)
            elif ch in IMPASSABLE:
                cells.append(True)
            else:
                raise WorldError(
                    f"{where} row {i} col {j}: unknown cell letter {ch!r} "
                    f"(passable {''.join(sorted(PASSABLE))!r}, impassable {''.join(sorted(IMPASSABLE))!r})"
                )
        out.append(cells)
    return np.array(out, dtype=bool)


def grid_to_rows(grid: np.ndarray) -> list[str]:
    """``['..@.', ...]``: ``.`` free, ``@`` obstacle."""
    return ["".join("@" if b else "." for b in row) for row in np.asarray(grid, dtype=bool).tolist()]


# ---------------------------------------------------------------- JSON worlds
def world_to_dict(world: World) -> dict:
    """``{"grid": [...], "robots": [[r, c], ...], "targets": [[r, c], ...]}`` (JSON-ready)."""
    return {
        "grid": grid_to_rows(world.grid),
        "robots": world.robots.tolist(),
        "targets": world.targets.tolist(),
    }


def _cells(d: dict, key: str) -> list:
    value = d[key]
    if not isinstance(value, (list, tuple)):
        raise WorldError(f"{key!r} must be a list of [row, col] pairs, got {type(value).__name__}")
    for i, cell in enumerate(value):
        if (
            not isinstance(cell, (list, tuple))
            or len(cell) != 2
            or not all(isinstance(v, numbers.Integral) and not isinstance(v, (bool, np.bool_)) for v in cell)
        ):
            raise WorldError(f"{key!r} entry {i} must be an integer [row, col] pair, got {cell!r}")
    return [list(c) for c in value]


def world_from_dict(d) -> World:
    """Build (and validate) a :class:`World` from a world dict.

    Raises:
        WorldError: not a dict, a missing or unknown key, a malformed grid
            or cell list, or any :class:`World` validation error.
    """
    if not isinstance(d, dict):
        raise WorldError(f"a world must be a JSON object, got {type(d).__name__}")
    missing = [k for k in ("grid", "robots", "targets") if k not in d]
    if missing:
        raise WorldError(f"world object is missing key(s) {missing} (needs 'grid', 'robots', 'targets')")
    extra = sorted(set(d) - {"grid", "robots", "targets"})
    if extra:
        raise WorldError(f"world object has unknown key(s) {extra} (allowed: 'grid', 'robots', 'targets')")
    grid = grid_from_rows(d["grid"])
    robots = _cells(d, "robots")
    targets = _cells(d, "targets")
    return World(grid, np.array(robots, dtype=np.int64).reshape(-1, 2), np.array(targets, dtype=np.int64).reshape(-1, 2))


def read_world(path) -> World:
    """Read one world from a JSON file."""
    text = Path(path).read_text(encoding="utf-8")
    try:
        d = json.loads(text)
    except json.JSONDecodeError as exc:
        raise WorldError(f"{path}: not valid JSON ({exc}); for JSON Lines use read_worlds") from exc
    try:
        return world_from_dict(d)
    except WorldError as exc:
        raise WorldError(f"{path}: {exc}") from exc


def write_world(world: World, path) -> None:
    """Write one world as a JSON object (grid rows one per line)."""
    d = world_to_dict(world)
    body = ",\n".join(f'    "{row}"' for row in d["grid"])
    text = (
        '{\n  "grid": [\n' + body + "\n  ],\n"
        f'  "robots": {json.dumps(d["robots"])},\n'
        f'  "targets": {json.dumps(d["targets"])}\n}}\n'
    )
    Path(path).write_text(text, encoding="utf-8")


def iter_world_lines(path) -> Iterator[tuple[int, World | Exception]]:
    """Yield ``(line_number, World or the exception)`` for each non-blank line
    of a JSON Lines file (1-based numbers), so a caller can report a bad line
    and go on with the rest."""
    with open(path, encoding="utf-8") as fh:
        for n, line in enumerate(fh, start=1):
            if not line.strip():
                continue
            try:
                d = json.loads(line)
            except json.JSONDecodeError as exc:
                yield n, WorldError(f"{path} line {n}: not valid JSON ({exc})")
                continue
            try:
                yield n, world_from_dict(d)
            except WorldError as exc:
                yield n, WorldError(f"{path} line {n}: {exc}")


def read_worlds(path) -> list[World]:
    """Read a file holding one JSON world or JSON Lines of worlds.

    A file that parses as one JSON object is one world; otherwise each
    non-blank line must be a world.  The first bad line raises a
    :class:`WorldError` naming it (use :func:`iter_world_lines` to skip bad lines).
    """
    text = Path(path).read_text(encoding="utf-8")
    try:
        d = json.loads(text)
    except json.JSONDecodeError:
        d = None
    if isinstance(d, dict):
        try:
            return [world_from_dict(d)]
        except WorldError as exc:
            raise WorldError(f"{path}: {exc}") from exc
    if isinstance(d, list):
        raise WorldError(f"{path}: a JSON array is not a world file; use one object or JSON Lines")
    worlds = []
    for _, item in iter_world_lines(path):
        if isinstance(item, Exception):
            raise item
        worlds.append(item)
    return worlds


def write_worlds(worlds, path) -> None:
    """Write worlds as JSON Lines (one compact object per line)."""
    with open(path, "w", encoding="utf-8") as fh:
        for world in worlds:
            fh.write(json.dumps(world_to_dict(world), separators=(",", ":")) + "\n")


# ------------------------------------------------------------------- MovingAI
def read_movingai_map(path) -> np.ndarray:
    """Read a MovingAI ``.map`` file as a bool obstacle grid ``(H, W)``."""
    lines = Path(path).read_text(encoding="utf-8").splitlines()
    header: dict[str, str] = {}
    i = 0
    while i < len(lines):
        line = lines[i].strip()
        i += 1
        if not line:
            continue
        if line.lower() == "map":
            break
        parts = line.split(None, 1)
        if len(parts) != 2:
            raise WorldError(f"{path} line {i}: bad header line {line!r} (expected 'type', 'height', 'width', 'map')")
        header[parts[0].lower()] = parts[1].strip()
    else:
        raise WorldError(f"{path}: no 'map' line ending the header")
    try:
        height = int(header["height"])
        width = int(header["width"])
    except KeyError as exc:
        raise WorldError(f"{path}: header lacks {exc.args[0]!r}") from exc
    except ValueError as exc:
        raise WorldError(f"{path}: height/width must be integers, got {header.get('height')!r}/{header.get('width')!r}") from exc
    if height < 1 or width < 1:
        raise WorldError(f"{path}: height and width must be >= 1, got {height}x{width}")
    rows = [ln.rstrip("\r\n") for ln in lines[i: i + height]]
    if len(rows) != height:
        raise WorldError(f"{path}: header says height {height} but the map has {len(rows)} rows")
    for k, row in enumerate(rows):
        if len(row) != width:
            raise WorldError(f"{path}: map row {k} has {len(row)} cells, header says width {width}")
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
    with open(path, encoding="utf-8") as fh:
        for n, line in enumerate(fh, start=1):
            s = line.strip()
            if not s or s.lower().startswith("version"):
                continue
            parts = s.split("\t") if "\t" in s else s.split()
            if len(parts) != 9:
                raise WorldError(f"{path} line {n}: expected 9 columns (bucket map w h sx sy gx gy optimal), got {len(parts)}")
            try:
                bucket, w, h, sx, sy, gx, gy = (int(parts[k]) for k in (0, 2, 3, 4, 5, 6, 7))
                opt = float(parts[8])
            except ValueError as exc:
                raise WorldError(f"{path} line {n}: non-numeric column ({exc})") from exc
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
    if n_robots < 1:
        raise ValueError(f"n_robots must be >= 1, got {n_robots}")
    if n_targets is not None and n_targets < 0:
        raise ValueError(f"n_targets must be >= 0, got {n_targets}")
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
        rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        chosen = cells[rng.choice(len(cells), size=need, replace=False)]
        if robots is None:
            robots, chosen = chosen[:n_robots], chosen[n_robots:]
        if targets is None:
            targets = chosen[:k_t]
    return World(grid, np.asarray(robots, dtype=np.int64).reshape(-1, 2), np.asarray(targets, dtype=np.int64).reshape(-1, 2))
