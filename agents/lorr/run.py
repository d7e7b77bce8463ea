"""One LoRR run: an instance, a scheduler and an executor, stepped as the start kit steps them.

Per step the scheduler proposes, the executor moves, the simulator applies; a step's time is the decision's
latency (host seconds plus the chip's own time), energies are per finished task in both conventions. Under a step
limit (:mod:`mrmt_env.lorr.clock`) a late decision costs its timeouts; without one a run is deterministic.
Design notes: docs/design/lorr_runs.md#one-run.
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
from agents.lorr.roles import Planner, Scheduler, charge
from agents.lorr.scores import best_known
from agents.lorr.spec import PlannerSpec, SchedulerSpec, is_class_path, specs_from_options

__all__ = ["run_lorr", "best_known", "make_roles", "peak_rss_mb", "RUN_KEYS", "MEASURED_KEYS", "Loop"]

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


def _warm(sched: SchedulerSpec, planner: PlannerSpec, chip) -> None:
    key = (sched.name, planner.name)
    if key in _WARM or is_class_path(sched.name) or is_class_path(planner.name):  # a user's role: none of ours
        return
    _WARM.add(key)
    from ising_backend.audit.record import suspended

    with suspended():  # compiling decides nothing of the run: an open audit records none of it
        _loop(read_instance(example_instance_path()), sched, planner, 3, 0, chip, None)


def make_roles(grid, scheduler, planner, seed: int = 0, chip=None):
    """The scheduler and the one-step planner of a run on ``grid``, as the runner and the start kit's adapter
    (:mod:`agents.lorr.startkit`, one role each) build them: from their specs (:mod:`agents.lorr.spec`), an object
    meeting its role used as it is; ``chip`` (a machine recipe) for the chip scheduler and the chip planners, each a
    machine of its own."""
    sched = scheduler.build(seed, chip) if isinstance(scheduler, SchedulerSpec) else scheduler
    check_chip_use(chip, sched, _name(scheduler), planner)
    if not isinstance(planner, PlannerSpec):
        return sched, planner
    machine = None
    if chip is not None and planner.machine:  # the same machine recipe, a machine of the planner's own
        from ising_backend import build_machine

        machine = build_machine(chip, seed)
    return sched, planner.build(grid, seed, machine)


def check_chip_use(chip, sched, scheduler: str, planner) -> None:
    """``ValueError`` when a machine is given (``chip``: ``--chip`` / ``--sampler``) but neither the scheduler
    ``sched`` (named ``scheduler``) nor the ``planner`` (a spec) runs on one: nothing given is dropped unsaid."""
    from planners.mapf import MACHINE_PLANNERS

    takes = isinstance(planner, PlannerSpec) and planner.machine
    if chip is not None and not takes and not getattr(sched, "accelerated", False):
        raise ValueError(f"--chip or --sampler given, but neither the scheduler {scheduler!r} nor the planner "
                         f"{_name(planner)!r} runs on a machine (chip schedulers: lorr-ising, ising, fast, ising-paper "
                         f"or a pair with an ising layer; chip planners: {', '.join(MACHINE_PLANNERS)})")


def _loop(inst, scheduler, planner, steps, seed, chip, bar, limit=None):
    """The run: per decision, ``(scheduler host, planner host, chip)`` seconds and the CPU seconds beyond the wall;
    under ``limit`` (a :class:`~mrmt_env.lorr.clock.StepLimit`) a late decision costs its timeouts first.
    ``scheduler`` / ``planner``: specs, or objects meeting the roles (used as they are)."""
    t0 = time.perf_counter()
    sched, ex = make_roles(inst.grid, scheduler, planner, seed, chip)
    sim = LoRRSimulator(inst)
    loop = StepLoop(sim, sched)
    prep_s = time.perf_counter() - t0
    n = []  # per decision: scheduler host, planner host, chip seconds
    busy = []  # CPU seconds beyond the wall (a planner's plans on several threads)
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
        c, e = charge(sched), charge(ex)  # a planner with a chip decision charges it too
        n.append((max(t1 - t0 - c.emulation_s, 0.0), max(t2 - t1 - e.emulation_s, 0.0),
                  c.chip_time_parallel_s + e.chip_time_parallel_s))
        accel_j += c.accelerator_energy_j + e.accelerator_energy_j
        calls += c.chip_calls + c.logical_calls + e.chip_calls
        before = sim.t
        loop.advance(actions, 0 if limit is None else limit.timeouts(sum(n[-1])), steps)
        if bar is not None:
            bar.update(sim.t - before)
    return Loop(sim, sched, ex, np.array(n).reshape(-1, 3), np.array(busy), accel_j, calls, prep_s)


def _as_roles(scheduler, planner, options):
    """``(scheduler, planner)`` as specs (names with the dict ``options``, or specs) or role objects; ``ValueError``
    for an object that does not meet its role."""
    from agents.lorr.spec import check_role

    if isinstance(scheduler, str) and isinstance(planner, str):
        return specs_from_options(scheduler, planner, options)
    if options:
        raise ValueError("options= goes with a scheduler and a planner named by strings; give specs "
                         "(agents.lorr.spec) or objects instead")
    if isinstance(scheduler, str):
        scheduler = SchedulerSpec(scheduler)
    if isinstance(planner, str):
        planner = PlannerSpec.of(planner)
    if not isinstance(scheduler, SchedulerSpec):
        check_role(scheduler, Scheduler, f"scheduler {type(scheduler).__name__}")
    if not isinstance(planner, PlannerSpec):
        check_role(planner, Planner, f"planner {type(planner).__name__}")
    return scheduler, planner


def run_lorr(instance, scheduler="lorr-greedy", executor="pibt", steps: int | None = None,
             seed: int = 0, chip=None, progress: bool = False, options: dict | None = None, limit=None):
    """Run ``instance`` (a path or :class:`LoRRInstance`) for ``steps`` (default: its simulation
    time); returns ``(record, sim, decision_seconds)`` -- the record's keys are :data:`RUN_KEYS`.  ``scheduler`` and
    ``executor`` (the planner): names (with ``options``, the dict form of :func:`agents.lorr.spec.specs_from_options`:
    ``replan``, ``keep``, ``scheduler_options``, ``guidance``, ``planner_options``), specs
    (:class:`~agents.lorr.spec.SchedulerSpec`, :class:`~agents.lorr.spec.PlannerSpec`), or objects that meet the
    roles (:mod:`agents.lorr.roles`: a user's own, used as they are).  ``limit``: a
    :class:`~mrmt_env.lorr.clock.StepLimit` runs under the start kit's clock (a late decision costs timeouts; the
    record's ``clock`` says so); ``None`` (default) is work-bounded and deterministic."""
    inst = instance if isinstance(instance, LoRRInstance) else read_instance(Path(instance))
    steps = int(steps or inst.steps or DEFAULT_STEPS)
    scheduler, executor = _as_roles(scheduler, executor, options)
    if isinstance(scheduler, SchedulerSpec) and isinstance(executor, PlannerSpec):
        _warm(scheduler, executor, chip)
    s_name, p_name = _name(scheduler), _name(executor)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=steps, desc=f"{inst.name} {s_name}+{p_name}", file=sys.stderr, leave=False)
    try:
        run = _loop(inst, scheduler, executor, steps, seed, chip, bar, limit)
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
        "instance": inst.name, "scheduler": s_name, "executor": p_name, "guidance": getattr(run.ex, "guidance", None),
        "executor_options": _given(executor), "scheduler_options": _given(scheduler), "seed": int(seed),
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
        "chip_s": chip_s, "paper_energy_per_task_j": (run.accel_j if getattr(run.sched, "accelerated", False) else host_j)
        / done,
        "total_energy_per_task_j": (host_j + run.accel_j) / done, "host_energy_per_task_j": host_j / done,
        "machine_energy_per_task_j": run.accel_j / done, "peak_rss_mb": peak_rss_mb(),
    }
    return record, sim, step_s


def _name(role) -> str:
    """A role's name: its spec's, else its own ``name``, else its class's."""
    return role.name if isinstance(role, (SchedulerSpec, PlannerSpec)) else getattr(role, "name", type(role).__name__)


def _given(role) -> dict:
    """The options a spec was given (a planner's without ``guidance``, recorded apart); none for an object."""
    if isinstance(role, PlannerSpec):
        return {k: v for k, v in role.given.items() if k != "guidance"}
    return dict(role.options) if isinstance(role, SchedulerSpec) else {}


def peak_rss_mb() -> float:
    """This process's peak resident memory so far, MiB (a run in a fresh process: the run's own peak)."""
    import resource

    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return float(peak) / (1 << 20 if sys.platform == "darwin" else 1 << 10)
