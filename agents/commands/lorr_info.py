"""``mrmt lorr check | startkit | options``: re-simulate an output file, print how the start kit runs the entry, list a
planner's or a scheduler's options.

    mrmt lorr check RANDOM-01.json OUTPUT.json [--json]
    mrmt lorr startkit [--kit 2026]
    mrmt lorr options [PLANNER|SCHEDULER]

Bad input: one line, exit 2.
"""

from __future__ import annotations

import json
import sys


def add_parsers(sub) -> None:
    check = sub.add_parser("check", help="re-simulate an output file on its instance")
    check.add_argument("instance", metavar="INSTANCE.json")
    check.add_argument("output", metavar="OUTPUT.json", help="an output file (or a .zip holding one)")
    check.add_argument("--json", action="store_true", help="one JSON object: numTaskFinished, errors, steps")
    kit = sub.add_parser("startkit", help="print how the start kit runs the package's entry (2024: its python_path; "
                                          "2026: the files to put in place)")
    kit.add_argument("--kit", type=int, choices=(2024, 2026), default=2024, help="the start kit's year (default 2024)")
    opts = sub.add_parser("options", help="list a planner's options (--planner-option KEY=VALUE) or a scheduler's "
                                          "(--scheduler-option): name, default, what it takes, what it does")
    opts.add_argument("planner", nargs="?", default=None, help="a planner or a scheduler (default: every one)")


def check(args) -> int:
    from mrmt_env.lorr.output import OutputError, check_output, read_output
    from mrmt_env.lorr.instance import LoRRFormatError, read_instance

    try:
        inst = read_instance(args.instance)
        result = check_output(inst, read_output(args.output), path=args.output)
    except (LoRRFormatError, OutputError) as exc:
        return _fail(str(exc))
    if args.json:
        print(json.dumps(result.to_json()))
        return 0
    tasks = "unknown (the file holds no schedule)" if result.tasks_finished is None else result.tasks_finished
    print(f"{inst.name}: {result.steps} steps, tasks finished {tasks}, errors {result.errors}, "
          f"schedule errors {result.schedule_errors}, timeouts {result.timeouts}")
    if result.events_agree is False:
        print("the file's events are not the re-simulated ones (a step, robot, task or errand differs)")
    if result.claimed is not None and result.tasks_finished is not None and result.claimed != result.tasks_finished:
        print(f"the file claims {result.claimed} tasks finished; re-simulated: {result.tasks_finished}")
    return 0


def startkit(args) -> int:
    from agents.lorr.startkit import TRACK_DIR, TRACK_DIR_2026

    if args.kit == 2026:
        print(f"from the kit's folder: cp {TRACK_DIR_2026}/pyMAPFPlanner.py python/user_planner/ && "
              f"cp {TRACK_DIR_2026}/pyTaskScheduler.py python/user_scheduler/")
        print("then: ./build/lifelong -i INSTANCE.json -o output.json --plannerPython true --schedulerPython true "
              "(the kit's own executor stages each window)")
        print("entry: MRMT_LORR_ENTRY=default (a name or a .toml file); seed: MRMT_LORR_SEED=0; window: "
              "MRMT_LORR_WINDOW (default: the kit's executor's); compile first: mrmt warmup")
        return 0
    print(f"config.json: {json.dumps({'python_path': str(TRACK_DIR)})}")
    print(f"from the kit's folder (its python/ samples have the same module names; this puts the package's first): "
          f"PYTHONPATH={TRACK_DIR}:$PYTHONPATH ./build/lifelong -i INSTANCE.json -o output.json")
    print("entry: MRMT_LORR_ENTRY=default (a name or a .toml file); seed: MRMT_LORR_SEED=0; compile first: mrmt warmup")
    return 0


def options(args) -> int:
    from agents.lorr.schedulers import SCHEDULERS, scheduler_options
    from planners.mapf import TURNING_PLANNERS

    name = args.planner
    if name is not None and name not in TURNING_PLANNERS and name not in SCHEDULERS:
        return _fail(f"unknown planner {name!r}; known: {', '.join(TURNING_PLANNERS)}; schedulers: "
                     f"{', '.join(SCHEDULERS)}")
    planners = [name] if name in TURNING_PLANNERS else [] if name else list(TURNING_PLANNERS)
    schedulers = [name] if name in SCHEDULERS else [] if name else list(SCHEDULERS)
    for kind, names, rows in (("", planners, lambda n: TURNING_PLANNERS[n].Options.describe()),
                              (" (scheduler)", schedulers, scheduler_options)):
        for n in names:
            print(f"{n}{kind}:")
            for key, default, allowed, meaning in rows(n):
                print(f"  {key} = {json.dumps(default)}  ({allowed}) {meaning}")
    return 0


def _fail(message: str) -> int:
    print(f"mrmt lorr: error: {message}", file=sys.stderr)
    return 2
