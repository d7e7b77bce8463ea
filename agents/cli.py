"""The ``mrmt`` command line: one subcommand per module in :mod:`agents.commands`.

Each subcommand module defines ``NAME``, ``HELP``, ``add_arguments(parser)``
and ``run(args) -> int`` (the exit code).  Modules are imported lazily so
``mrmt plan`` never pays for importing torch.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import sys

__all__ = ["main", "SUBCOMMANDS"]

#: subcommand name -> module under agents.commands
SUBCOMMANDS = {
    "plan": "agents.commands.plan",
    "compare": "agents.commands.compare",
    "train": "agents.commands.train",
    "reproduce": "agents.commands.reproduce",
    "watch": "agents.commands.watch",
    "sweep": "agents.commands.sweep",
}


def _available() -> dict[str, str]:
    found = {}
    for name, module in SUBCOMMANDS.items():
        if importlib.util.find_spec(module) is not None:
            found[name] = module
    return found


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mrmt",
        description="Multi-robot multi-target planning with an emulated CMOS Ising chip.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    available = _available()
    wanted = None
    if argv:
        first = next((a for a in argv if not a.startswith("-")), None)
        if first in available:
            wanted = first
    for name, module_name in available.items():
        if wanted is not None and name != wanted:
            sub.add_parser(name)  # placeholder; only the chosen command's module is imported
            continue
        module = importlib.import_module(module_name)
        p = sub.add_parser(name, help=module.HELP, description=module.HELP)
        module.add_arguments(p)
        p.set_defaults(_run=module.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(argv)
    args = parser.parse_args(argv)
    return int(args._run(args) or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
