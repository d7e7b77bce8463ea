"""The start kit's output file: written from a run, read back and re-simulated (``mrmt lorr check``).

:func:`write_output` writes the keys the competition's tools read (PlanViz, the start kit's evaluation);
:func:`check_output` re-simulates any such file on its instance.
Design notes (the keys, what is checked): docs/design/lorr_simulator.md#output-files.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mrmt_env.lorr.rules import ACTION_LETTERS, ORIENT_LETTERS, TIMEOUT, WAIT, parse_actions
from mrmt_env.lorr.sim import LoRRSimulator

__all__ = ["write_output", "output_dict", "check_output", "read_output", "CheckResult", "OutputError"]


class OutputError(ValueError):
    """An output file that cannot be re-simulated (the message names the file and key)."""


def _paths(rows: list[np.ndarray], r: int) -> list[str]:
    if not rows:
        return [""] * r
    letters = np.array(list(ACTION_LETTERS))[np.stack(rows, axis=1)]  # TIMEOUT (-1): the last letter, T
    return [",".join(row) for row in letters.tolist()]


def _schedule(table) -> list[str]:
    return [",".join(f"{t}:{k}" for t, k in entries) for entries in table]


def output_dict(sim: LoRRSimulator, planner_times=None) -> dict:
    """The start kit's output of a finished run (see the module docstring)."""
    inst, w = sim.inst, sim.width
    tasks = sim.tasks
    r = sim.n_robots
    return {
        "actionModel": "MAPF_T",
        "version": inst.version,
        "teamSize": r,
        "start": [[int(p) // w, int(p) % w, ORIENT_LETTERS[int(o)]] for p, o in zip(sim.start_pos, sim.start_orient)],
        "numTaskFinished": int(sim.finished),
        "sumOfCost": int(sim.busy.sum()),
        "makespan": int(sim.makespan),
        "numPlannerErrors": len(sim.errors),
        "numScheduleErrors": len(tasks.schedule_errors),
        "numEntryTimeouts": int(sim.timeouts),
        "actualPaths": _paths(sim.actual, r),
        "plannerPaths": _paths(sim.planned, r),
        "plannerTimes": [float(x) for x in (planner_times if planner_times is not None else [])],
        "errors": [[a, b, t, msg] for msg, a, b, t in sim.errors],
        "actualSchedule": _schedule(getattr(tasks, "actual_schedule", [[] for _ in range(r)])),
        "plannerSchedule": _schedule(getattr(tasks, "planner_schedule", [[] for _ in range(r)])),
        "scheduleErrors": [[k, a, b, t, msg] for msg, k, a, b, t in tasks.schedule_errors],
        "events": [list(e) for e in tasks.events],
        "tasks": tasks.task_records(w),
    }


def write_output(sim: LoRRSimulator, path, planner_times=None) -> Path:
    """Write :func:`output_dict` to ``path`` (a file; its folder is created)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(output_dict(sim, planner_times)))
    return path


@dataclass(frozen=True)
class CheckResult:
    """What a re-simulation found: tasks finished (``None`` without a schedule), errands reached,
    invalid joint actions, rejected schedules, steps, the file's own claim, whether the file's ``events``
    are the re-simulated ones (``None`` when it has none or no schedule), the timeouts, and the step of the first
    invalid joint action (counted from 1, as the file's ``errors`` give it; ``None`` without one)."""

    tasks_finished: int | None
    errands: int | None
    errors: int
    schedule_errors: int
    steps: int
    claimed: int | None
    events_agree: bool | None = None
    timeouts: int = 0
    first_error_step: int | None = None

    def to_json(self) -> dict:
        return {"numTaskFinished": self.tasks_finished, "errors": self.errors, "steps": self.steps,
                "errands": self.errands, "scheduleErrors": self.schedule_errors, "claimedTaskFinished": self.claimed,
                "eventsAgree": self.events_agree, "numEntryTimeouts": self.timeouts,
                "firstErrorStep": self.first_error_step}


def read_output(path) -> dict:
    """An output file as a dict (a ``.zip`` holding one JSON is read too); ``OutputError`` otherwise."""
    path = Path(path)
    try:
        if path.suffix == ".zip":
            import zipfile

            with zipfile.ZipFile(path) as z:
                names = [n for n in z.namelist() if n.endswith(".json")]
                if len(names) != 1:
                    raise OutputError(f"{path}: a zipped output holds one .json file, found {len(names)}")
                text = z.read(names[0]).decode("utf-8")
        else:
            text = path.read_text(encoding="utf-8")
        data = json.loads(text)
    except FileNotFoundError:
        raise OutputError(f"{path}: no such output file") from None
    except (OSError, ValueError) as exc:
        if isinstance(exc, OutputError):
            raise
        raise OutputError(f"{path}: not a JSON output file ({str(exc).splitlines()[0][:120]})") from None
    if not isinstance(data, dict):
        raise OutputError(f"{path}: an output file is a JSON object, got {type(data).__name__}")
    return data


def _parse_schedule(path, data, r) -> dict[int, list[tuple[int, int]]] | None:
    table = data.get("actualSchedule")
    if table is None:
        return None
    if not isinstance(table, list) or len(table) != r:
        raise OutputError(f"{path}: actualSchedule must hold one string per robot ({r})")
    by_step: dict[int, list[tuple[int, int]]] = {}
    for a, text in enumerate(table):
        for item in filter(None, str(text).split(",")):
            try:
                t, k = (int(x) for x in item.split(":"))
            except ValueError:
                raise OutputError(f"{path}: actualSchedule of robot {a}: {item[:20]!r} is not step:task") from None
            by_step.setdefault(t, []).append((a, k))
    return by_step


def check_output(instance, data: dict, path="output") -> CheckResult:
    """Re-simulate ``data`` (an output dict) on ``instance`` (see the module docstring)."""
    r = instance.team_size
    if data.get("teamSize") != r:
        raise OutputError(f"{path}: teamSize {data.get('teamSize')!r} but {instance.name} has {r} robots")
    start = data.get("start")
    if not isinstance(start, list) or len(start) != r:
        raise OutputError(f"{path}: start must list {r} robots")
    w = instance.width
    try:
        pos = np.array([int(s[0]) * w + int(s[1]) for s in start], dtype=np.int64)
        orient = np.array([ORIENT_LETTERS.index(s[2]) for s in start], dtype=np.int64)
    except (TypeError, ValueError, IndexError):
        raise OutputError(f"{path}: start entries are [row, col, E|S|W|N]") from None
    if not np.array_equal(pos, instance.starts):
        k = int(np.flatnonzero(pos != instance.starts)[0])
        raise OutputError(f"{path}: robot {k} starts at {int(pos[k])}, the instance at {int(instance.starts[k])}")
    key = "plannerPaths" if isinstance(data.get("plannerPaths"), list) else "actualPaths"
    paths = data.get(key)
    if not isinstance(paths, list) or len(paths) != r:
        raise OutputError(f"{path}: {key} must hold one action string per robot ({r})")
    try:
        rows = [parse_actions(str(p), f"{path}: {key} of robot {k}") for k, p in enumerate(paths)]
    except ValueError as exc:
        raise OutputError(str(exc)) from None
    steps = len(rows[0]) if rows else 0
    if any(len(x) != steps for x in rows):
        raise OutputError(f"{path}: {key} of the robots differ in length")
    schedule = _parse_schedule(path, data, r) if instance.strategy is None else {}
    sim = LoRRSimulator(instance, record=False)
    sim.orient = orient.copy()
    acts = np.stack(rows, axis=1) if rows else np.zeros((0, r), dtype=np.int8)
    for t in range(steps):
        proposal = None
        if schedule:
            changes = schedule.get(t + 1)
            if changes:
                proposal = sim.tasks.assigned.copy()
                for a, k in changes:
                    proposal[a] = k
        late = acts[t] == TIMEOUT
        if late.all():  # the entry's decision was late: nobody moved, no task was updated
            sim.time_out()
            continue
        if late.any():  # a short action vector: the start kit refuses it and everyone waits
            sim.step(np.full(r, WAIT, dtype=np.int64), proposal)
            sim.errors.append(("incorrect vector size", -1, -1, t + 1))
            continue
        sim.step(acts[t], proposal)
    counted = schedule is not None
    claimed = data.get("numTaskFinished")
    events = data.get("events")
    agree = None
    if counted and isinstance(events, list) and instance.strategy is None:
        agree = [list(e) for e in events] == [list(e) for e in sim.tasks.events]
    return CheckResult(tasks_finished=sim.finished if counted else None,
                       errands=sim.tasks.errands_done if counted else None, errors=len(sim.errors),
                       schedule_errors=len(sim.tasks.schedule_errors), steps=steps,
                       claimed=int(claimed) if isinstance(claimed, int) else None, events_agree=agree,
                       timeouts=sim.timeouts, first_error_step=sim.errors[0][3] if sim.errors else None)
