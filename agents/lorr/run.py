"""One LoRR run: an instance, a scheduler and an executor, stepped as the start kit steps them.

Per step: the scheduler proposes (2024 instances), the executor turns the proposed tasks' next
errands into a joint MAPF_T move, the simulator moves and applies the proposal.  The step time is
the decision's latency as the start kit would see it: host seconds of scheduler + executor (wall
seconds minus the time spent emulating the chip) plus the chip's own time (8-core parallel
dispatch).  Energies per finished task in both conventions (paper section 6.1): the paper's
(accelerator only for a scheduler with Ising layers, else host x 15 W) and the total; the host's seconds
for energy are CPU seconds of every thread (``host_cpu_s``: an executor's portfolio on several threads), at
least the wall seconds (``host_s``).  Under a step limit (:mod:`mrmt_env.lorr.clock`) the scheduler and the
executor get the step's deadline and a late decision costs its timeouts; without one a run is work-bounded
and deterministic, and its record says which (``clock``).  Kernels are compiled before the first timed step,
on the shipped example instance (the entry's build, not its preprocessing).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

from mrmt_env.lorr.env import DEFAULT_STEPS
from mrmt_env.lorr.instance import LoRRInstance, example_instance_path, read_instance
from mrmt_env.lorr.loop import StepLoop
from mrmt_env.lorr.sim import LoRRSimulator
from planners.compute import CPU_WATTS_PER_CORE
from agents.lorr.scores import best_known

__all__ = ["run_lorr", "best_known", "make_roles", "split_options", "peak_rss_mb", "RUN_KEYS", "MEASURED_KEYS", "Loop"]

RUN_KEYS = ("instance", "scheduler", "executor", "guidance", "executor_options", "scheduler_options", "seed", "robots",
            "steps", "tasks_finished", "best_known",
            "share_of_best", "errands", "errors", "schedule_errors", "step_p50_s", "step_p99_s", "step_max_s",
            "scheduler_p99_s", "executor_p99_s", "chip_calls", "host_s", "host_cpu_s", "chip_s", "paper_energy_per_task_j",
            "total_energy_per_task_j", "host_energy_per_task_j", "machine_energy_per_task_j", "clock", "timeouts",
            "decisions", "preprocess_s", "preprocess_timeout", "peak_rss_mb")
# what a run measures of the machine it ran on (seconds, joules, memory): differs run to run; the rest does not
MEASURED_KEYS = tuple(k for k in RUN_KEYS if k.endswith("_s") or "energy" in k or k == "peak_rss_mb")
_WARM: set = set()


class Loop(NamedTuple):
    """What a run's step loop leaves: the simulator, the scheduler and executor, per decision ``(scheduler host,
    executor host, chip)`` seconds and CPU seconds beyond the wall, accelerator joules, chip calls, and the
    preprocessing seconds (building the scheduler, the executor and the simulator)."""

    sim: LoRRSimulator
    sched: object
    ex: object
    seconds: np.ndarray
    busy: np.ndarray
    accel_j: float
    calls: int
    preprocess_s: float


def _warm(scheduler: str, executor: str, chip, options) -> None:
    if (scheduler, executor) in _WARM:
        return
    _WARM.add((scheduler, executor))
    from ising_backend.audit.record import suspended

    with suspended():  # compiling decides nothing of the run: an open audit records none of it
        _loop(read_instance(example_instance_path()), scheduler, executor, 3, 0, chip, dict(options), None)


def split_options(options: dict | None) -> tuple[dict, dict]:
    """:func:`run_lorr`'s ``options`` as ``(scheduler's, planner's)``: ``guidance`` and ``executor_options`` go to
    the planner, the rest to :func:`~agents.lorr.schedulers.make_scheduler`."""
    options = dict(options or {})
    planner = dict(options.pop("executor_options", None) or {})
    if "guidance" in options:
        if "guidance" in planner:
            raise ValueError(f"guidance given twice ({options['guidance']!r} and the planner option's "
                             f"{planner['guidance']!r}); give it once")
        planner["guidance"] = options.pop("guidance")
    return options, planner


def make_roles(grid, scheduler: str, executor: str, seed: int = 0, chip=None, options: dict | None = None):
    """The scheduler and the one-step planner of a run on ``grid`` (``options`` as :func:`run_lorr`'s), as the
    runner and the start kit's adapter (:mod:`agents.lorr.startkit`, one role each) build them."""
    from agents.lorr.schedulers import make_scheduler
    from planners.mapf import MACHINE_PLANNERS, make_turning_executor

    sched_options, planner_options = split_options(options)
    sched = make_scheduler(scheduler, seed=seed, chip=chip, **sched_options)
    check_chip_use(chip, sched, scheduler, executor)
    if chip is not None and executor in MACHINE_PLANNERS:  # the same machine recipe, a machine of the planner's own
        from ising_backend import build_machine

        planner_options["machine"] = build_machine(chip, seed)
    return sched, make_turning_executor(executor, grid, seed=seed, **planner_options)


def check_chip_use(chip, sched, scheduler: str, executor: str) -> None:
    """``ValueError`` when a machine is given (``chip``: ``--chip`` / ``--sampler``) but neither the scheduler
    ``sched`` (named ``scheduler``) nor the planner ``executor`` runs on one: nothing given is dropped unsaid."""
    from planners.mapf import MACHINE_PLANNERS

    if chip is not None and executor not in MACHINE_PLANNERS and not sched.accelerated:
        raise ValueError(f"--chip or --sampler given, but neither the scheduler {scheduler!r} nor the planner "
                         f"{executor!r} runs on a machine (chip schedulers: lorr-ising, ising, fast, ising-paper or a "
                         f"pair with an ising layer; chip planners: {', '.join(MACHINE_PLANNERS)})")


def _loop(inst, scheduler, executor, steps, seed, chip, options, bar, limit=None):
    """The run: per decision, ``(scheduler host, executor host, chip)`` seconds and the CPU seconds beyond the wall;
    under ``limit`` (a :class:`~mrmt_env.lorr.clock.StepLimit`) a late decision costs its timeouts first."""
    t0 = time.perf_counter()
    sched, ex = make_roles(inst.grid, scheduler, executor, seed, chip, options)
    sim = LoRRSimulator(inst)
    loop = StepLoop(sim, sched)
    prep_s = time.perf_counter() - t0
    n = []  # per decision: scheduler host, executor host, chip seconds
    busy = []  # CPU seconds beyond the wall (an executor's plans on several threads)
    accel_j = 0.0
    calls = 0
    while sim.t < steps:
        t0 = time.perf_counter()
        deadline = None if limit is None else t0 + limit.step_s
        loop.propose(deadline)
        t1 = time.perf_counter()
        c1 = time.process_time()
        actions = ex.actions(sim.pos, sim.orient, loop.goal_cells(), deadline=deadline, **loop.rest_for(ex))
        t2 = time.perf_counter()
        busy.append(max(time.process_time() - c1 - (t2 - t1), 0.0))
        c, e = sched.last_compute, ex.last_compute  # an executor with a chip decision charges it too
        n.append((max(t1 - t0 - c.emulation_s, 0.0), max(t2 - t1 - e.emulation_s, 0.0),
                  c.chip_time_parallel_s + e.chip_time_parallel_s))
        accel_j += c.accelerator_energy_j + e.accelerator_energy_j
        calls += c.chip_calls + c.logical_calls + e.chip_calls
        before = sim.t
        loop.advance(actions, 0 if limit is None else limit.timeouts(sum(n[-1])), steps)
        if bar is not None:
            bar.update(sim.t - before)
    return Loop(sim, sched, ex, np.array(n).reshape(-1, 3), np.array(busy), accel_j, calls, prep_s)


def run_lorr(instance, scheduler: str = "lorr-greedy", executor: str = "pibt", steps: int | None = None,
             seed: int = 0, chip=None, progress: bool = False, options: dict | None = None, limit=None):
    """Run ``instance`` (a path or :class:`LoRRInstance`) for ``steps`` (default: its simulation
    time); returns ``(record, sim, decision_seconds)`` -- the record's keys are :data:`RUN_KEYS`.  ``options``:
    the scheduler's (:func:`agents.lorr.schedulers.make_scheduler`), ``guidance`` for the executor
    (:mod:`planners.mapf.guides.guidance`; default: the executor's own) and ``executor_options``, a dict of the
    executor's own keyword options (e.g. ``{"weight_power": 2}`` for ``epibt``).  ``limit``: a
    :class:`~mrmt_env.lorr.clock.StepLimit` runs under the start kit's clock (a late decision costs timeouts; the
    record's ``clock`` says so); ``None`` (default) is work-bounded and deterministic."""
    inst = instance if isinstance(instance, LoRRInstance) else read_instance(Path(instance))
    steps = int(steps or inst.steps or DEFAULT_STEPS)
    options = dict(options or {})
    _warm(scheduler, executor, chip, options)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=steps, desc=f"{inst.name} {scheduler}+{executor}", file=sys.stderr, leave=False)
    try:
        run = _loop(inst, scheduler, executor, steps, seed, chip, options, bar, limit)
    finally:
        if bar is not None:
            bar.close()
    sim, n = run.sim, run.seconds
    step_s = n.sum(axis=1)
    done = max(sim.finished, 1)
    host_s, chip_s = float(n[:, :2].sum()), float(n[:, 2].sum())
    host_cpu_s = host_s + float(run.busy.sum())
    host_j = host_cpu_s * CPU_WATTS_PER_CORE  # each busy core's seconds: a portfolio's threads too
    best = best_known(inst)
    record = {
        "instance": inst.name, "scheduler": scheduler, "executor": executor, "guidance": run.ex.guidance,
        "executor_options": dict(options.get("executor_options") or {}),
        "scheduler_options": dict(options.get("scheduler_options") or {}), "seed": int(seed),
        "robots": inst.team_size, "steps": steps, "tasks_finished": sim.finished, "best_known": best,
        # the best-known is over the instance's full simulation time: a share only for a full run
        "share_of_best": (sim.finished / best) if best and steps == inst.steps else None,
        "errands": sim.tasks.errands_done,
        "errors": len(sim.errors), "schedule_errors": len(sim.tasks.schedule_errors),
        "clock": "work-bounded" if limit is None else limit.label(), "timeouts": sim.timeouts,
        "decisions": len(step_s), "preprocess_s": run.preprocess_s,
        "preprocess_timeout": limit is not None and run.preprocess_s > limit.preprocess_s,
        "step_p50_s": float(np.percentile(step_s, 50)), "step_p99_s": float(np.percentile(step_s, 99)),
        "step_max_s": float(step_s.max()), "scheduler_p99_s": float(np.percentile(n[:, 0] + n[:, 2], 99)),
        "executor_p99_s": float(np.percentile(n[:, 1], 99)), "chip_calls": int(run.calls), "host_s": host_s,
        "host_cpu_s": host_cpu_s,
        "chip_s": chip_s, "paper_energy_per_task_j": (run.accel_j if run.sched.accelerated else host_j) / done,
        "total_energy_per_task_j": (host_j + run.accel_j) / done, "host_energy_per_task_j": host_j / done,
        "machine_energy_per_task_j": run.accel_j / done, "peak_rss_mb": peak_rss_mb(),
    }
    return record, sim, step_s


def peak_rss_mb() -> float:
    """This process's peak resident memory so far, MiB (a run in a fresh process: the run's own peak)."""
    import resource

    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return float(peak) / (1 << 20 if sys.platform == "darwin" else 1 << 10)
