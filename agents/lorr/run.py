"""One LoRR run: an instance, a scheduler and an executor, stepped as the start kit steps them.

Per step: the scheduler proposes (2024 instances), the executor turns the proposed tasks' next
errands into a joint MAPF_T move, the simulator moves and applies the proposal.  The step time is
the decision's latency as the start kit would see it: host seconds of scheduler + executor (wall
seconds minus the time spent emulating the chip) plus the chip's own time (8-core parallel
dispatch).  Energies per finished task in both conventions (paper section 6.1): the paper's
(accelerator only for a scheduler with Ising layers, else host x 15 W) and the total; the host's seconds
for energy are CPU seconds of every thread (``host_cpu_s``: an executor's portfolio on several threads), at
least the wall seconds (``host_s``).
Kernels are compiled before the first timed step, on the shipped example instance.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

from mrmt_env.lorr.env import DEFAULT_STEPS
from mrmt_env.lorr.instance import LoRRInstance, example_instance_path, read_instance
from mrmt_env.lorr.sim import LoRRSimulator
from planners.compute import CPU_WATTS_PER_CORE

__all__ = ["run_lorr", "best_known", "proposal_goals", "RUN_KEYS"]

RUN_KEYS = ("instance", "scheduler", "executor", "guidance", "executor_options", "seed", "robots", "steps", "tasks_finished", "best_known",
            "share_of_best", "errands", "errors", "schedule_errors", "step_p50_s", "step_p99_s", "step_max_s",
            "scheduler_p99_s", "executor_p99_s", "chip_calls", "host_s", "host_cpu_s", "chip_s", "paper_energy_per_task_j",
            "total_energy_per_task_j")
_WARM: set = set()


def best_known(instance: LoRRInstance) -> int | None:
    """The best-known tasks finished of ``instance`` from a ``best_known.json`` in its folder or up
    to three above (``{"<year>": {"NAME": [agents, steps, tasks]}}``), else ``None``."""
    folder = instance.path.parent
    for d in [folder, *list(folder.parents)[:3]]:
        f = d / "best_known.json"
        if f.is_file():
            try:
                table = json.loads(f.read_text())
            except (OSError, ValueError):
                return None
            for section in table.values():
                if isinstance(section, dict) and instance.name in section:
                    row = section[instance.name]
                    return int(row[-1]) if isinstance(row, list) and row else None
    return None


def proposal_goals(sim: LoRRSimulator, proposal) -> np.ndarray:
    """The cell each robot heads for under ``proposal``: its task's next errand, else its own cell."""
    tasks = sim.tasks
    goals = np.where(tasks.goal >= 0, tasks.goal, sim.pos)
    if proposal is None:
        return goals
    proposal = np.asarray(proposal)
    for a in np.flatnonzero(proposal != tasks.assigned).tolist():
        k = int(proposal[a])
        goals[a] = int(tasks.remaining(k)[0]) if k in tasks.open else sim.pos[a]
    return goals


def _warm(scheduler: str, executor: str, chip, options) -> None:
    if (scheduler, executor) in _WARM:
        return
    _WARM.add((scheduler, executor))
    from ising_backend.audit import suspended

    with suspended():  # compiling decides nothing of the run: an open audit records none of it
        _loop(read_instance(example_instance_path()), scheduler, executor, 3, 0, chip, dict(options), None)


def _loop(inst, scheduler, executor, steps, seed, chip, options, bar):
    from agents.lorr.schedulers import make_scheduler
    from planners.mapf import make_turning_executor

    options = dict(options)
    ex_options = dict(options.pop("executor_options", None) or {})
    if "guidance" in options:
        ex_options["guidance"] = options.pop("guidance")
    sched = make_scheduler(scheduler, seed=seed, chip=chip, **options)
    ex = make_turning_executor(executor, inst.grid, seed=seed, **ex_options)
    sim = LoRRSimulator(inst)
    sched.reset(sim)
    n = np.zeros((steps, 3))  # scheduler host, executor host, chip seconds
    busy = np.zeros(steps)  # CPU seconds beyond the wall (an executor's plans on several threads)
    accel_j = 0.0
    calls = 0
    for t in range(steps):
        t0 = time.perf_counter()
        proposal = sched.schedule(sim) if inst.strategy is None else None
        t1 = time.perf_counter()
        c1 = time.process_time()
        actions = ex.actions(sim.pos, sim.orient, proposal_goals(sim, proposal))
        t2 = time.perf_counter()
        busy[t] = max(time.process_time() - c1 - (t2 - t1), 0.0)
        c, e = sched.last_compute, ex.last_compute  # an executor with a chip decision charges it too
        n[t] = (max(t1 - t0 - c.emulation_s, 0.0), max(t2 - t1 - e.emulation_s, 0.0),
                c.chip_time_parallel_s + e.chip_time_parallel_s)
        accel_j += c.accelerator_energy_j + e.accelerator_energy_j
        calls += c.chip_calls + c.logical_calls + e.chip_calls
        sim.step(actions, proposal)
        if bar is not None:
            bar.update(1)
    return sim, sched, ex, n, busy, accel_j, calls


def run_lorr(instance, scheduler: str = "lorr-greedy", executor: str = "pibt", steps: int | None = None,
             seed: int = 0, chip=None, progress: bool = False, options: dict | None = None):
    """Run ``instance`` (a path or :class:`LoRRInstance`) for ``steps`` (default: its simulation
    time); returns ``(record, sim, step_seconds)`` -- the record's keys are :data:`RUN_KEYS`.  ``options``:
    the scheduler's (:func:`agents.lorr.schedulers.make_scheduler`), ``guidance`` for the executor
    (:mod:`planners.mapf.guidance`; default: the executor's own) and ``executor_options``, a dict of the
    executor's own keyword options (e.g. ``{"weight_power": 2}`` for ``epibt``)."""
    inst = instance if isinstance(instance, LoRRInstance) else read_instance(Path(instance))
    steps = int(steps or inst.steps or DEFAULT_STEPS)
    options = dict(options or {})
    _warm(scheduler, executor, chip, options)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=steps, desc=f"{inst.name} {scheduler}+{executor}", file=sys.stderr, leave=False)
    try:
        sim, sched, ex, n, busy, accel_j, calls = _loop(inst, scheduler, executor, steps, seed, chip, options, bar)
    finally:
        if bar is not None:
            bar.close()
    step_s = n.sum(axis=1)
    done = max(sim.finished, 1)
    host_s, chip_s = float(n[:, :2].sum()), float(n[:, 2].sum())
    host_cpu_s = host_s + float(busy.sum())
    host_j = host_cpu_s * CPU_WATTS_PER_CORE  # each busy core's seconds: a portfolio's threads too
    best = best_known(inst)
    record = {
        "instance": inst.name, "scheduler": scheduler, "executor": executor, "guidance": ex.guidance,
        "executor_options": dict(options.get("executor_options") or {}), "seed": int(seed),
        "robots": inst.team_size, "steps": steps, "tasks_finished": sim.finished, "best_known": best,
        # the best-known is over the instance's full simulation time: a share only for a full run
        "share_of_best": (sim.finished / best) if best and steps == inst.steps else None,
        "errands": sim.tasks.errands_done,
        "errors": len(sim.errors), "schedule_errors": len(sim.tasks.schedule_errors),
        "step_p50_s": float(np.percentile(step_s, 50)), "step_p99_s": float(np.percentile(step_s, 99)),
        "step_max_s": float(step_s.max()), "scheduler_p99_s": float(np.percentile(n[:, 0] + n[:, 2], 99)),
        "executor_p99_s": float(np.percentile(n[:, 1], 99)), "chip_calls": int(calls), "host_s": host_s,
        "host_cpu_s": host_cpu_s,
        "chip_s": chip_s, "paper_energy_per_task_j": (accel_j if sched.accelerated else host_j) / done,
        "total_energy_per_task_j": (host_j + accel_j) / done,
    }
    return record, sim, step_s
