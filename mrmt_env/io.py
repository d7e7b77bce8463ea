"""World files: JSON and JSON Lines (the MovingAI ``.map`` / ``.scen`` formats: :mod:`mrmt_env.movingai`).

A world is ``{"grid": ["..@.", ...], "robots": [[r, c], ...], "targets": [[r, c], ...]}``; files are data only
(never executed or unpickled) and refused beyond the size limits. Formats: ``docs/world_format.md``; design
notes: docs/design/worlds.md#world-files.
"""

from __future__ import annotations

import json
import numbers
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from mrmt_env.generation import MAX_FIELD_CELLS, MAX_GRID_CELLS
from mrmt_env.world import World, WorldError

__all__ = [
    "PASSABLE",
    "IMPASSABLE",
    "grid_from_rows",
    "grid_to_rows",
    "world_to_dict",
    "world_from_dict",
    "read_world",
    "read_text",
    "iter_worlds_text",
    "example_world_path",
    "MAX_FILE_BYTES",
    "MAX_GRID_CELLS",
    "MAX_FIELD_CELLS",
    "write_world",
    "read_worlds",
    "iter_world_lines",
    "write_worlds",
    "example_map_path",
]

PASSABLE = frozenset(".GS")
IMPASSABLE = frozenset("@OTW")

#: Largest file a reader takes (bytes): world JSON / JSON Lines, MovingAI ``.map`` and ``.scen``.
MAX_FILE_BYTES = 64 * 2**20
# MAX_GRID_CELLS (2**22 cells, 2048 x 2048) and MAX_FIELD_CELLS (2**27 distance-field cells
# (robots + targets) x H x W, 512 MiB of int32) are the generator's limits, shared with world files.


def example_world_path(lines: bool = False) -> Path:
    """An example world file shipped with the package: ``example_world.json`` (one world of the
    paper's set-up: 10x10, 20 obstacles, 3 robots, 10 targets) or, with ``lines=True``,
    ``example_worlds.jsonl`` (five such worlds, the first the same, as JSON Lines)."""
    return Path(__file__).with_name("data") / ("example_worlds.jsonl" if lines else "example_world.json")


def example_map_path(scen: bool = False) -> Path:
    """The MovingAI map shipped with the package: ``warehouse_32x32.map`` (a 32 x 32 warehouse of
    :mod:`mrmt_env.maps`) or, with ``scen=True``, its ``.scen`` (100 scenarios: robots' starts to
    targets, for ``world_from_movingai(map, scen, n_robots=10, n_targets=100)``)."""
    return Path(__file__).with_name("data") / ("warehouse_32x32.scen" if scen else "warehouse_32x32.map")


# --------------------------------------------------------------------- grids
def grid_from_rows(rows, where: str = "grid") -> np.ndarray:
    """Bool obstacle grid from a list of equal-length strings of map letters."""
    if isinstance(rows, str) or not isinstance(rows, (list, tuple)):
        raise WorldError(f"{where} must be a list of strings, got {type(rows).__name__}")
    if len(rows) == 0:
        raise WorldError(f"{where} has no rows")
    first = rows[0]
    if isinstance(first, str) and len(rows) * len(first) > MAX_GRID_CELLS:
        raise WorldError(f"{where} is {len(rows)}x{len(first)} = {len(rows) * len(first)} cells; a grid read from "
                         f"a file may hold at most {MAX_GRID_CELLS} (MAX_GRID_CELLS)")
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


def _cells(d: dict, key: str, shape: tuple[int, int]) -> list:
    value = d[key]
    if not isinstance(value, (list, tuple)):
        raise WorldError(f"{key!r} must be a list of [row, col] pairs, got {type(value).__name__}")
    h, w = shape
    for i, cell in enumerate(value):
        if (
            not isinstance(cell, (list, tuple))
            or len(cell) != 2
            or not all(isinstance(v, numbers.Integral) and not isinstance(v, (bool, np.bool_)) for v in cell)
        ):
            raise WorldError(f"{key!r} entry {i} must be an integer [row, col] pair, got {_short(cell)}")
        r, c = (int(v) for v in cell)
        if not (0 <= r < h and 0 <= c < w):
            raise WorldError(
                f"{key[:-1]} {i} cell [{r}, {c}] is out of bounds for a {h}x{w} grid "
                f"(rows 0..{h - 1}, cols 0..{w - 1})"
            )
    return [[int(v) for v in c] for c in value]


def _short(value, limit: int = 80) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def world_from_dict(d) -> World:
    """Build (and validate) a :class:`World` from a world dict.

    Raises:
        WorldError: not a dict, a missing or unknown key, a malformed grid
            or cell list, a world beyond the file limits
            (:data:`MAX_GRID_CELLS`, :data:`MAX_FIELD_CELLS`), or any
            :class:`World` validation error.
    """
    if not isinstance(d, dict):
        raise WorldError(f"a world must be a JSON object, got {type(d).__name__}")
    missing = [k for k in ("grid", "robots", "targets") if k not in d]
    if missing:
        raise WorldError(f"world object is missing key(s) {missing} (needs 'grid', 'robots', 'targets')")
    extra = sorted(set(d) - {"grid", "robots", "targets"})
    if extra:
        shown = [k if len(k) <= 40 else k[:37] + "..." for k in extra[:5]]
        more = f" and {len(extra) - 5} more" if len(extra) > 5 else ""
        raise WorldError(f"world object has unknown key(s) {shown}{more} (allowed: 'grid', 'robots', 'targets')")
    grid = grid_from_rows(d["grid"])
    robots = _cells(d, "robots", grid.shape)
    targets = _cells(d, "targets", grid.shape)
    nodes = len(robots) + len(targets)
    if nodes * grid.size > MAX_FIELD_CELLS:
        raise WorldError(
            f"{len(robots)} robots + {len(targets)} targets on a {grid.shape[0]}x{grid.shape[1]} grid need "
            f"{nodes * grid.size} distance-field cells; a world read from a file may need at most "
            f"{MAX_FIELD_CELLS} (MAX_FIELD_CELLS)"
        )
    return World(grid, np.array(robots, dtype=np.int64).reshape(-1, 2), np.array(targets, dtype=np.int64).reshape(-1, 2))


def read_text(path, what: str = "world file") -> str:
    """A text file's content (UTF-8, newlines as ``\\n``), at most :data:`MAX_FILE_BYTES` bytes.

    Raises:
        WorldError: the file is larger than the limit or is not UTF-8 text.
        OSError: it cannot be read.
    """
    p = Path(path)
    if p.is_file() and p.stat().st_size > MAX_FILE_BYTES:
        raise WorldError(f"{path}: {p.stat().st_size} bytes; a {what} may hold at most {MAX_FILE_BYTES} bytes "
                         "(MAX_FILE_BYTES)")
    with open(p, "rb") as fh:
        data = fh.read(MAX_FILE_BYTES + 1)
    if len(data) > MAX_FILE_BYTES:
        raise WorldError(f"{path}: more than {MAX_FILE_BYTES} bytes; a {what} may hold at most {MAX_FILE_BYTES} "
                         "bytes (MAX_FILE_BYTES)")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise WorldError(f"{path}: byte {exc.start} ({data[exc.start:exc.start + 1]!r}) is not UTF-8 text; "
                         f"a {what} is UTF-8 text") from None
    return text.replace("\r\n", "\n").replace("\r", "\n")


def _loads(text: str):
    """``json.loads`` whose failures are one ``ValueError`` line each (a decode error keeps its
    position; nesting too deep for the parser and over-long integers are named too)."""
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        raise
    except RecursionError:
        raise ValueError("nested too deeply for the JSON parser") from None
    except ValueError as exc:  # e.g. an integer of more digits than Python converts
        raise ValueError(str(exc).split(";")[0]) from None


def _json_error(where: str, exc: ValueError, line_offset: int = 0) -> WorldError:
    if isinstance(exc, json.JSONDecodeError):
        return WorldError(f"{where} line {exc.lineno + line_offset} column {exc.colno}: not valid JSON ({exc.msg})")
    return WorldError(f"{where}: not valid JSON ({exc})")


def _nonblank(text: str) -> list[tuple[int, str]]:
    return [(n, line) for n, line in enumerate(text.split("\n"), start=1) if line.strip()]


def _line_world(where: str, n: int, line: str) -> World | WorldError:
    try:
        d = _loads(line)
    except ValueError as exc:
        if isinstance(exc, json.JSONDecodeError):
            return WorldError(f"{where} line {n} column {exc.colno}: not valid JSON ({exc.msg})")
        return WorldError(f"{where} line {n}: not valid JSON ({exc})")
    try:
        return world_from_dict(d)
    except WorldError as exc:
        return WorldError(f"{where} line {n}: {exc}")


def _parses_alone(line: str, want_object: bool) -> bool:
    try:
        value = _loads(line)
    except ValueError:
        return False
    return isinstance(value, dict) or not want_object


def iter_worlds_text(text: str, where="worlds") -> Iterator[tuple[int, World | WorldError]]:
    """Yield ``(line_number, World or WorldError)`` for every world of a world file's text.

    The text is one JSON object (it may span lines; line number 1) or JSON
    Lines (one object per non-blank line).  It is JSON Lines when its first
    non-blank line is a JSON value by itself, or when any later line is a
    JSON object by itself; otherwise it is one document, and a parse error
    names the line and column where the parser stopped.  Each bad line of
    JSON Lines is yielded in its place, so a caller can report it and go on.
    """
    lines = _nonblank(text)
    if not lines:
        return
    try:
        whole = _loads(text)
        error = None
    except ValueError as exc:
        whole, error = None, exc
    if error is None:
        if isinstance(whole, dict):
            try:
                yield 1, world_from_dict(whole)
            except WorldError as exc:
                yield 1, WorldError(f"{where}: {exc}")
        elif isinstance(whole, list):
            yield lines[0][0], WorldError(f"{where} line {lines[0][0]}: a JSON array is not a world file; "
                                          "use one object or JSON Lines")
        else:
            yield lines[0][0], WorldError(f"{where} line {lines[0][0]}: a world must be a JSON object, "
                                          f"got {type(whole).__name__}")
        return
    json_lines = len(lines) == 1 or _parses_alone(lines[0][1], want_object=False) or any(
        _parses_alone(line, want_object=True) for _, line in lines[1:])
    if not json_lines:  # one object spread over lines: report where the parser stopped
        yield (error.lineno if isinstance(error, json.JSONDecodeError) else lines[0][0]), _json_error(where, error)
        return
    for n, line in lines:
        yield n, _line_world(where, n, line)


def read_world(path) -> World:
    """Read one world from a JSON file (one object; it may span lines)."""
    text = read_text(path)
    try:
        d = _loads(text)
    except ValueError as exc:
        raise WorldError(f"{_json_error(str(path), exc)}; for JSON Lines use read_worlds") from None
    try:
        return world_from_dict(d)
    except WorldError as exc:
        raise WorldError(f"{path}: {exc}") from None


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
    for n, line in _nonblank(read_text(path)):
        yield n, _line_world(str(path), n, line)


def read_worlds(path) -> list[World]:
    """Read a file holding one JSON world (it may span lines) or JSON Lines of worlds.

    The first bad world raises a :class:`WorldError` naming its line (see
    :func:`iter_worlds_text` for how the two forms are told apart).
    """
    worlds = []
    for _, item in iter_worlds_text(read_text(path), str(path)):
        if isinstance(item, Exception):
            raise item
        worlds.append(item)
    return worlds


def write_worlds(worlds, path) -> None:
    """Write worlds as JSON Lines (one compact object per line)."""
    with open(path, "w", encoding="utf-8") as fh:
        for world in worlds:
            fh.write(json.dumps(world_to_dict(world), separators=(",", ":")) + "\n")

