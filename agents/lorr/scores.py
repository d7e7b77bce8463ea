"""The archive's best-known scores: the package's table, a file in its format, and one instance's best-known.

Contract: :func:`best_known_table` ``(file=None) -> {name: BestKnown}`` (the package's table of the archive's published
scores, or a file in its format); :func:`best_known` ``(instance) -> tasks | None`` (a ``best_known.json`` beside the
instance or up to three folders above, else the package's table).  Both the runner (:mod:`agents.lorr.run`) and the
round (:mod:`agents.lorr.round`) read them from here, so neither imports the other for them.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import NamedTuple

import mrmt_env

__all__ = ["BestKnown", "best_known_table", "best_known", "BEST_KNOWN_FILE"]

#: The archive's published best-known scores (2023 and 2024, main and test rounds).
BEST_KNOWN_FILE = Path(mrmt_env.__file__).resolve().parent / "data" / "lorr_best_known.json"


class BestKnown(NamedTuple):
    """One instance's row of the archive's table."""

    agents: int
    steps: int
    tasks: int


def best_known_table(path=None) -> dict[str, BestKnown]:
    """``{instance name: BestKnown}`` from ``path`` (``{"<round>": {"NAME": [agents, steps, tasks]}}``, the format of
    the package's table) or the package's table; ``ValueError`` naming a malformed file or row."""
    path = Path(path) if path is not None else BEST_KNOWN_FILE
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ValueError(f"{path}: no such best-known file") from None
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: not a JSON best-known table ({str(exc).splitlines()[0][:100]})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: a best-known table is a JSON object of rounds")
    table: dict[str, BestKnown] = {}
    for section, rows in data.items():
        if not isinstance(rows, dict) or section in ("source", "columns"):
            continue
        for name, row in rows.items():
            if not (isinstance(row, list) and len(row) == 3 and all(isinstance(x, int) and x > 0 for x in row)):
                raise ValueError(f"{path}: {section}/{name} must be [agents, steps, tasks], whole numbers > 0, "
                                 f"got {row!r}")
            table[name] = BestKnown(*row)
    return table


def best_known(instance) -> int | None:
    """The best-known tasks finished of ``instance`` (a :class:`~mrmt_env.lorr.instance.LoRRInstance`) from a
    ``best_known.json`` in its folder or up to three above (``{"<year>": {"NAME": [agents, steps, tasks]}}``), else
    from the package's table of the archive's published scores (:data:`BEST_KNOWN_FILE`), else ``None``."""
    folder = instance.path.parent
    for d in [folder, *list(folder.parents)[:3]]:
        f = d / "best_known.json"
        if f.is_file():
            try:
                row = best_known_table(f).get(instance.name)
            except ValueError:
                continue
            if row is not None:
                return row.tasks
    row = best_known_table().get(instance.name)
    return None if row is None else row.tasks
