"""A League entry: one named configuration (scheduler, planner, their options) for every instance of a round.

Contract: :func:`load_entry` ``(name or path) -> Entry``; :meth:`Entry.choose` ``(instance) -> Choice``: the first
rule whose conditions (bounds on :class:`mrmt_env.lorr.shape.Shape`, never the map's name) hold decides.
``--entry default`` is the package's own (``agents/lorr/entries/default.toml``).
Design notes (the file's shape): docs/design/lorr_runs.md#entries.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from agents.lorr.spec import PlannerSpec, SchedulerSpec
from mrmt_env.lorr.shape import MEASURES, Shape, shape_of

__all__ = ["Entry", "Rule", "Choice", "load_entry", "ENTRIES_DIR", "EntryError"]

#: Entries shipped with the package, by name (``<name>.toml``).
ENTRIES_DIR = Path(__file__).resolve().parent / "entries"
_CONDITIONS = tuple(f"{end}_{m}" for m in MEASURES for end in ("max", "min"))
_DECISIONS = ("scheduler", "planner", "scheduler_options", "planner_options")
#: Keys of earlier entry files and where they now live.
_MOVED = {"replan": "scheduler_options", "keep": "scheduler_options", "guidance": "planner_options"}


class EntryError(ValueError):
    """An entry that cannot be used (the message names the file, the rule and the key)."""


@dataclass(frozen=True)
class Choice:
    """What an entry runs on one instance: the scheduler's and the planner's specs, and the rule's number."""

    scheduler: SchedulerSpec
    planner: PlannerSpec
    rule: int = 0


@dataclass(frozen=True)
class Rule:
    """One rule of an entry: conditions on the instance and the choice they lead to."""

    conditions: dict
    choice: Choice

    def holds(self, shape: Shape) -> bool:
        """Whether the instance of :class:`~mrmt_env.lorr.shape.Shape` ``shape`` meets every bound of the rule."""
        for key, bound in self.conditions.items():
            end, measure = key.split("_", 1)
            value = getattr(shape, measure)
            if (value < bound) if end == "min" else (value > bound):
                return False
        return True


@dataclass(frozen=True)
class Entry:
    """A named list of rules (see the module docstring)."""

    name: str
    rules: tuple
    description: str = ""
    source: str = ""

    def choose(self, instance) -> Choice:
        """The first rule's choice that holds for ``instance`` (a :class:`~mrmt_env.lorr.instance.LoRRInstance`)."""
        shape = shape_of(instance)
        for rule in self.rules:
            if rule.holds(shape):
                return rule.choice
        raise EntryError(f"{self.source}: no rule holds for {instance.name}")  # unreachable: the last has none

    def to_json(self) -> dict:
        return {"name": self.name, "description": self.description, "source": self.source,
                "rules": [{**r.conditions, "scheduler": r.choice.scheduler.name,
                           "scheduler_options": r.choice.scheduler.options, "planner": r.choice.planner.name,
                           "planner_options": r.choice.planner.given} for r in self.rules]}


def _read(path: Path) -> dict:
    text = path.read_text(encoding="utf-8")
    if path.suffix == ".json":
        try:
            return json.loads(text)
        except ValueError as exc:
            raise EntryError(f"{path}: not JSON ({exc})") from None
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib  # type: ignore[no-redef]  # the same module under its 3.10 name
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise EntryError(f"{path}: not TOML ({exc})") from None


def _number(where: str, key: str, value, integer: bool):
    ok = isinstance(value, int) if integer else isinstance(value, (int, float))
    if isinstance(value, bool) or not ok or value < 0:
        raise EntryError(f"{where}: {key} = {value!r} must be a {'whole ' if integer else ''}number >= 0")
    return value


def _rule(where: str, raw, last: bool) -> Rule:
    if not isinstance(raw, dict):
        raise EntryError(f"{where}: a rule is a table of conditions and decisions, got {type(raw).__name__}")
    moved = sorted(set(raw) & set(_MOVED))
    if moved:
        raise EntryError(f"{where}: {moved[0]} is a {_MOVED[moved[0]].split('_')[0]} option: write "
                         f"{_MOVED[moved[0]]} = {{ {moved[0]} = {json.dumps(raw[moved[0]])} }}")
    unknown = sorted(set(raw) - set(_CONDITIONS) - set(_DECISIONS))
    if unknown:
        raise EntryError(f"{where}: unknown key {unknown[0]!r}; conditions: {', '.join(_CONDITIONS)}; decisions: "
                         f"{', '.join(_DECISIONS)}")
    conditions = {}
    for key in _CONDITIONS:
        if key in raw:
            measure = key.split("_", 1)[1]
            value = _number(where, key, raw[key], measure in ("robots", "cells"))
            if measure in ("corridors", "narrow") and value > 1:
                raise EntryError(f"{where}: {key} = {value!r} must be a share of the free cells, in [0, 1]")
            conditions[key] = value
    for measure in MEASURES:
        low, high = conditions.get(f"min_{measure}"), conditions.get(f"max_{measure}")
        if low is not None and high is not None and low > high:
            raise EntryError(f"{where}: min_{measure} = {low!r} exceeds max_{measure} = {high!r}: no instance meets "
                             "the rule")
    if last and conditions:
        raise EntryError(f"{where}: the last rule must have no condition (it decides every other instance)")
    for key in ("scheduler", "planner"):
        if not isinstance(raw.get(key), str) or not raw[key]:
            raise EntryError(f"{where}: {key} must name a {key} (as mrmt lorr run takes it), got {raw.get(key)!r}")
    tables = {}
    for key in ("scheduler_options", "planner_options"):
        table = raw.get(key, {})
        if not isinstance(table, dict):
            raise EntryError(f"{where}: {key} must be a table of the {key.split('_')[0]}'s options")
        tables[key] = dict(table)
    try:
        sched = SchedulerSpec.of(raw["scheduler"], tables["scheduler_options"])
        planner = PlannerSpec.of(raw["planner"], tables["planner_options"])
    except ValueError as exc:
        raise EntryError(f"{where}: {exc}") from None
    return Rule(conditions, Choice(sched, planner))


def load_entry(spec) -> Entry:
    """An entry by name (shipped in :data:`ENTRIES_DIR`) or path (``.toml`` / ``.json``); :class:`EntryError`
    naming the file, the rule and the key of anything wrong, an unknown scheduler, planner or option included."""
    spec = str(spec)
    path = Path(spec)
    if not path.suffix:
        path = ENTRIES_DIR / f"{spec}.toml"
        if not path.is_file():
            known = sorted(p.stem for p in ENTRIES_DIR.glob("*.toml"))
            raise EntryError(f"no entry named {spec!r}; shipped: {', '.join(known)} (or give a .toml / .json file)")
    elif not path.is_file():
        raise EntryError(f"{path}: no such entry file")
    data = _read(path)
    if not isinstance(data, dict) or not isinstance(data.get("rule"), list) or not data["rule"]:
        raise EntryError(f"{path}: an entry has a non-empty list of rules ([[rule]] tables)")
    unknown = sorted(set(data) - {"name", "description", "rule"})
    if unknown:
        raise EntryError(f"{path}: unknown key {unknown[0]!r}; an entry has name, description and rule")
    n = len(data["rule"])
    rules = []
    for i, raw in enumerate(data["rule"]):
        rule = _rule(f"{path} rule {i + 1}", raw, i == n - 1)
        rules.append(Rule(rule.conditions, Choice(rule.choice.scheduler, rule.choice.planner, rule=i + 1)))
    return Entry(name=str(data.get("name", path.stem)), rules=tuple(rules),
                 description=str(data.get("description", "")), source=str(path))
