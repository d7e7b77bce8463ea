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


def add_world_arguments(parser, density: bool = True) -> None:
    """``--env-id`` and the world overrides ``--robots/--targets/--height/--width[/--density]/--placement/--layout``
    (each ``None`` unless given: the env id's default)."""
    from mrmt_env.maps import LAYOUTS

    parser.add_argument("--env-id", default="mrmt_env/MRMT-v0", help="Gymnasium env id (default mrmt_env/MRMT-v0)")
    parser.add_argument("--robots", type=int, default=None, help="robots per world (default: the env id's, 3)")
    parser.add_argument("--targets", type=int, default=None, help="targets per world (default: the env id's, 10)")
    parser.add_argument("--height", type=int, default=None, help="grid height (default: the env id's, 10)")
    parser.add_argument("--width", type=int, default=None, help="grid width (default: the env id's, 10)")
    if density:
        parser.add_argument("--density", type=float, default=None, help="obstacle density (default: the env id's, 0.2)")
    parser.add_argument("--placement", default=None, choices=("uniform", "centre"), help="robot placement")
    parser.add_argument("--layout", default=None, choices=LAYOUTS,
                        help="map family (default: the env id's; docs/maps.md)")


def add_chip_argument(parser, who: str = "the Ising planners", chip: bool = True) -> None:
    """``--chip`` (unless ``chip=False``: the command has its own), ``--sampler`` and ``--sampler-option``."""
    from ising_backend import SAMPLERS

    if chip:
        parser.add_argument("--chip", action="append", default=[], metavar="KEY=VALUE|FILE.json",
                            help=f"the chip of {who}: any ChipSpec field (e.g. n_spins=64, "
                                 "j_range=15 meaning (-15, 15)) or a JSON file of fields; repeatable")
    parser.add_argument("--sampler", default=None, metavar="NAME",
                        help=f"an Ising sampler behind {who} instead of the emulator, held to the --chip spec "
                             f"(refused programs, calls charged by it): {', '.join(SAMPLERS)}")
    parser.add_argument("--sampler-option", action="append", default=[], metavar="KEY=VALUE",
                        help="a parameter of the --sampler, e.g. num_sweeps=100 or timeout=2 (repeatable)")


def chip_from_args(args, key: str = "chip"):
    """The chip the options ask for: ``None`` (none given), a :class:`~ising_backend.ChipSpec`
    (the emulator) or a :class:`~ising_backend.MachineSpec` (``--sampler``); a bad field, an
    unknown sampler or option, or a missing package raises ``ValueError`` in one line."""
    from ising_backend import ChipSpec, MachineSpec
    from ising_backend.machines.machine import parse_sampler_options

    from agents.keyvalues import split_items

    items = getattr(args, key, None) or []
    pairs = iter(split_items([i for i in items if "=" in i], "--chip", "n_spins=64"))
    spec = ChipSpec.from_options([next(pairs) if "=" in i else i for i in items]) if items else None
    sampler = getattr(args, "sampler", None)
    options = getattr(args, "sampler_option", None) or []
    if sampler is None:
        if options:
            raise ValueError("--sampler-option given without --sampler")
        return spec
    texts = split_items(options, "--sampler-option", "num_sweeps=100")  # read by their parameters' types below
    MachineSpec(spec or ChipSpec(), sampler).build()  # an unknown sampler, a missing package, a faulty spec
    try:  # each value read by its parameter's type (ising_backend.machines.sampler_options)
        pairs = parse_sampler_options(sampler, texts)
    except ValueError as exc:
        raise ValueError(f"--sampler-option {exc}") from None
    machine = MachineSpec(spec or ChipSpec(), sampler, pairs)
    try:  # values of the right type the sampler still refuses fail now, not at the first plan
        machine.build().probe()
    except ValueError as exc:
        raise ValueError(f"--sampler {sampler}: {exc}") from None
    return machine


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


def add_decision_arguments(parser, where: str) -> None:
    """``--no-progress``, ``--audit DIR`` (every chip decision recorded; ``where`` says where it applies) and
    ``--host-rule CLASS[,CLASS...]|all`` (the host rule answers those decision classes instead of the chip)."""
    from ising_backend.audit.host_rule import HOST_RULE_CLASSES

    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    parser.add_argument("--audit", default=None, metavar="DIR",
                        help=f"record every chip decision in DIR (mrmt audit DIR judges it; {where}); plans are unchanged")
    parser.add_argument("--host-rule", default=None, metavar="CLASSES",
                        help="ablation: the host rule answers these decision classes where the chip decided (greedy + "
                             "descent; joint_moves: PIBT's answer; lns_groups: the search's greedy; task_groups: "
                             "the greedy matching) "
                             f"({', '.join(HOST_RULE_CLASSES)}, or all; this process only)")


def host_rule_from_args(args):
    """The ``HostRule`` context of ``--host-rule`` (a null context without it); ``ValueError`` naming a bad class."""
    from contextlib import nullcontext

    from ising_backend.audit.host_rule import HostRule

    return HostRule(args.host_rule) if args.host_rule else nullcontext()
