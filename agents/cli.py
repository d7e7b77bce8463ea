"""The ``mrmt`` command line: one subcommand per module in :mod:`agents.commands`.

Each subcommand module defines ``NAME``, ``HELP``, ``add_arguments(parser)``
and ``run(args) -> int`` (the exit code).  Modules are imported lazily so
``mrmt plan`` never pays for importing torch.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
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
    "warmup": "agents.commands.warmup",
    "lorr": "agents.commands.lorr",
    "audit": "agents.commands.audit",
}


def _available() -> dict[str, str]:
    found = {}
    for name, module in SUBCOMMANDS.items():
        if importlib.util.find_spec(module) is not None:
            found[name] = module
    return found


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("mrmt-ising")
    except PackageNotFoundError:  # run from a source tree that was never installed
        return "unknown (not installed)"


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mrmt",
        description="Multi-robot multi-target planning with an emulated CMOS Ising chip.",
    )
    parser.add_argument("--version", action="version", version=f"mrmt {_version()}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    parser.set_defaults(_parser=parser)
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
        p.set_defaults(_run=module.run, _parser=p)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(argv)
    args, unknown = parser.parse_known_args(argv)
    if unknown:  # reported by the subcommand's parser, with its usage (argparse would show the top-level one)
        args._parser.error(f"unrecognized arguments: {' '.join(unknown)}")
    try:
        return int(args._run(args) or 0)
    except BrokenPipeError:  # the reader went away (``mrmt plan ... | head``): stop quietly, as Unix tools do
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # so the interpreter's final flush does not raise again
        return 141  # 128 + SIGPIPE, what a shell reports for a tool a closed pipe stopped


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
