"""``mrmt reproduce``: every experiment of paper section 6, its figures and ``summary.md``.

    mrmt reproduce --out results/            # paper sizes: 1000 path queries, 100 tour/sharing/end-to-end
    mrmt reproduce --quick --out results/quick  # a small version for CI (under a minute)

The files it writes: docs/design/experiments.md#mrmt-reproduce. See :mod:`agents.experiments`.
"""

from __future__ import annotations

import sys

from agents.commands.options import add_chip_argument, add_runner_arguments, chip_from_args, check_seed, runner_from_args

NAME = "reproduce"
HELP = "run the paper's section-6 experiments and write CSV/JSON, PNG figures and summary.md"


def add_arguments(parser) -> None:
    parser.add_argument("--out", required=True, help="output directory")
    parser.add_argument("--quick", action="store_true", help="small sizes (CI): under a minute")
    parser.add_argument("--seed", type=int, default=0, help="first world seed (default 0)")
    add_runner_arguments(parser)
    parser.add_argument(
        "--only",
        default=None,
        help="comma-separated subset of experiments: path,tour,sharing,endtoend (default all)",
    )
    for name in ("path", "tour", "sharing", "endtoend"):
        parser.add_argument(f"--{name}", type=int, default=None, metavar="N", help=f"instances of the {name} experiment")
    add_chip_argument(parser, "the Ising methods")
    parser.add_argument("--no-progress", action="store_true", help="hide progress bars")


def run(args) -> int:
    from agents.experiments import PAPER_SIZES, QUICK_SIZES, reproduce

    from agents.runner import RunnerError

    try:
        runner = runner_from_args(args)
    except RunnerError as exc:
        print(f"mrmt reproduce: error: {exc}", file=sys.stderr)
        return 2
    names = tuple(PAPER_SIZES)
    if args.only:
        names = tuple(s.strip() for s in args.only.split(",") if s.strip())
        bad = [s for s in names if s not in PAPER_SIZES]
        if bad or not names:
            print(
                f"mrmt reproduce: error: unknown experiment {bad[0] if bad else args.only!r}; "
                f"known: {', '.join(PAPER_SIZES)}",
                file=sys.stderr,
            )
            return 2
    sizes = {}
    for name in PAPER_SIZES:
        v = getattr(args, name)
        if v is not None:
            if v < 1:
                print(f"mrmt reproduce: error: --{name} must be >= 1, got {v}", file=sys.stderr)
                return 2
            sizes[name] = v
    count = max([sizes.get(n, (QUICK_SIZES if args.quick else PAPER_SIZES)[n]) for n in names])
    problem = check_seed("--seed", args.seed, count)
    if problem:
        print(f"mrmt reproduce: error: {problem}", file=sys.stderr)
        return 2
    try:
        chip = chip_from_args(args)
    except ValueError as exc:
        print(f"mrmt reproduce: error: {exc}", file=sys.stderr)
        return 2
    from agents.warmup import warm

    warm(("fast", "strong", "ising-paper"), jobs=args.jobs, progress=not args.no_progress)  # a cold install only
    out = reproduce(
        args.out, quick=args.quick, seed=args.seed, n_jobs=args.jobs, progress=not args.no_progress,
        sizes=sizes, experiments=names, chip=chip, run=runner,
    )
    from pathlib import Path

    print(Path(args.out, "summary.md").read_text())
    print(f"wrote {len(out['files'])} files to {args.out}", file=sys.stderr)
    return 0
