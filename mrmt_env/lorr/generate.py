"""Write League of Robot Runners 2024 instances: the instance JSON, its map, agents and task files.

Contract: :func:`generate_instance` ``(source, agents, out, seed=0, tasks=None, reveal=1.5, errands=(2, 5))
-> InstanceFiles``; every bad input is one :class:`GenerateError` (a ``ValueError``). The draw follows the 2024
generator of the League's archive. Design notes: docs/design/lorr_simulator.md#generated-instances.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import NamedTuple

import numpy as np

from mrmt_env.generation import MAX_GRID_CELLS, _largest_component
from mrmt_env.maps import LAYOUT_OPTIONS, LAYOUTS, build_layout
from mrmt_env.movingai import read_movingai_map, write_movingai_map
from mrmt_env.world import WorldError

__all__ = ["generate_instance", "family_grid", "read_map", "default_tasks", "InstanceFiles", "GenerateError",
           "DEFAULT_REVEAL", "DEFAULT_ERRANDS", "ARCHIVE_TASKS", "MAX_TASKS", "FAMILY_SYNTAX"]

#: ``numTasksReveal`` of every 2024 main-round instance.
DEFAULT_REVEAL = 1.5
#: Errands per task (inclusive range) of the 2024 main round's RANDOM and CITY task files.
DEFAULT_ERRANDS = (2, 5)
#: Task lines of every 2024 main-round task file.
ARCHIVE_TASKS = 100_000
#: Task lines per robot of the default when more than :data:`ARCHIVE_TASKS` (the 2024 records: at most 15.5).
TASKS_PER_ROBOT = 20
#: Most task lines a generated file holds (about 200 MB of text).
MAX_TASKS = 10_000_000
MAX_ERRANDS = 1000
FAMILY_SYNTAX = "family:NAME:HxW[:KEY=VALUE,...] (NAME one of " + ", ".join(LAYOUTS) + ")"
_HEADER = "# version for LoRR 2024\n"


class GenerateError(ValueError):
    """An instance that cannot be generated (the message names the value and the limit)."""


class InstanceFiles(NamedTuple):
    """The paths written: the instance JSON, the map, the agents and the task file."""

    instance: Path
    map: Path
    agents: Path
    tasks: Path


def default_tasks(agents: int) -> int:
    """Task lines by default: the archive's 100,000, or 20 per robot when more (the 2024 record runs finish at most
    15.5 tasks per robot, WAREHOUSE's 154,834 by 10,000 robots, so the file is not read cyclically within them)."""
    return max(ARCHIVE_TASKS, TASKS_PER_ROBOT * int(agents))


def _option_value(text: str):
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return text


def family_grid(spec: str, rng: np.random.Generator) -> np.ndarray:
    """The grid of a family spec ``family:NAME:HxW[:KEY=VALUE,...]`` (``H`` rows by ``W`` columns; options those of
    :data:`mrmt_env.maps.LAYOUT_OPTIONS`, ``uniform`` takes ``obstacle_density``, default 0.2), built from ``rng``."""
    parts = spec.split(":")
    if len(parts) not in (3, 4) or parts[0] != "family":
        raise GenerateError(f"map {spec!r}: a family map is {FAMILY_SYNTAX}, e.g. family:warehouse:64x64")
    name, size = parts[1], parts[2].lower()
    if name not in LAYOUTS:
        raise GenerateError(f"map {spec!r}: unknown family {name!r}; known: {', '.join(LAYOUTS)}")
    dims = size.split("x")
    if len(dims) != 2 or not all(d.isdigit() and int(d) >= 1 for d in dims):
        raise GenerateError(f"map {spec!r}: size {parts[2]!r} must be HxW, two integers >= 1 (e.g. 64x64)")
    height, width = int(dims[0]), int(dims[1])
    if height * width > MAX_GRID_CELLS:
        raise GenerateError(f"map {spec!r}: {height}x{width} = {height * width} cells; at most {MAX_GRID_CELLS} "
                            "(MAX_GRID_CELLS)")
    options = {}
    for item in (parts[3].split(",") if len(parts) == 4 and parts[3] else []):
        key, eq, value = item.partition("=")
        if not eq or not key.strip():
            raise GenerateError(f"map {spec!r}: option {item!r} must be KEY=VALUE")
        options[key.strip()] = _option_value(value.strip())
    if name == "uniform":
        unknown = sorted(set(options) - {"obstacle_density"})
        if unknown:
            raise GenerateError(f"map {spec!r}: unknown options {unknown} for uniform; allowed: ['obstacle_density']")
        density = options.get("obstacle_density", 0.2)
        if isinstance(density, str) or not 0.0 <= density < 1.0:
            raise GenerateError(f"map {spec!r}: obstacle_density must be a number in [0, 1), got {density!r}")
        flat = np.zeros(height * width, dtype=bool)
        flat[rng.choice(height * width, size=round(density * height * width), replace=False)] = True
        return flat.reshape(height, width)
    try:
        return np.asarray(build_layout(name, rng, height, width, options).grid, dtype=bool)
    except (ValueError, IndexError) as exc:
        allowed = ", ".join(f"{k}={v}" for k, v in LAYOUT_OPTIONS[name].items())
        raise GenerateError(f"map {spec!r}: {exc} (defaults: {allowed})") from None


def read_map(path) -> np.ndarray:
    """A ``.map`` file's grid: MovingAI letters (``@ O T W`` blocked, ``. G S`` free), or else as the start kit
    reads a LoRR map (``@ T`` blocked, any other letter free)."""
    from mrmt_env.lorr.instance import LoRRFormatError, read_lorr_map

    path = Path(path)
    if not path.is_file():
        raise GenerateError(f"map {str(path)!r}: no such map file (or give {FAMILY_SYNTAX})")
    try:
        return read_movingai_map(path)
    except WorldError as first:
        if "unknown cell letter" not in str(first):
            raise GenerateError(str(first)) from None  # it names the file
    try:
        return read_lorr_map(path)
    except LoRRFormatError as exc:
        raise GenerateError(str(exc)) from None


def _whole(name: str, value, lo: int, hi: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lo \
            or (hi is not None and value > hi):
        bound = f">= {lo}" if hi is None else f"in [{lo}, {hi}]"
        raise GenerateError(f"{name} must be an integer {bound}, got {value!r}")
    return int(value)


class Draw(NamedTuple):
    """What an instance is drawn with, checked."""

    agents: int
    tasks: int
    reveal: float
    seed: int
    errands: tuple[int, int]  # errands per task, least and most


def _check(agents, tasks, reveal, seed, errands) -> Draw:
    agents = _whole("agents", agents, 1)
    tasks = default_tasks(agents) if tasks is None else _whole("tasks", tasks, 1, MAX_TASKS)
    seed = _whole("seed", seed, 0)
    if isinstance(reveal, bool) or not isinstance(reveal, (int, float)) or not math.isfinite(reveal) or reveal <= 0:
        raise GenerateError(f"reveal (numTasksReveal) must be a number > 0, got {reveal!r}")
    if int(np.float32(reveal) * np.float32(agents)) < 1:
        raise GenerateError(f"reveal {reveal!r} x agents {agents} keeps no task open (the start kit truncates the "
                            "product; it must be at least 1)")
    if not isinstance(errands, (tuple, list)) or len(errands) != 2:
        raise GenerateError(f"errands must be (min, max), got {errands!r}")
    lo = _whole("errands min", errands[0], 1, MAX_ERRANDS)
    hi = _whole("errands max", errands[1], lo, MAX_ERRANDS)
    return Draw(agents, tasks, float(reveal), seed, (lo, hi))


def generate_instance(source, agents: int, out, seed: int = 0, tasks: int | None = None,
                      reveal: float = DEFAULT_REVEAL, errands=DEFAULT_ERRANDS) -> InstanceFiles:
    """Write a LoRR 2024 instance at ``out`` (see the module docstring); returns the paths written."""
    draw = _check(agents, tasks, reveal, seed, errands)
    agents, tasks, reveal, seed = draw.agents, draw.tasks, draw.reveal, draw.seed
    lo, hi = draw.errands
    out = Path(out)
    if out.suffix != ".json" or not out.stem:
        raise GenerateError(f"out {str(out)!r}: the instance file must be NAME.json")
    rng = np.random.default_rng(seed)
    if isinstance(source, np.ndarray):
        grid = np.asarray(source, dtype=bool)
        if grid.ndim != 2 or grid.size == 0 or grid.size > MAX_GRID_CELLS:
            raise GenerateError(f"map: a grid must be 2-D with 1..{MAX_GRID_CELLS} cells, got shape {grid.shape}")
    elif str(source).startswith("family:"):
        grid = family_grid(str(source), rng)
    else:
        grid = read_map(source)
    cells = np.flatnonzero(_largest_component(grid).reshape(-1)).astype(np.int64)
    if agents > cells.size:
        raise GenerateError(f"agents {agents}: the map's largest connected component has {cells.size} free cells "
                            f"(at most one robot a cell)")
    starts = rng.choice(cells, size=agents, replace=False)
    counts = rng.integers(lo, hi + 1, size=tasks)
    drawn = rng.choice(cells, size=int(counts.sum()), replace=True)
    stem = out.stem
    files = InstanceFiles(out, out.parent / "maps" / f"{stem}.map", out.parent / "agents" / f"{stem}.agents",
                          out.parent / "tasks" / f"{stem}.tasks")
    for path in files[1:]:
        path.parent.mkdir(parents=True, exist_ok=True)
    write_movingai_map(grid, files.map)
    files.agents.write_text(_HEADER + f"{agents}\n" + "".join(f"{int(c)}\n" for c in starts), encoding="utf-8")
    bounds = np.concatenate(([0], np.cumsum(counts)))
    text = drawn.astype(str)
    lines = [",".join(text[bounds[i]:bounds[i + 1]]) for i in range(tasks)]
    files.tasks.write_text(_HEADER + f"{tasks}\n" + "\n".join(lines) + "\n", encoding="utf-8")
    data = {"mapFile": f"maps/{stem}.map", "agentFile": f"agents/{stem}.agents", "teamSize": agents,
            "taskFile": f"tasks/{stem}.tasks", "numTasksReveal": reveal, "version": "2024 LoRR"}
    files.instance.write_text(json.dumps(data, indent=4) + "\n", encoding="utf-8")
    return files
