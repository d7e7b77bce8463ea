"""Typed, validated options: one record per planner or scheduler, one validator for them all.

A class's options are the fields of a frozen dataclass derived from :class:`Options`, each declared with
:func:`option` (default, kind, range or words, one line of meaning); building a record, :meth:`Options.from_dict`
and :meth:`Options.replace` check every field and refuse unknown ones, in one ``ValueError`` line.
Design notes: docs/design/league_parts.md#options-records.
"""

from __future__ import annotations

import dataclasses
from dataclasses import MISSING, dataclass, field, fields, make_dataclass
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

__all__ = ["Options", "option", "Bound", "record"]

P = TypeVar("P", bound="Options")


@dataclass(frozen=True)
class Bound:
    """What an option's value may be: ``kind`` (``int``, ``float``, ``bool`` or ``str``) within ``[lo, hi]``
    (either end ``None``: open; ``lo_open``: above ``lo``), or one of ``words`` (besides a number, e.g. ``"auto"``),
    or ``None`` when ``none`` is set.  Kind ``tuple``: a non-empty tuple (or list) of ``words`` (a single word: a
    tuple of one), or of finite numbers without words; ``dict``: a mapping; ``object``: any value (its owner's
    ``__post_init__`` checks it)."""

    kind: type
    lo: float | None = None
    hi: float | None = None
    words: tuple[str, ...] = ()
    none: bool = False
    meaning: str = ""
    lo_open: bool = False

    def allowed(self) -> str:
        """What the option takes, in words (the tail of an error line)."""
        if self.kind is bool:
            text = "true or false"
        elif self.kind is str:
            text = "one of " + ", ".join(self.words)
        elif self.kind is tuple:
            text = "a non-empty tuple of " + (", ".join(self.words) if self.words else "finite numbers")
        elif self.kind is dict:
            text = "a mapping"
        elif self.kind is object:
            text = "any value"
        else:
            noun = "an integer" if self.kind is int else "a number"
            lo, hi = (None if x is None else str(x) if self.kind is int else f"{x:g}" for x in (self.lo, self.hi))
            if lo is not None and hi is not None:
                text = f"{noun} in {'(' if self.lo_open else '['}{lo}, {hi}]"
            elif lo is not None:
                text = f"{noun} {'>' if self.lo_open else '>='} {lo}"
            elif hi is not None:
                text = f"{noun} <= {hi}"
            else:
                text = noun
            if self.words:
                text += " or " + " or ".join(repr(w) for w in self.words)
        return text + (" or null" if self.none else "")

    def read(self, name: str, value):
        """``value`` as the option's type, or ``ValueError`` naming ``name``, ``value`` and :meth:`allowed`."""
        if value is None and self.none:
            return None
        if self.kind is object:
            return value
        if self.kind is tuple:
            entries = (value,) if isinstance(value, str) else tuple(value) if isinstance(value, (tuple, list)) else ()
            if entries and all(self._entry(e) for e in entries):
                return entries if self.words else tuple(float(e) for e in entries)
        elif self.kind is dict:
            if isinstance(value, dict):
                return dict(value)
        elif isinstance(value, str) and value in self.words:
            return value
        if self.kind is bool:
            if isinstance(value, (bool, np.bool_)):
                return bool(value)
        elif self.kind is int:
            if isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_)) and self._within(value):
                return int(value)
        elif self.kind is float:
            if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_)) \
                    and np.isfinite(value) and self._within(value):
                return float(value)
        raise ValueError(f"{name} = {value!r} must be {self.allowed()}")

    def _within(self, value) -> bool:
        above = self.lo is None or (value > self.lo if self.lo_open else value >= self.lo)
        return above and (self.hi is None or value <= self.hi)

    def _entry(self, value) -> bool:
        """Whether ``value`` may be an entry of a tuple option: one of its words, or a finite number."""
        if self.words:
            return isinstance(value, str) and value in self.words
        return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_)) \
            and bool(np.isfinite(value))


def option(default, kind: type, lo=None, hi=None, *, words: tuple[str, ...] = (), none: bool = False,
           meaning: str = "", lo_open: bool = False):
    """A dataclass field of an :class:`Options` record (module docstring; ``lo_open``: above ``lo``, not at it)."""
    return field(default=default, metadata={"bound": Bound(kind, lo, hi, tuple(words), none, meaning, lo_open)})


@dataclass(frozen=True)
class Options:
    """Base of every options record: each field checked (and made its plain type) when the record is built."""

    def __post_init__(self) -> None:
        for f in fields(self):
            object.__setattr__(self, f.name, f.metadata["bound"].read(f.name, getattr(self, f.name)))

    @classmethod
    def from_dict(cls, values: dict, owner: str):
        """The record of ``values`` (option name -> value; the others their defaults); ``ValueError`` naming an
        option ``owner`` does not take, with those it takes."""
        cls._refuse_unknown(values, owner)
        return cls(**values)

    @classmethod
    def _refuse_unknown(cls, values, owner: str) -> None:
        names = [f.name for f in fields(cls)]
        for key in values:
            if key not in names:
                raise ValueError(f"{owner} takes no option {key!r}; its options: {', '.join(names)}")

    def replace(self: P, **changes) -> P:
        """This record with ``changes`` applied (checked as when built); ``ValueError`` naming an option the record
        does not take, with those it takes (the record's class its owner)."""
        self._refuse_unknown(changes, type(self).__name__)
        return dataclasses.replace(self, **changes)

    @classmethod
    def resolve(cls: type[P], config: P | None = None, options: dict | None = None, default: P | None = None) -> P:
        """``config`` (a ``cls`` record; ``None``: ``default``, else ``cls()``) with ``options`` applied
        (:meth:`replace`): a planner taking ``config=`` and/or the same options as keywords.  ``ValueError`` for a
        config of another class."""
        if config is None:
            config = cls() if default is None else default
        elif not isinstance(config, cls):
            raise ValueError(f"config must be a {cls.__name__}, got {type(config).__name__}")
        return config.replace(**options) if options else config

    def part(self, cls: type[P]) -> P:
        """The record ``cls`` of this record's values of its fields (a composed record handing a part its own)."""
        return cls(**{f.name: getattr(self, f.name) for f in fields(cls)})

    if TYPE_CHECKING:  # a record composed by :func:`record` has the fields of its parts
        def __getattr__(self, name: str) -> Any: ...

    @classmethod
    def describe(cls) -> list[tuple[str, object, str, str]]:
        """``(name, default, allowed, meaning)`` of every option, in declaration order."""
        out = []
        for f in fields(cls):
            b = f.metadata["bound"]
            out.append((f.name, None if f.default is MISSING else f.default, b.allowed(), b.meaning))
        return out


def record(name: str, doc: str, *parts: type[Options], defaults: dict | None = None,
           module: str = __name__) -> type[Options]:
    """An options record named ``name`` whose fields are those of ``parts`` (each an :class:`Options` record, in
    order), ``defaults`` replacing some of their defaults: a composition's record (a part takes its own back with
    :meth:`Options.part`).  Bind it to ``name`` in ``module`` (pickling finds it there).  ``ValueError`` for a field
    two parts declare or a default of no field."""
    defaults = dict(defaults or {})
    spec, seen = [], {}
    for part in parts:
        for f in fields(part):
            if f.name in seen:
                raise ValueError(f"{name}: option {f.name!r} declared by both {seen[f.name]} and {part.__name__}")
            seen[f.name] = part.__name__
            b = f.metadata["bound"]
            default = defaults.pop(f.name, f.default)
            spec.append((f.name, f.type, option(default, b.kind, b.lo, b.hi, words=b.words, none=b.none,
                                                meaning=b.meaning, lo_open=b.lo_open)))
    if defaults:
        raise ValueError(f"{name}: a default for {sorted(defaults)[0]!r}, which none of its parts declares")
    cls = make_dataclass(name, spec, bases=(Options,), frozen=True, namespace={"__doc__": doc})
    cls.__module__ = module
    return cls
