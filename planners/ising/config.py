"""Frozen, validated configuration dataclasses for the Ising methods (shared helpers).

Each Ising method has one config class (:class:`~planners.ising.path.PathConfig`,
:class:`~planners.ising.tour.TourConfig`, :class:`~planners.ising.sharing.SharingConfig`)
validated once in ``__post_init__``: a bad value raises ``ValueError`` naming the
option, the value and the limit.  Planners take ``config=`` and/or the same
options as keywords (``IsingPath(patch_size=7)``), which build a config.
"""

from __future__ import annotations

import dataclasses
import math

__all__ = ["IsingConfig", "check_choice", "check_int", "check_real", "check_rules", "resolve_config"]


def check_choice(name: str, value, options) -> None:
    if value not in options:
        raise ValueError(f"{name} = {value!r} not in {tuple(options)}")


def check_rules(name: str, value, options=None) -> tuple:
    """``value`` (one rule or several) as a tuple of distinct rules, each in ``options`` when given: every
    rule is one program of each round, so a rule named twice would merge its counts."""
    rules = (value,) if isinstance(value, str) else tuple(value)
    if not rules:
        raise ValueError(f"{name} must name at least one quantization rule")
    for r in rules if options is not None else ():
        check_choice(f"{name} entry", r, options)
    if len(set(rules)) != len(rules):
        raise ValueError(f"{name} = {rules} names a rule twice (each rule is one program of every round)")
    return rules


def check_int(name: str, value, lo: int, *, none: bool = False, hi: int | None = None) -> None:
    """``value`` must be an integer >= ``lo`` (<= ``hi``), or ``None`` when ``none``."""
    if value is None and none:
        return
    ok = (isinstance(value, int) or (hasattr(value, "__index__") and not isinstance(value, float))) \
        and not isinstance(value, bool)
    if ok:
        value = int(value)
    if not ok or value < lo or (hi is not None and value > hi):
        rng = f"in {lo}..{hi}" if hi is not None else f">= {lo}"
        raise ValueError(f"{name} = {value!r} must be {'None or ' if none else ''}an integer {rng}")


def check_real(name: str, value, *, lo: float | None = None, lo_open: bool = False) -> None:
    """``value`` must be a finite real number (>= ``lo``, or > ``lo`` when ``lo_open``)."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {value!r} must be a finite number") from None
    if isinstance(value, bool) or not math.isfinite(v):
        raise ValueError(f"{name} = {value!r} must be a finite number")
    if lo is not None and (v <= lo if lo_open else v < lo):
        raise ValueError(f"{name} = {value!r} must be {'>' if lo_open else '>='} {lo:g}")


class IsingConfig:
    """Mixin for the frozen config dataclasses: ``replace`` that names unknown options."""

    def replace(self, **changes):
        known = {f.name for f in dataclasses.fields(self)}
        unknown = sorted(set(changes) - known)
        if unknown:
            raise TypeError(f"unknown option(s) {unknown} for {type(self).__name__}; valid: {sorted(known)}")
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


def resolve_config(cls, config, options: dict, default=None):
    """``config`` (an instance of ``cls``; ``None``: ``default``, else ``cls()``) with keyword
    ``options`` applied."""
    if config is None:
        config = cls() if default is None else default
    elif not isinstance(config, cls):
        raise TypeError(f"config must be a {cls.__name__}, got {type(config).__name__}")
    return config.replace(**options) if options else config
