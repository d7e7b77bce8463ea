"""Online controllers of the lifelong envs: task assignment on events, moves from a MAPF executor.

A controller reads only the observation, keeps a task queue per robot and each step drops served tasks, gives
unclaimed tasks to idle robots on an event (:class:`GreedyAssigner`, or :class:`PipelineAssigner`: the package's
sharing and tour layers on the sub-world of idle robots) and moves every robot through the executor (PIBT by
default); every call's compute is summed into :attr:`LifelongController.last_compute`.
Design notes (groups, defaults and how they were chosen): docs/design/lifelong.md#online-controllers.
"""

from __future__ import annotations

import numpy as np

from dataclasses import dataclass

from planners.compute import ComputeReport
from planners.options import Options, option

__all__ = ["LifelongController", "Round", "GreedyAssigner", "PipelineAssigner", "make_lifelong_controller",
           "LIFELONG_CONTROLLERS", "PIPELINE_LAYERS"]

#: Pipeline specs and the (sharing, tour) layers they run in the lifelong loop.
PIPELINE_LAYERS = {"fast": ("psa", "nn"), "strong": ("ssa", "3opt"), "ising": ("ising", "ising"),
                   "ising-paper": ("ising-paper", "ising-paper")}
LIFELONG_CONTROLLERS = ("greedy",) + tuple(PIPELINE_LAYERS)
#: Idle robots per planning call of a pipeline assigner.
DEFAULT_GROUP_SIZE = 4
#: Unclaimed tasks a pipeline assigner considers per idle robot (its nearest ones).
DEFAULT_CANDIDATES = 1


@dataclass(frozen=True)
class PipelineOptions(Options):
    """A pipeline assigner's options."""

    group_size: int = option(DEFAULT_GROUP_SIZE, int, 1, 1 << 20, meaning="free robots per decision (Z-order groups)")
    commit: int | None = option(1, int, 1, 1 << 20, none=True, meaning="tasks of each route committed (null: the "
                                "whole route)")
    candidates: int | None = option(DEFAULT_CANDIDATES, int, 1, 1 << 20, none=True, meaning="free tasks per decision "
                                    "per free robot, its nearest (null: every one)")
    fill: bool = option(False, bool, meaning="robots the decision leaves without a task take the nearest free one")


def _spread(v: np.ndarray) -> np.ndarray:
    v = v.astype(np.uint64) & np.uint64(0xFFFF)
    for shift, mask in ((8, 0x00FF00FF), (4, 0x0F0F0F0F), (2, 0x33333333), (1, 0x55555555)):
        v = (v | (v << np.uint64(shift))) & np.uint64(mask)
    return v


def _morton(rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Z-order (Morton) keys of cells: sorting by them keeps nearby cells together."""
    return (_spread(rows) << np.uint64(1)) | _spread(cols)


class GreedyAssigner:
    """Each idle robot, in index order, takes the nearest unclaimed task (BFS distance; ties: row-major)."""

    name = "greedy"
    accelerated = False

    def assign(self, grid, fields, idle_cells, tasks, seed, fleet=None) -> tuple[list[list[int]], ComputeReport]:
        queues: list[list[int]] = [[] for _ in idle_cells]
        if len(tasks) == 0:
            return queues, ComputeReport()
        dist = fields.fields[fields.rows(tasks)][:, idle_cells].astype(np.int64)  # (tasks, idle robots)
        dist[dist < 0] = np.iinfo(np.int64).max
        free = np.ones(len(tasks), dtype=bool)
        for i in range(len(idle_cells)):
            if not free.any():
                break
            col = np.where(free, dist[:, i], np.iinfo(np.int64).max)
            j = int(np.argmin(col))
            queues[i] = [j]
            free[j] = False
        return queues, ComputeReport()


class PipelineAssigner:
    """The sharing and tour layers of a pipeline on the sub-world of idle robots and unclaimed tasks
    (see the module docstring).  ``chip``: an :class:`ising_backend.ChipSpec` for Ising layers."""

    def __init__(self, spec: str, chip=None, **options) -> None:
        from planners.pipeline import make_pipeline

        if spec in PIPELINE_LAYERS:
            sharing, tour = PIPELINE_LAYERS[spec]
        elif spec.count("+") == 1 and all(spec.split("+")):
            sharing, tour = spec.split("+")
        else:
            raise ValueError(f"unknown lifelong controller {spec!r}; expected one of {', '.join(LIFELONG_CONTROLLERS)} "
                             "or a sharing+tour pair (e.g. ssa+3opt)")
        opts = PipelineOptions.from_dict(options, spec)
        self.name = spec
        self.group_size, self.commit, self.candidates, self.fill = opts.group_size, opts.commit, opts.candidates, \
            opts.fill
        shared = {}
        if "ising" in (sharing, tour):
            from ising_backend import ChipSpec, build_machine

            shared["chip"] = build_machine(chip if chip is not None else ChipSpec())  # a ChipSpec or MachineSpec
        self.pipeline = make_pipeline(sharing=sharing, tour=tour, path="bfs", **shared)
        self.accelerated = bool(shared)

    def assign(self, grid, fields, idle_cells, tasks, seed, fleet=None) -> tuple[list[list[int]], ComputeReport]:
        from mrmt_env.world import World

        queues: list[list[int]] = [[] for _ in idle_cells]
        compute = ComputeReport()
        if len(tasks) == 0:
            return queues, compute
        width = grid.shape[1]
        dist = fields.fields[fields.rows(tasks)][:, idle_cells].astype(np.int64)  # (tasks, idle robots)
        dist[dist < 0] = np.iinfo(np.int64).max
        dist_all = dist
        if self.candidates is not None and len(tasks) > self.candidates * len(idle_cells):
            k = self.candidates
            near = np.argpartition(dist, k - 1, axis=0)[:k] if k < len(tasks) else np.arange(len(tasks))[:, None]
            keep = np.unique(near)  # each idle robot's k nearest unclaimed tasks
            tasks, dist, index = tasks[keep], dist[keep], keep
        else:
            index = np.arange(len(tasks))
        rows, cols = np.divmod(idle_cells, width)
        order = np.argsort(_morton(rows, cols), kind="stable")  # Z-order: consecutive robots are neighbours
        n_groups = -(-len(idle_cells) // self.group_size)
        group_of = np.empty(len(idle_cells), dtype=np.int64)
        for g, chunk in enumerate(np.array_split(order, n_groups)):
            group_of[chunk] = g
        if n_groups > 1:
            task_group = group_of[np.argmin(dist, axis=1)]
        else:
            task_group = np.zeros(len(tasks), dtype=np.int64)
        for g in range(n_groups):
            robots = np.flatnonzero(group_of == g)
            mine = np.flatnonzero(task_group == g)
            if len(mine) == 0:
                continue
            cells = idle_cells[robots]
            world = World(grid, np.stack(np.divmod(cells, width), axis=1),
                          np.stack(np.divmod(tasks[mine], width), axis=1))
            plan = self.pipeline.plan(world, seed=[int(seed), g])
            compute = compute + plan.compute
            if not plan.success:
                raise RuntimeError(f"lifelong controller {self.name!r}: planning failed: {plan.failure}")
            for i, route in enumerate(plan.routes):
                queues[int(robots[i])] = [int(index[mine[t]]) for t in route.targets[:self.commit]]
        if self.fill:  # robots the plan left without a task take the nearest one still unclaimed
            free = np.ones(len(dist_all), dtype=bool)
            free[[j for q in queues for j in q]] = False
            for i in range(len(idle_cells)):
                if queues[i] or not free.any():
                    continue
                j = int(np.argmin(np.where(free, dist_all[:, i], np.iinfo(np.int64).max)))
                queues[i] = [j]
                free[j] = False
        return queues, compute


class Round:
    """One step's view of the fleet (flat cells): ``pos`` and ``goals`` (queue heads, own cell when
    idle) per robot, the ``idle`` robots' indices and the ``unclaimed`` open tasks."""

    __slots__ = ("grid", "pos", "goals", "idle", "unclaimed")

    def __init__(self, grid, pos, goals, idle, unclaimed) -> None:
        self.grid, self.pos, self.goals, self.idle, self.unclaimed = grid, pos, goals, idle, unclaimed


class LifelongController:
    """Queues of tasks per robot, an assigner on events and a MAPF executor (see the module docstring).

    ``act(obs) -> actions (R,)``; after it, :attr:`last_compute` holds the step's planning calls'
    report (chip calls, emulation seconds) and :attr:`replans` counts the events so far.
    """

    def __init__(self, assigner, executor: str = "pibt", seed: int = 0, executor_options: dict | None = None) -> None:
        self.assigner = assigner
        self.name = assigner.name
        self.executor_name = executor
        self.executor_options = dict(executor_options or {})
        self.seed = int(seed)
        self.grid = None

    def reset(self) -> None:
        """Forget the queues (the next ``act`` starts from its observation's world)."""
        self.grid = None

    def _start(self, grid: np.ndarray, n_robots: int) -> None:
        from planners.mapf import make_executor
        from planners.mapf.common import GoalFields

        self.grid = grid.copy()
        self.executor = make_executor(self.executor_name, self.grid, seed=self.seed, **self.executor_options)
        self.fields = GoalFields(self.grid, capacity=max(1024, 4 * n_robots))
        self.queues: list[list[int]] = [[] for _ in range(n_robots)]  # flat task cells
        self.replans = 0
        self.steps = 0

    def observe(self, obs: np.ndarray) -> "Round":
        """Read an observation: drop served tasks from the queues; the step's :class:`Round`."""
        obs = np.asarray(obs)
        n_robots = obs.shape[0] - 2
        grid = obs[0].astype(bool)
        if self.grid is None or self.grid.shape != grid.shape or not np.array_equal(self.grid, grid):
            self._start(grid, n_robots)
        pos = obs[2:].reshape(n_robots, -1).argmax(axis=1).astype(np.int64)
        open_cells = np.flatnonzero(obs[1].reshape(-1))
        is_open = np.zeros(grid.size, dtype=bool)
        is_open[open_cells] = True
        claimed = np.zeros(grid.size, dtype=bool)
        for k, q in enumerate(self.queues):
            if q and not all(is_open[c] for c in q):
                self.queues[k] = q = [c for c in q if is_open[c]]
            claimed[q] = True
        idle = np.array([k for k, q in enumerate(self.queues) if not q], dtype=np.int64)
        goals = np.array([q[0] if q else p for q, p in zip(self.queues, pos.tolist())], dtype=np.int64)
        return Round(grid, pos, goals, idle, open_cells[~claimed[open_cells]])

    def apply(self, rnd: "Round", queues: list[list[int]]) -> None:
        """Give idle robot ``rnd.idle[i]`` the tasks ``rnd.unclaimed[queues[i]]``."""
        for i, k in enumerate(rnd.idle.tolist()):
            self.queues[k] = [int(rnd.unclaimed[j]) for j in queues[i]]
        self.replans += 1

    def move(self, rnd: "Round") -> np.ndarray:
        """The executor's conflict-free joint move towards each queue's head (its own cell when idle):
        the round's goals, with the tasks the idle robots were given since."""
        goals = rnd.goals.copy()
        for k in rnd.idle.tolist():
            if self.queues[k]:
                goals[k] = self.queues[k][0]
        self.steps += 1
        return self.executor.actions(rnd.pos, goals)

    def act(self, obs: np.ndarray) -> np.ndarray:
        rnd = self.observe(obs)
        self.last_compute = ComputeReport()
        if len(rnd.idle) and len(rnd.unclaimed):
            queues, compute = self.assigner.assign(rnd.grid, self.fields, rnd.pos[rnd.idle], rnd.unclaimed,
                                                   seed=self.seed * 1_000_003 + self.steps, fleet=rnd)
            self.apply(rnd, queues)
            self.last_compute = compute
        return self.move(rnd)


def make_lifelong_controller(spec: str, seed: int = 0, chip=None, executor: str = "pibt",
                             **options) -> LifelongController:
    """``greedy``, ``ppo:MODEL.zip`` (:mod:`agents.lifelong.choice`) or a pipeline spec (:data:`PIPELINE_LAYERS`, or ``sharing+tour``), executed by ``executor``
    (``pibt`` or ``windowed``); ``options`` go to :class:`PipelineAssigner` (``group_size``,
    ``candidates``, ``commit``, ``fill``); ``ValueError`` naming an unknown spec or option."""
    from planners.mapf import EXECUTORS

    if executor not in EXECUTORS:
        raise ValueError(f"unknown executor {executor!r}; known: {', '.join(EXECUTORS)}")
    if spec == "greedy" or spec.startswith("ppo:"):
        if options:
            raise ValueError(f"{spec} takes no options, got {sorted(options)}")
        assigner = GreedyAssigner() if spec == "greedy" else _learned(spec)
    else:
        assigner = PipelineAssigner(spec, chip=chip, **options)
    return LifelongController(assigner, executor=executor, seed=seed)


def _learned(spec: str):
    """``ppo:PATH``: a model trained by ``mrmt train`` on a lifelong id, as a :class:`LearnedAssigner`."""
    from agents.learned.policy import load_policy
    from agents.lifelong.choice import LearnedAssigner

    policy = load_policy(spec[len("ppo:"):])
    if policy.meta.get("decision") != "lifelong-task":
        raise ValueError(f"{spec}: the model was not trained on a lifelong id (its sidecar names env "
                         f"{policy.meta.get('env_id')!r}); train one with mrmt train --env-id mrmt_env/MRMT-Lifelong-v0")
    return LearnedAssigner(policy, name=spec)
