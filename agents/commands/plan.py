"""``mrmt plan``: plan every world of a file, one JSON object per world.

    mrmt plan WORLDS --pipeline strong                    # fast | strong | ising | ising-paper | exact | pyvrp
    mrmt plan WORLDS --sharing ssa --tour 3opt --path astar
    mrmt plan WORLDS --pipeline fast --out plans.jsonl --keep-going
    mrmt plan WORLDS --pipeline strong --option tour.moves=7

Exit code 1 when a plan fails, 2 on bad input. Design notes: docs/design/cli.md#mrmt-plan.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from agents.commands.options import add_chip_argument, chip_from_args

NAME = "plan"
HELP = "plan worlds from a JSON / JSON Lines file; one plan (JSON) per world"

#: Files with at least this many worlds get a progress bar.
PROGRESS_MIN_WORLDS = 20


def add_arguments(parser) -> None:
    parser.add_argument("worlds", metavar="WORLDS", help="world JSON file or JSON Lines file of worlds")
    parser.add_argument("--pipeline", default=None, help="preset: fast, strong (default), ising, ising-paper, ising-fleet, exact, pyvrp or ortools (extra peers)")
    parser.add_argument("--sharing", default=None, help="sharing layer: round_robin, psa, ssa, exact, ising")
    parser.add_argument("--tour", default=None, help="tour layer: nn, 2opt, 3opt, brute, ising")
    parser.add_argument("--path", default=None, help="path layer: bfs, astar, gbfs, ising")
    parser.add_argument(
        "--option",
        action="append",
        default=[],
        metavar="LAYER.KEY=VALUE",
        help="layer factory option, e.g. tour.moves=7 or sharing.bid=tour (repeatable)",
    )
    parser.add_argument("--chip", action="append", default=[], metavar="KEY=VALUE|FILE.json",
                        help="the chip of the Ising layers: any ChipSpec field (e.g. n_spins=64, "
                             "j_range=15 meaning (-15, 15), cores_per_chip=4) or a JSON file of fields; repeatable")
    add_chip_argument(parser, "the Ising layers", chip=False)
    parser.add_argument("--out", default=None, help="write the plans here (JSON Lines) instead of stdout")
    parser.add_argument("--seed", type=int, default=0, help="planning seed (default 0); line N uses [seed, N]")
    parser.add_argument("--keep-going", action="store_true", help='continue past bad lines: each gets {"error": ..., "line": N} in its output place (still exit 2)')
    from agents.commands.options import add_decision_arguments

    add_decision_arguments(parser, "this process")


def _error(message: str) -> None:
    print(f"mrmt plan: error: {message}", file=sys.stderr)


def _parse_options(items: list[str]) -> dict[str, dict]:
    from agents.keyvalues import split_items, typed

    options: dict[str, dict] = {"sharing": {}, "tour": {}, "path": {}}
    for key, raw in split_items(items, "--option", "tour.moves=7"):
        layer, dot, name = key.partition(".")
        if not dot or not name:
            raise ValueError(f"--option {key}={raw}: the key must look like LAYER.KEY (e.g. tour.moves=7)")
        if layer not in options:
            raise ValueError(f"--option {key}={raw}: layer {layer!r} is not one of sharing, tour, path")
        options[layer][name] = typed(raw)
    return options


def build_pipeline(args):
    """The pipeline the arguments ask for (raises ValueError / TypeError with a clear message)."""
    from planners.pipeline import make_pipeline

    options = _parse_options(args.option)
    preset = args.pipeline
    if preset is None and not (args.sharing and args.tour and args.path):
        preset = "strong"
    shared = {}
    chip = chip_from_args(args)
    if chip is not None:
        from ising_backend import build_machine

        shared["chip"] = build_machine(chip)
    try:
        return make_pipeline(
            preset,
            sharing=args.sharing,
            tour=args.tour,
            path=args.path,
            sharing_options=options["sharing"],
            tour_options=options["tour"],
            path_options=options["path"],
            **shared,
        )
    except ValueError as exc:
        if shared and "accepted by no layer" in str(exc):
            raise ValueError("--chip or --sampler given, but no layer of this pipeline runs on a chip (use --pipeline ising "
                             "or an ising layer)") from None
        raise


def _error_line(item: Exception) -> str:
    return str(item).replace("\n", " ")


def run(args) -> int:
    if args.seed < 0:
        _error(f"--seed must be >= 0 (a numpy seed), got {args.seed}")
        return 2
    if args.audit and Path(args.audit).exists() and not Path(args.audit).is_dir():
        _error(f"--audit {args.audit}: exists and is not a directory")
        return 2
    if args.host_rule:
        from ising_backend.audit.host_rule import parse_classes

        try:
            parse_classes(args.host_rule)
        except ValueError as exc:
            _error(f"--host-rule: {exc}")
            return 2
    try:
        pipeline = build_pipeline(args)
    except (ValueError, TypeError, ImportError, RuntimeError) as exc:
        _error(f"cannot build the pipeline: {type(exc).__name__}: {exc}" if isinstance(exc, (ImportError, RuntimeError))
               else str(exc))
        return 2
    from mrmt_env.io import iter_worlds_text, read_text
    from mrmt_env.world import WorldError

    path = Path(args.worlds)
    try:
        text = read_text(path)
    except WorldError as exc:
        _error(str(exc))
        return 2
    except OSError as exc:
        _error(f"{path}: cannot read ({exc.strerror or exc})")
        return 2
    # first pass: read and check every world, so a bad line is found before any planning
    total = 0
    bad_lines = []
    for line, item in iter_worlds_text(text, str(path)):
        total += 1
        if isinstance(item, Exception):
            bad_lines.append(line)
            if not args.keep_going:
                _error(_error_line(item))
    if total == 0:
        _error(f"{path}: no worlds (the file is empty)")
        return 2
    if bad_lines and not args.keep_going:
        if total > 1:
            _error(f"{len(bad_lines)} of {total} worlds in {path} are invalid, so none was planned; --keep-going "
                   'plans the valid ones and writes {"error": ..., "line": N} in place of each invalid one')
        return 2

    import os

    from tqdm import tqdm

    from agents.warmup import warm

    spec = "+".join((args.sharing, args.tour, args.path)) if args.sharing and args.tour and args.path \
        else (args.pipeline or "strong")
    warm([spec], jobs=min(2, os.cpu_count() or 1), progress=not args.no_progress)  # first run only
    out = sys.stdout
    if args.out:
        try:
            out = open(args.out, "w", encoding="utf-8")
        except OSError as exc:
            _error(f"{args.out}: cannot write ({exc.strerror or exc})")
            return 2
    bad = 0
    failed = 0
    planned = 0
    done = 0
    from contextlib import nullcontext

    from ising_backend.audit.record import Audit

    from agents.commands.options import host_rule_from_args

    audit = Audit(args.audit) if args.audit else nullcontext()
    host_rule = host_rule_from_args(args)  # checked in run()
    try:
        progress = tqdm(
            total=total,
            unit="world",
            file=sys.stderr,
            disable=args.no_progress or total < PROGRESS_MIN_WORLDS,
            desc="mrmt plan",
        )
        with progress, audit, host_rule:
            for line, item in iter_worlds_text(text, str(path)):
                progress.update(1)
                done += 1
                if not isinstance(item, Exception):
                    try:
                        record = pipeline.plan(item, seed=[args.seed, line]).to_dict()
                        planned += 1
                        failed += not record["success"]
                    except (ValueError, TypeError, RuntimeError) as exc:
                        item = ValueError(f"{path} line {line}: planning failed: {exc}")
                if isinstance(item, Exception):
                    bad += 1
                    message = _error_line(item)
                    if not args.keep_going:
                        rest = total - done
                        more = (f" (stopped: the {rest} world(s) after line {line} were not planned; --keep-going "
                                "plans past a world the planners refuse)") if rest else ""
                        progress.write(f"mrmt plan: error: {message}{more}", file=sys.stderr)
                        return 2
                    progress.write(f"mrmt plan: error: {message}", file=sys.stderr)
                    record = {"error": message, "line": line}
                out.write(json.dumps(record) + "\n")
                out.flush()
    finally:
        if out is not sys.stdout:
            out.close()
    if bad:
        return 2
    if failed:
        print(f"mrmt plan: {failed} of {planned} plans failed (\"success\": false; see their \"failure\")",
              file=sys.stderr)
        return 1
    return 0
