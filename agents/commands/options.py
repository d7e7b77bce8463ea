"""Options shared by several subcommands: the task runner, the emulated chip, seeds and counts.

Each ``check_*`` returns an error line (without the ``mrmt CMD: error:`` prefix) or ``None``;
commands print it and exit 2.
"""

from __future__ import annotations

#: Largest world or controller seed (numpy seeds a generator from any integer in [0, 2**63)).
MAX_SEED = 2**63 - 1


def add_runner_arguments(parser, jobs_help: str = "workers; 1 = inline unless --backend says otherwise") -> None:
    from agents.runner import BACKENDS

    parser.add_argument("--jobs", type=int, default=2, help=f"{jobs_help} (default 2)")
    parser.add_argument("--backend", default=None, choices=BACKENDS,
                        help="where tasks run: inline, process (this machine's cores) or ray (a local Ray "
                             "instance, or the cluster at --address); default process, inline for --jobs 1")
    parser.add_argument("--address", default=None,
                        help="address of a running Ray cluster (ray start --head prints it); implies --backend ray")


def runner_from_args(args):
    """The :class:`agents.runner.RunConfig` of ``--jobs/--backend/--address/--no-progress``;
    raises ``ValueError`` (a :class:`agents.runner.RunnerError`) on a bad combination."""
    from agents.runner import RunConfig, RunnerError, _ray

    if args.jobs < 1:
        raise RunnerError(f"--jobs must be >= 1, got {args.jobs}")
    if args.address and args.backend not in (None, "ray"):
        raise RunnerError(f"--address is for --backend ray, not {args.backend}")
    run = RunConfig.from_jobs(args.jobs, progress=not getattr(args, "no_progress", False),
                              backend=args.backend, address=args.address)
    if run.backend == "ray":
        _ray(local=not run.address)  # fail now, with the install hint, rather than after the first experiment
    return run


def add_chip_argument(parser, who: str = "the Ising planners") -> None:
    parser.add_argument("--chip", action="append", default=[], metavar="KEY=VALUE|FILE.json",
                        help=f"the emulated chip of {who}: any ChipSpec field (e.g. n_spins=64, "
                             "j_range=15 meaning (-15, 15)) or a JSON file of fields; repeatable")


def check_seed(name: str, value: int, count: int = 1) -> str | None:
    """``value .. value + count - 1`` must be seeds in [0, 2**63)."""
    if value < 0 or value + count - 1 > MAX_SEED:
        last = f" (and {name} + {count - 1} for the last one)" if count > 1 else ""
        return f"{name} must be in [0, 2**63){last}, got {value}"
    return None


def check_positive(args, names) -> str | None:
    """Every ``--NAME`` given (not None) must be >= 1."""
    for name in names:
        value = getattr(args, name.replace("-", "_"))
        if value is not None and value < 1:
            return f"--{name} must be >= 1, got {value}"
    return None
