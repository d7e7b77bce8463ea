"""``mrmt warmup``: compile every planner's numba kernels now, not on first use.

    mrmt warmup                       # every preset: fast, strong, ising, ising-paper, exact
    mrmt warmup --pipelines ising --jobs 2
    mrmt warmup --lorr epibt,pibt        # also the kernels of `mrmt lorr run`'s executors (or --lorr all)

The kernels are cached on disk by numba, so this is needed once per install (and after an
upgrade); the first command that plans does it anyway (:mod:`agents.warmup`).  Parts run on
``--jobs`` processes, longest first, with a progress bar.
"""

from __future__ import annotations

import os
import sys
import time

NAME = "warmup"
HELP = "compile the planners' numba kernels up front (once per install; otherwise done on first use)"


def add_arguments(parser) -> None:
    parser.add_argument("--pipelines", default="fast,strong,ising,ising-paper,exact",
                        help="comma-separated presets or sharing+tour+path triples (default: every preset)")
    parser.add_argument("--lorr", default="",
                        help="comma-separated LoRR executors of `mrmt lorr run` to compile as well, or `all` "
                             "(default: none)")
    parser.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1),
                        help="worker processes (default 2, or 1 on a one-core machine)")
    parser.add_argument("--force", action="store_true", help="compile again even if already warm")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")


def run(args) -> int:
    from agents.errors import ControllerError
    from agents.evaluation import parse_controllers
    from agents.warmup import parts_for, warm

    if args.jobs < 1:
        print(f"mrmt warmup: error: --jobs must be >= 1, got {args.jobs}", file=sys.stderr)
        return 2
    try:
        specs = parse_controllers(args.pipelines)
    except ControllerError as exc:
        print(f"mrmt warmup: error: {exc}", file=sys.stderr)
        return 2
    learned = [s for s in specs if not parts_for([s])]
    if learned:
        print(f"mrmt warmup: error: {learned[0]!r} is not a planner (learned models compile nothing)", file=sys.stderr)
        return 2
    try:
        specs = specs + [f"lorr:{name}" for name in _lorr_executors(args.lorr)]
    except ValueError as exc:
        print(f"mrmt warmup: error: {exc}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    done = warm(specs, jobs=args.jobs, progress=not args.no_progress, force=args.force, minimum_s=0)
    if done:
        print(f"compiled {len(done)} part(s) in {time.perf_counter() - t0:.1f} s: {', '.join(done)}")
    else:
        print(f"already warm: {', '.join(parts_for(specs))} (--force compiles again)")
    return 0


def _lorr_executors(text: str) -> list[str]:
    """The LoRR executor names of ``--lorr`` (``all``: every registered one); ``ValueError`` naming an
    unknown one and the known ones."""
    from planners.mapf import TURNING_PLANNERS

    names = [n.strip() for n in text.split(",") if n.strip()]
    if names == ["all"]:
        return list(TURNING_PLANNERS)
    unknown = [n for n in names if n not in TURNING_PLANNERS]
    if unknown:
        raise ValueError(f"--lorr: unknown executor {unknown[0]!r}; expected `all` or some of "
                         f"{', '.join(TURNING_PLANNERS)}")
    return names
