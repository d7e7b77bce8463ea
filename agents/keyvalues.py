"""``KEY=VALUE`` options as every command reads them: one splitter and one value reader.

:func:`split_items` turns items into ``(key, text)`` pairs (keys stripped, ``-`` read as ``_``), refusing an item
without ``=`` or key and a key given twice, each in one line naming the flag, the item and an example;
:func:`typed` reads a value as JSON (numbers, ``true`` / ``false``, ``null``) or keeps the text;
:func:`key_values` is both.  Options whose type a parameter fixes (``--sampler-option``) keep the text for their
own reader.
"""

from __future__ import annotations

import json

__all__ = ["split_items", "typed", "key_values"]


def split_items(items, what: str, example: str) -> list[tuple[str, str]]:
    """``(key, text)`` of each ``KEY=VALUE`` item in order (module docstring); ``what`` names the flag."""
    pairs: dict[str, str] = {}
    for item in items:
        key, sep, text = str(item).partition("=")
        key = key.strip().replace("-", "_")
        if not sep or not key:
            raise ValueError(f"{what} {item!r} must look like KEY=VALUE (e.g. {example})")
        if key in pairs:
            raise ValueError(f"{what} {key} given twice ({pairs[key]!r} and {text.strip()!r}); give it once")
        pairs[key] = text.strip()
    return list(pairs.items())


def typed(text: str):
    """A value as JSON when it parses (numbers, ``true`` / ``false``, ``null``), else the text."""
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text


def key_values(items, what: str, example: str) -> dict:
    """``{key: typed(text)}`` of :func:`split_items`."""
    return {key: typed(text) for key, text in split_items(items, what, example)}
