"""``mrmt lorr generate``: write a League of Robot Runners 2024 instance (JSON, map, agents, tasks) to run.

    mrmt lorr generate MAP --agents N --seed S --out FILE.json [--tasks N] [--reveal R] [--errands MIN-MAX]

``MAP``: a MovingAI or LoRR ``.map`` file, or ``family:NAME:HxW[:KEY=VALUE,...]`` (a map family of
:mod:`mrmt_env.maps`, e.g. ``family:warehouse:64x64``).  The draw is :func:`mrmt_env.lorr.generate.generate_instance`'s.
Bad input: one line, exit 2.
"""

from __future__ import annotations

import sys


def add_parser(sub) -> None:
    from mrmt_env.lorr.generate import DEFAULT_ERRANDS, DEFAULT_REVEAL, FAMILY_SYNTAX, default_tasks

    p = sub.add_parser("generate", help="write a LoRR 2024 instance (JSON, map, agents, tasks) on a .map file or a "
                                        "package map family")
    p.add_argument("map", metavar="MAP", help=f"a MovingAI or LoRR .map file, or {FAMILY_SYNTAX}, e.g. "
                                              "family:warehouse:64x64 or family:rooms:32x32:room_size=5")
    p.add_argument("--agents", type=int, required=True, metavar="N",
                   help="robots, on distinct free cells of the map's largest connected component")
    p.add_argument("--seed", type=int, default=0, help="seed of the map family and the draw (default 0)")
    p.add_argument("--out", required=True, metavar="FILE.json",
                   help="the instance file; maps/, agents/, tasks/ files named after it are written beside it")
    p.add_argument("--tasks", type=int, default=None, metavar="N",
                   help=f"task lines (default: {default_tasks(1):,} as the archive's files, or 20 per robot when more)")
    p.add_argument("--reveal", type=float, default=DEFAULT_REVEAL, metavar="R",
                   help=f"numTasksReveal: open tasks = R x agents (default {DEFAULT_REVEAL}, the 2024 main round's)")
    p.add_argument("--errands", default=f"{DEFAULT_ERRANDS[0]}-{DEFAULT_ERRANDS[1]}", metavar="MIN-MAX",
                   help="errands per task, uniform in MIN..MAX (default %(default)s, as the 2024 main round's RANDOM "
                        "and CITY task files)")


def _errands(text: str) -> tuple[int, int]:
    lo, sep, hi = text.partition("-")
    if not sep:
        lo = hi = text
    if not (lo.strip().isdigit() and hi.strip().isdigit()):
        raise ValueError(f"--errands {text!r}: must be MIN-MAX (or one number), whole numbers >= 1")
    return int(lo), int(hi)


def run(args) -> int:
    from mrmt_env.lorr.generate import GenerateError, generate_instance
    from mrmt_env.lorr.instance import LoRRFormatError, read_instance

    try:
        files = generate_instance(args.map, args.agents, args.out, seed=args.seed, tasks=args.tasks,
                                  reveal=args.reveal, errands=_errands(args.errands))
        inst = read_instance(files.instance)
    except GenerateError as exc:  # its messages start with the parameter's name: the flag's
        text = str(exc)
        return _fail(f"--{text}" if text.split(" ")[0] in ("agents", "tasks", "seed", "reveal", "errands") else text)
    except (ValueError, LoRRFormatError, OSError) as exc:
        return _fail(str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
    print(f"wrote {files.instance} ({inst.team_size} robots, {inst.n_tasks} tasks of {inst.errands.size} errands, "
          f"map {inst.height}x{inst.width}) and {files.map.name}, {files.agents.name}, {files.tasks.name} beside it")
    return 0


def _fail(message: str) -> int:
    print(f"mrmt lorr: error: {message}", file=sys.stderr)
    return 2
