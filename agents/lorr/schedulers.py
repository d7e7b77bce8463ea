"""LoRR schedulers: which robot takes which task, proposed once per step.

``lorr-greedy`` (the start kit's), ``lorr-weighted`` (the 2024 winner's measure), ``lorr-ising`` (the chip in
contested groups), a pipeline spec (the package's sharing and tour layers) or ``ppo:MODEL.zip``. Free robots
shortlist their ``shortlist`` tasks of least makespan; ``replan`` and ``keep`` re-plan robots whose task is not
opened yet. Every scheduler leaves its step's compute in ``last_compute``.
Design notes: docs/design/lorr_runs.md#schedulers.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from mrmt_env.lorr.greedy import FAR, MAX_WAY, GreedyScheduler
from planners.compute import ComputeReport
from planners.options import Options, option

__all__ = ["AssignerScheduler", "AssignerOptions", "make_scheduler", "scheduler_options", "SCHEDULERS"]

#: Free tasks each free robot shortlists for a pipeline or learned decision (least makespan first).
DEFAULT_SHORTLIST = 6
#: Scheduler names besides pipeline specs and ``ppo:PATH``.
SCHEDULERS = ("lorr-greedy", "lorr-weighted", "lorr-ising", "strong", "ising", "fast", "ising-paper")


@dataclass(frozen=True)
class AssignerOptions(Options):
    """A pipeline or learned scheduler's own options (module docstring); the rest go to its layers."""

    replan: bool = option(False, bool, meaning="robots whose task is not opened yet are free again when a task "
                          "finishes")
    shortlist: int | None = option(DEFAULT_SHORTLIST, int, 1, 1 << 20, none=True, meaning="free tasks each free "
                                   "robot shortlists, least makespan first (null: every free task)")
    keep: bool = option(True, bool, meaning="with replan: a re-planned robot keeps its task unless given one of "
                        "smaller makespan or its task goes to another robot")


class AssignerScheduler:
    """A lifelong assigner (``assign(grid, fields, idle_cells, task_cells, seed, fleet)``) as a LoRR
    scheduler (see the module docstring); ``options``: the fields of :class:`AssignerOptions`."""

    Options = AssignerOptions

    def __init__(self, assigner, seed: int = 0, **options) -> None:
        self.options = opts = AssignerOptions.from_dict(options, assigner.name)
        self.shortlist, self.replan, self.keep = opts.shortlist, opts.replan, opts.keep
        self.assigner = assigner
        self.name = assigner.name
        self.accelerated = bool(assigner.accelerated)
        self.seed = int(seed)
        self.last_compute = ComputeReport()

    def reset(self, sim) -> None:
        from planners.mapf.common import GoalFields

        self.grid = sim.inst.grid
        self.fields = GoalFields(self.grid, capacity=max(1024, 2 * sim.inst.open_target()))
        self.lengths = GreedyScheduler(work_budget=1 << 62)
        self.lengths.reset(sim)
        self.last_compute = ComputeReport()

    def schedule(self, sim, deadline: float | None = None) -> np.ndarray:
        """The proposal for this step (``deadline``: the step's ``time.perf_counter()`` deadline under a clock, or
        ``None``; the decision here is bounded by its groups and shortlist, not by it)."""
        from agents.lifelong.controllers import Round

        tasks = sim.tasks
        self.last_compute = ComputeReport()
        before = tasks.assigned
        proposal = before.copy()
        held = proposal >= 0
        if self.replan and len(tasks.new_free):
            unopened = np.array([k >= 0 and not tasks.is_opened(int(k)) for k in proposal.tolist()])
            proposal[unopened] = -1
            held = proposal >= 0
        free_robots = np.flatnonzero(~held)
        taken = set(proposal[held].tolist())
        free_ids = [k for k in tasks.open if k not in taken]
        if len(free_robots) == 0 or not free_ids:
            return proposal
        cells = np.array([tasks.remaining(k)[0] for k in free_ids], dtype=np.int64)
        ids = np.asarray(free_ids, dtype=np.int64)
        pos = sim.pos
        rank = ids
        if self.shortlist is not None and len(ids) > self.shortlist:
            keep, length = self._shortlist(tasks, ids, cells, pos[free_robots])
            ids, cells, rank = ids[keep], cells[keep], length[keep]
        # one task per cell: the shortest there (then the lowest id)
        order = np.lexsort((ids, rank, cells))
        cells, first = np.unique(cells[order], return_index=True)
        ids = ids[order][first]
        goals = np.where(tasks.goal >= 0, tasks.goal, pos)
        goals[free_robots] = pos[free_robots]
        rnd = Round(self.grid, pos, goals, free_robots, cells)
        queues, compute = self.assigner.assign(self.grid, self.fields, pos[free_robots], cells,
                                               seed=self.seed * 1_000_003 + sim.t, fleet=rnd)
        self.last_compute = compute
        for i, q in enumerate(queues):
            if q:
                proposal[free_robots[i]] = ids[q[0]]
        if self.replan and self.keep:
            self._keep(tasks, pos, before, proposal)
        return proposal

    def makespan(self, tasks, task: int, cell: int) -> int | np.int64:
        """The start kit's makespan of unopened ``task`` from ``cell``: the way to its first errand, then through
        every errand (:data:`~mrmt_env.lorr.greedy.FAR` when cut off)."""
        way = int(self.fields.fields[self.fields.rows(np.array([tasks.remaining(task)[0]]))[0], cell])
        length = int(self.lengths.task_length(tasks, np.array([task]), 1 << 62)[0])
        return FAR if way < 0 or length >= FAR else way + length

    def _keep(self, tasks, pos, before: np.ndarray, proposal: np.ndarray) -> None:
        """In place: each robot the re-plan moved off its task takes it back, in robot order, when no other robot
        got it and the re-plan gave the robot no task of smaller makespan (its new task is then free again)."""
        given = set(proposal.tolist())
        for a in np.flatnonzero((before >= 0) & (proposal != before)).tolist():
            old, new = int(before[a]), int(proposal[a])
            if old in given:
                continue
            if new >= 0 and self.makespan(tasks, new, int(pos[a])) < self.makespan(tasks, old, int(pos[a])):
                continue
            proposal[a] = old
            given.add(old)
            given.discard(new)

    def _shortlist(self, tasks, ids: np.ndarray, cells: np.ndarray, robot_cells: np.ndarray):
        """Indices of the tasks among some free robot's ``shortlist`` least-makespan tasks, and every
        task's errand-to-errand length."""
        length = self.lengths.task_length(tasks, ids, 1 << 62)
        d = self.fields.fields[self.fields.rows(cells)][:, robot_cells].astype(np.int64)
        cost = np.where((d < 0) | (length[:, None] >= FAR), FAR, d + length[:, None])
        k = self.shortlist
        near = np.argpartition(cost, k - 1, axis=0)[:k]
        return np.unique(near), length


class _Greedy(GreedyScheduler):
    """The start kit's default scheduler with an empty compute report per step."""

    last_compute = ComputeReport()


@dataclass(frozen=True)
class GreedyOptions(Options):
    """``lorr-greedy``'s option."""

    way: int = option(1, int, 1, MAX_WAY, meaning="the way to a task's first errand weighed against its errand legs "
                      "(1 = the start kit's)")


def scheduler_options(name: str) -> list[tuple[str, object, str, str]]:
    """``(key, default, allowed, meaning)`` of each of a named scheduler's own options (``--scheduler-option``);
    ``ValueError`` naming an unknown scheduler."""
    if name == "lorr-greedy":
        rows = GreedyOptions.describe()
    elif name == "lorr-weighted":
        from agents.lorr.weighted import WeightedOptions

        rows = WeightedOptions.describe()
    elif name == "lorr-ising":
        from agents.lorr.task_groups import TaskGroupOptions

        rows = TaskGroupOptions.describe()
    elif name in SCHEDULERS:
        from agents.lifelong.controllers import PipelineOptions

        rows = AssignerOptions.describe() + [(n, True if n == "fill" else d, a, m)  # the League fills by default
                                             for n, d, a, m in PipelineOptions.describe()]
    else:
        raise ValueError(f"unknown scheduler {name!r}; known: {', '.join(SCHEDULERS)}")
    return rows


def make_scheduler(name: str, seed: int = 0, chip=None, **options):
    """A scheduler by name (see the module docstring) with its ``options``; ``ValueError`` naming an unknown one or
    an option it does not take."""
    if name == "lorr-greedy":
        return _Greedy(way=GreedyOptions.from_dict(options, name).way)
    if name == "lorr-weighted":
        from agents.lorr.weighted import WeightedScheduler

        return WeightedScheduler(**options)
    if name == "lorr-ising":
        from agents.lorr.task_groups import IsingWeightedScheduler
        from ising_backend import build_machine

        return IsingWeightedScheduler(seed=seed, machine=None if chip is None else build_machine(chip, seed), **options)
    from agents.lifelong.controllers import PIPELINE_LAYERS, PipelineAssigner, _learned
    from planners.registry import UnknownPlannerError

    own = {f.name: options.pop(f.name) for f in fields(AssignerOptions) if f.name in options}
    if name.startswith("ppo:"):
        if options:
            raise ValueError(f"{name} takes no options besides replan, keep and shortlist, got {sorted(options)}")
        return AssignerScheduler(_learned(name), seed=seed, **own)
    known = f"known: {', '.join(SCHEDULERS)}, a sharing+tour pair or ppo:MODEL.zip"
    if name not in PIPELINE_LAYERS and not (name.count("+") == 1 and all(name.split("+"))):
        raise ValueError(f"unknown scheduler {name!r}; {known}")
    listed = [row[0] for row in scheduler_options("strong")]  # the pipeline's, as `mrmt lorr options` lists them
    unknown = sorted(set(options) - set(listed))
    if unknown:
        raise ValueError(f"{name} takes no option {unknown[0]!r}; its options: {', '.join(listed)}")
    options.setdefault("fill", True)
    try:  # an option's own error passes as it is; only an unknown half of a pair is an unknown scheduler
        assigner = PipelineAssigner(name, chip=chip, **options)
    except UnknownPlannerError as exc:
        raise ValueError(f"unknown scheduler {name!r}; {known} ({exc})") from None
    return AssignerScheduler(assigner, seed=seed, **own)
