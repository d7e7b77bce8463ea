"""League of Robot Runners instances (2023 and 2024): the JSON, the map, the agents and the task file.

Contract: :func:`read_instance` ``(path) -> LoRRInstance``; every problem in the data is one
:class:`LoRRFormatError` (a ``ValueError``) naming the file and line. Data only: nothing in a file is executed.
Design notes (the rules as the start kit reads them): docs/design/lorr_simulator.md#instances.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mrmt_env.generation import MAX_GRID_CELLS
from mrmt_env.io import read_text
from mrmt_env.movingai import map_header
from mrmt_env.world import WorldError

__all__ = ["LoRRInstance", "LoRRFormatError", "read_instance", "read_lorr_map", "example_instance_path",
           "ASSIGNMENT_STRATEGIES"]

#: 2023 system assignments this package runs (``taskAssignmentStrategy``).
ASSIGNMENT_STRATEGIES = ("roundrobin",)
_BLOCKED = frozenset("@T")


class LoRRFormatError(ValueError):
    """A LoRR instance file that cannot be read (the message names the file and line)."""


@dataclass(frozen=True, eq=False)
class LoRRInstance:
    """One LoRR instance.

    Attributes:
        name: the JSON's stem (``RANDOM-01``), the key of the best-known tables.
        grid: ``(H, W)`` bool, True = blocked.
        starts: ``(R,)`` int64 flat start cells (``row * W + col``); every robot faces east.
        errands: all tasks' errands back to back, int64 flat cells; task ``i`` of the file is
            ``errands[offsets[i]:offsets[i + 1]]``.
        offsets: ``(T + 1,)`` int64.
        reveal: ``numTasksReveal`` (2024: open tasks = reveal x teamSize; 2023: tasks known per robot).
        strategy: ``None`` (2024: a scheduler assigns) or the 2023 ``taskAssignmentStrategy``.
        steps: the instance's simulation time when a ``simulation_time.json`` beside it names it.
    """

    name: str
    path: Path
    grid: np.ndarray
    starts: np.ndarray
    errands: np.ndarray
    offsets: np.ndarray
    reveal: float
    strategy: str | None = None
    version: str = "2024 LoRR"
    steps: int | None = None
    map_name: str = ""
    meta: dict = field(default_factory=dict)

    @property
    def team_size(self) -> int:
        return int(len(self.starts))

    @property
    def n_tasks(self) -> int:
        """Task lines in the file (the file is read cyclically)."""
        return int(len(self.offsets) - 1)

    @property
    def width(self) -> int:
        return int(self.grid.shape[1])

    @property
    def height(self) -> int:
        return int(self.grid.shape[0])

    @property
    def max_errands(self) -> int:
        return int(np.diff(self.offsets).max())

    def task_errands(self, i: int) -> np.ndarray:
        """Errands of task line ``i % n_tasks`` (flat cells, in order)."""
        i %= self.n_tasks
        return self.errands[self.offsets[i]:self.offsets[i + 1]]

    def open_target(self) -> int:
        """2024: how many tasks are kept open: ``reveal x teamSize`` as the start kit stores it (an ``int`` set from
        the ``float`` product, so truncated: 1.3 x 8 keeps 10 open)."""
        return int(np.float32(self.reveal) * np.float32(self.team_size))


def example_instance_path() -> Path:
    """A small LoRR 2024 instance shipped with the package (8 robots on a 12 x 12 map)."""
    return Path(__file__).resolve().parent.parent / "data" / "lorr" / "EXAMPLE-01.json"


def _lines(path: Path, what: str) -> list[str]:
    try:
        text = read_text(path, what)
    except FileNotFoundError:
        raise LoRRFormatError(f"{path}: no such {what}") from None
    except (OSError, WorldError) as exc:
        raise LoRRFormatError(f"{path}: {exc}") from None
    return text.split("\n")


def read_lorr_map(path) -> np.ndarray:
    """A MovingAI map as the start kit reads it: ``(H, W)`` bool, ``@`` and ``T`` blocked."""
    path = Path(path)
    lines = _lines(path, "map file")
    header, i = map_header(lines, path, LoRRFormatError)
    dims = []
    for key in ("height", "width"):
        if key not in header:
            raise LoRRFormatError(f"{path}: the header has no {key!r} line")
        n, value = header[key]
        if not value.isdigit() or int(value) < 1:
            raise LoRRFormatError(f"{path} line {n}: {key} must be an integer >= 1, got {value[:40]!r}")
        dims.append(int(value))
    height, width = dims
    if height * width > MAX_GRID_CELLS:
        raise LoRRFormatError(f"{path}: {height}x{width} = {height * width} cells; at most {MAX_GRID_CELLS} "
                              "(MAX_GRID_CELLS)")
    while len(lines) > i and not lines[-1].strip():
        lines.pop()
    rows = lines[i:i + height]
    if len(rows) < height:
        raise LoRRFormatError(f"{path}: the header says height {height} but the map has {len(rows)} rows")
    for k, row in enumerate(rows):
        if len(row) != width:
            raise LoRRFormatError(f"{path} line {i + k + 1}: map row {k} has {len(row)} cells, the header says "
                                  f"width {width}")
    extra = [n for n, line in enumerate(lines[i + height:], start=i + height + 1) if line.strip()]
    if extra:
        raise LoRRFormatError(f"{path} line {extra[0]}: text after the {height} map rows the header announces")
    flat = np.frombuffer("".join(rows).encode("utf-8", "replace"), dtype=np.uint8) if rows else np.zeros(0, np.uint8)
    if flat.size != height * width:  # a multi-byte letter
        raise LoRRFormatError(f"{path}: map rows hold a non-ASCII letter")
    grid = np.isin(flat, np.frombuffer("".join(sorted(_BLOCKED)).encode(), dtype=np.uint8))
    return grid.reshape(height, width)


def _count_lines(path: Path, what: str) -> tuple[int, list[tuple[int, str]]]:
    """The count line and the non-comment lines after it, with 1-based line numbers."""
    lines = _lines(path, what)
    body = [(n, line.strip()) for n, line in enumerate(lines, start=1) if line.strip() and not line.lstrip().startswith("#")]
    if not body:
        raise LoRRFormatError(f"{path}: empty {what} (expected a count line)")
    n, first = body[0]
    head = first.split(",")[0].strip()
    if not head.isdigit():
        raise LoRRFormatError(f"{path} line {n}: the count must be a non-negative integer, got {first[:40]!r}")
    return int(head), body[1:]


def _cells(path: Path, n: int, text: str, grid: np.ndarray, what: str) -> list[int]:
    cells = []
    size = grid.size
    for part in text.split(","):
        part = part.strip()
        try:
            loc = int(part)
        except ValueError:
            raise LoRRFormatError(f"{path} line {n}: {what} {part[:40]!r} is not an integer location") from None
        if not 0 <= loc < size:
            raise LoRRFormatError(f"{path} line {n}: {what} {loc} is off the map (locations 0..{size - 1}, "
                                  f"row * {grid.shape[1]} + col)")
        if grid.flat[loc]:
            raise LoRRFormatError(f"{path} line {n}: {what} {loc} (row {loc // grid.shape[1]}, col "
                                  f"{loc % grid.shape[1]}) is on a blocked cell")
        cells.append(loc)
    return cells


def _read_agents(path: Path, team: int, grid: np.ndarray) -> np.ndarray:
    count, body = _count_lines(path, "agents file")
    if count < team:
        raise LoRRFormatError(f"{path}: holds {count} agents, teamSize asks for {team}")
    if len(body) < count:
        raise LoRRFormatError(f"{path}: the count says {count} agents but {len(body)} lines follow")
    starts = []
    seen: dict[int, int] = {}
    for n, text in body[:team]:
        (loc,) = _cells(path, n, text.split(",")[0], grid, "start")  # body lines are never empty
        if loc in seen:
            raise LoRRFormatError(f"{path} line {n}: start {loc} is also the start on line {seen[loc]} "
                                  "(two robots in one cell)")
        seen[loc] = n
        starts.append(loc)
    return np.array(starts, dtype=np.int64)


def _read_tasks(path: Path, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    count, body = _count_lines(path, "task file")
    if count < 1:
        raise LoRRFormatError(f"{path}: the count must be >= 1 (the file is read cyclically), got {count}")
    if len(body) != count:
        raise LoRRFormatError(f"{path}: the count says {count} tasks but {len(body)} task lines follow")
    errands: list[int] = []
    offsets = [0]
    for n, text in body:
        if not text.strip(", "):
            raise LoRRFormatError(f"{path} line {n}: a task with no errand")
        errands.extend(_cells(path, n, text, grid, "errand"))
        offsets.append(len(errands))
    return np.array(errands, dtype=np.int64), np.array(offsets, dtype=np.int64)


def _simulation_time(folder: Path, name: str) -> int | None:
    """The instance's steps from a ``simulation_time.json`` in its folder or the one above."""
    for candidate in (folder / "simulation_time.json", folder.parent / "simulation_time.json"):
        if candidate.is_file():
            try:
                table = json.loads(read_text(candidate, "simulation time file"))
            except (ValueError, OSError, WorldError):
                return None
            steps = table.get(name) if isinstance(table, dict) else None
            return int(steps) if isinstance(steps, int) and steps > 0 else None
    return None


def read_instance(path) -> LoRRInstance:
    """Read a LoRR instance JSON and the files it names (see the module docstring)."""
    path = Path(path)
    lines = _lines(path, "instance file")
    try:
        data = json.loads("\n".join(lines))
    except ValueError as exc:
        raise LoRRFormatError(f"{path} line {getattr(exc, 'lineno', 1)}: not JSON ({getattr(exc, 'msg', exc)})") \
            from None
    if not isinstance(data, dict):
        raise LoRRFormatError(f"{path} line 1: an instance is a JSON object, got {type(data).__name__}")
    for key in ("mapFile", "agentFile", "teamSize", "taskFile"):
        if key not in data:
            raise LoRRFormatError(f"{path}: no {key!r} key (an instance names mapFile, agentFile, teamSize, taskFile)")
    for key in ("mapFile", "agentFile", "taskFile"):
        if not isinstance(data[key], str) or not data[key]:
            raise LoRRFormatError(f"{path}: {key} must be a file path, got {data[key]!r}")
    team = data["teamSize"]
    if isinstance(team, bool) or not isinstance(team, int) or team < 1:
        raise LoRRFormatError(f"{path}: teamSize must be an integer >= 1, got {team!r}")
    reveal = data.get("numTasksReveal", 1)
    if isinstance(reveal, bool) or not isinstance(reveal, (int, float)) or not reveal > 0 or not math.isfinite(reveal):
        raise LoRRFormatError(f"{path}: numTasksReveal must be a number > 0, got {reveal!r}")
    if int(np.float32(reveal) * np.float32(team)) < 1:
        raise LoRRFormatError(f"{path}: numTasksReveal {reveal!r} x teamSize {team} keeps no task open (the start kit "
                              f"truncates the product; it must be at least 1)")
    strategy = data.get("taskAssignmentStrategy")
    if strategy is not None and strategy not in ASSIGNMENT_STRATEGIES:
        raise LoRRFormatError(f"{path}: taskAssignmentStrategy {strategy!r} is not supported; supported: "
                              f"{', '.join(ASSIGNMENT_STRATEGIES)} (2024 instances name none)")
    if strategy is not None and float(reveal) != int(reveal):
        raise LoRRFormatError(f"{path}: numTasksReveal must be a whole number of tasks per robot under "
                              f"{strategy!r}, got {reveal!r}")
    folder = path.parent
    grid = read_lorr_map(folder / data["mapFile"])
    starts = _read_agents(folder / data["agentFile"], team, grid)
    errands, offsets = _read_tasks(folder / data["taskFile"], grid)
    version = str(data.get("version", "2023 LoRR" if strategy else "2024 LoRR"))
    return LoRRInstance(name=path.stem, path=path, grid=grid, starts=starts, errands=errands, offsets=offsets,
                        reveal=float(reveal), strategy=strategy, version=version,
                        steps=_simulation_time(folder, path.stem), map_name=Path(data["mapFile"]).name,
                        meta={k: v for k, v in data.items() if isinstance(v, (str, int, float))})
