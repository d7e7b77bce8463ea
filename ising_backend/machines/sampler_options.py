"""A ``dimod.Sampler``'s parameters and their types, read from the sampler itself.

Contract: :func:`sampler_parameters` is what a sampler takes, :func:`parameter_types` the type of each
(``None``: any value); :func:`check_value` holds a Python value to such a type and :func:`parse_value`
reads a command-line text as one; both raise ``ValueError`` naming the parameter, the value and the
expected type.  Design notes: docs/design/machine_link.md.
"""

from __future__ import annotations

import ast
import builtins
import collections.abc
import inspect
import json
import types
import typing

import numpy as np

__all__ = ["RESERVED", "sampler_parameters", "parameter_types", "describe", "fits", "check_value", "parse_value"]

#: Parameters the planner sets on every call, never fixed by an option.
RESERVED = ("num_reads", "seed")

_SEQUENCES = (list, tuple, collections.abc.Sequence, collections.abc.MutableSequence)
_MAPPINGS = (dict, collections.abc.Mapping, collections.abc.MutableMapping)
_PLURAL = {int: "integers", float: "numbers", bool: "booleans", str: "strings"}


def _named_keywords(sampler) -> list[inspect.Parameter]:
    return [p for p in inspect.signature(sampler.sample).parameters.values()
            if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY) and p.name not in ("self", "bqm")]


def sampler_parameters(sampler) -> set:
    """``sampler.parameters`` and the named keywords of its ``sample`` (OpenJij lists only some)."""
    return set(sampler.parameters) | {p.name for p in _named_keywords(sampler)}


def _annotation(param: inspect.Parameter, namespace: dict):
    ann = param.annotation
    if isinstance(ann, str):  # ``from __future__ import annotations`` in the sampler's module
        try:
            ann = eval(ann, namespace)  # noqa: S307  (the installed package's own annotation text)
        except Exception:
            return None
    if ann is inspect.Parameter.empty:
        default = param.default
        return type(default) if type(default) in (int, float, bool, str) else None
    return ann


def parameter_types(sampler) -> dict:
    """``{name: type hint or None}`` for every parameter of ``sampler`` (module docstring)."""
    func = inspect.unwrap(getattr(sampler.sample, "__func__", sampler.sample))
    namespace = {**vars(typing), "np": np, "numpy": np, "collections": collections,
                 **getattr(func, "__globals__", {}), "__builtins__": builtins}
    out = {name: None for name in sampler_parameters(sampler)}
    for param in _named_keywords(sampler):
        out[param.name] = _annotation(param, namespace)
    return out


def _members(hint) -> tuple | None:
    """The members of a union hint (``Optional[X]`` too), else ``None``."""
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        return typing.get_args(hint)
    return None


def _known(hint) -> bool:
    """True when :func:`fits` can decide for this hint (else any value is passed on)."""
    members = _members(hint)
    if members is not None:
        return all(_known(m) for m in members)
    if hint in (type(None), int, float, bool, str, np.ndarray):
        return True
    origin = typing.get_origin(hint) or hint
    if origin is typing.Literal:
        return True
    if origin in _SEQUENCES or origin in _MAPPINGS:
        return all(a is Ellipsis or _known(a) for a in typing.get_args(hint))
    return False


def fits(hint, value) -> bool:
    """Whether ``value`` is of type ``hint`` (any value fits an unknown or missing hint)."""
    if hint is None or not _known(hint):
        return True
    members = _members(hint)
    if members is not None:
        return any(fits(m, value) for m in members)
    if hint is type(None):
        return value is None
    if hint is bool:
        return isinstance(value, (bool, np.bool_))
    if hint is int:
        return isinstance(value, (int, np.integer)) and not isinstance(value, bool)
    if hint is float:
        return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    if hint is str:
        return isinstance(value, str)
    if hint is np.ndarray:
        return isinstance(value, (list, tuple, np.ndarray))
    origin, args = typing.get_origin(hint) or hint, typing.get_args(hint)
    if origin is typing.Literal:
        return any(type(value) is type(a) and value == a for a in args)
    if origin in _MAPPINGS:
        return isinstance(value, dict) and (len(args) != 2 or all(fits(args[0], k) and fits(args[1], v)
                                                                  for k, v in value.items()))
    if not isinstance(value, (list, tuple)):  # a sequence hint; a string is not a list of strings here
        return False
    if origin is tuple and args and args[-1] is not Ellipsis:
        return len(value) == len(args) and all(fits(a, v) for a, v in zip(args, value))
    return not args or all(fits(args[0], v) for v in value)


def describe(hint) -> str:
    """``hint`` in words: "an integer", "a list of 2 numbers", "one of 'linear', 'geometric'"."""
    if hint is None or not _known(hint):
        return "any value"
    members = _members(hint)
    if members is not None:
        words = [describe(m) for m in members if m is not type(None)]
        return " or ".join(dict.fromkeys(words)) or "null"
    simple = {type(None): "null", int: "an integer", float: "a number", bool: "true or false", str: "a string",
              np.ndarray: "a list of numbers"}
    if hint in simple:
        return simple[hint]
    origin, args = typing.get_origin(hint) or hint, typing.get_args(hint)
    if origin is typing.Literal:
        return "one of " + ", ".join(repr(a) for a in args)
    if origin in _MAPPINGS:
        return "a JSON object"
    if origin is tuple and args and args[-1] is not Ellipsis:
        if len(set(args)) == 1:
            return f"a list of {len(args)} {_PLURAL.get(args[0], 'values')}"
        return f"a list of {len(args)} values ({', '.join(describe(a) for a in args)})"
    return f"a list of {_PLURAL.get(args[0], 'values')}" if args else "a list"


def check_value(hint, name: str, value) -> None:
    """``ValueError`` ("num_sweeps='abc': expected an integer") unless ``value`` fits ``hint``."""
    if not fits(hint, value):
        raise ValueError(f"{name}={value!r}: expected {describe(hint)}")


def _readings(text: str):
    """The values a command-line text may mean, in order: JSON, a Python literal, the text itself."""
    try:
        yield json.loads(text)
    except ValueError:
        pass
    try:
        yield ast.literal_eval(text)
    except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):
        pass
    yield text


def parse_value(hint, name: str, text: str):
    """The first reading of ``text`` (see :func:`_readings`) that fits ``hint``; ``ValueError``
    naming the option, the text and the expected type when none does."""
    for value in _readings(text):
        if fits(hint, value):
            return value
    raise ValueError(f"{name}={text!r}: expected {describe(hint)}")
