"""Composable planning pipelines: target sharing -> tour construction -> pathfinding.

:func:`make_pipeline` builds a :class:`Pipeline` from a preset (:data:`PRESETS`), from layer names
(:mod:`planners.registry`) or from layer objects, e.g. ``make_pipeline("strong", tour=ThreeOptTour(moves="7"))``.
``Pipeline.plan(world, seed)`` charges every layer call to the plan's compute; a layer that gives up fails the
plan (``success=False``) instead of raising. Design notes: docs/design/pipeline.md#composable-pipelines.
"""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass, field

import numpy as np

from mrmt_env.world import World
from planners import registry
from planners.base import PathResult, SharingResult, TourResult
from planners.compute import ComputeReport, stopwatch
from planners.fallback import METHODS, answer, fall_back
from planners.plan import Plan, PlanError, RobotRoute, path_problem, validate_plan

__all__ = ["Pipeline", "make_pipeline", "PRESETS", "merge_stats"]

#: Preset name -> (sharing, tour, path) registry names.
PRESETS: dict[str, tuple[str, str, str]] = {
    "fast": ("psa", "nn", "astar"),
    "strong": ("ssa", "3opt", "astar"),
    "ising": ("ising", "ising", "field"),
    "ising-paper": ("ising-paper", "ising-paper", "ising-paper"),
    "exact": ("exact", "brute", "bfs"),
    "pyvrp": ("pyvrp", "keep", "astar"),
    "ising-fleet": ("ising-fleet", "keep", "field"),
    "ortools": ("ortools", "keep", "astar"),
}

#: Preset ``ising`` plans a world with more targets than this with preset ``ising-fleet`` (when built
#: without layer options): measured crossover, docs/design/ising_fleet.md.
FLEET_ABOVE = 20


_ZERO = ComputeReport()

#: The clock of :func:`~planners.compute.stopwatch`, called directly around each
#: layer call (a context manager per path leg would cost more than a leg of A*).
_clock = time.perf_counter


class _Account:
    """Per-layer accumulator: measured seconds plus the layers' accelerator counts."""

    __slots__ = ("cpu_s", "report")

    def __init__(self) -> None:
        self.cpu_s = 0.0
        self.report = _ZERO

    def add(self, compute: ComputeReport, seconds: float) -> None:
        self.cpu_s += seconds
        if compute is not _ZERO:  # the layers' cpu_s is replaced by the measured seconds in total()
            self.report = self.report + compute

    def total(self) -> ComputeReport:
        if self.report is _ZERO:
            return ComputeReport(cpu_s=self.cpu_s)
        return self.report.replace(cpu_s=self.cpu_s)


def merge_stats(into: dict, new: dict) -> dict:
    """Merge layer ``new`` stats into ``into`` in place (rules in the module docstring)."""
    for key, value in new.items():
        old = into.get(key)
        tv = type(value)
        if tv is int or tv is float:  # fast path: counters
            to = type(old)
            if to is int or to is float:
                into[key] = old + value
                continue
        if key == "failure":
            continue
        if tv is dict:
            into[key] = merge_stats(old if isinstance(old, dict) else {}, value)
        elif old is None:  # a new entry: a copy of a list or dict, any other value as it is
            into[key] = merge_stats({}, value) if isinstance(value, dict) else (
                list(value) if isinstance(value, list) else value)
        else:
            into[key] = _merged(old, value)
    return into


def _merged(old, value):
    """The merged value of an entry already in the stats (the general rules)."""
    if isinstance(value, dict):
        return merge_stats(old if isinstance(old, dict) else {}, value)
    if isinstance(value, list):
        return (list(old) if isinstance(old, list) else []) + list(value)
    if isinstance(value, (bool, np.bool_)) and isinstance(old, (bool, np.bool_)):
        return bool(old or value)
    if (
        isinstance(value, (int, float, np.integer, np.floating))
        and not isinstance(value, (bool, np.bool_))
        and isinstance(old, (int, float, np.integer, np.floating))
        and not isinstance(old, (bool, np.bool_))
    ):
        return old + value
    return value


def _shared_frozen_arrays(root) -> dict:
    """A :func:`copy.deepcopy` memo that shares every read-only array reachable from ``root``
    (through containers and instance attributes): they cannot change, and a copy would be
    writable -- another array type, so the warm-up would compile kernels the plan never calls."""
    import types

    skip = (str, bytes, int, float, complex, bool, type(None), type, types.ModuleType, types.FunctionType,
            types.BuiltinFunctionType, types.MethodType)
    memo: dict = {}
    seen: set = set()
    stack = [root]
    while stack:
        obj = stack.pop()
        if isinstance(obj, skip) or id(obj) in seen:
            continue
        seen.add(id(obj))
        if isinstance(obj, np.ndarray):
            if not obj.flags.writeable:
                memo[id(obj)] = obj
        elif isinstance(obj, dict):
            stack.extend(obj.values())
        elif isinstance(obj, (list, tuple, set, frozenset)):
            stack.extend(obj)
        elif not type(obj).__module__.startswith(("numba", "numpy")) and not hasattr(obj, "__deepcopy__"):
            stack.extend(getattr(obj, "__dict__", {}).values())
            stack.extend(getattr(obj, name) for cls in type(obj).__mro__
                         for name in getattr(cls, "__slots__", ()) if hasattr(obj, name))
    return memo


def _assignment_problem(assignment, n_robots: int, n_targets: int) -> str | None:
    if len(assignment) != n_robots:
        return f"assignment has {len(assignment)} groups for {n_robots} robots"
    owner: dict[int, int] = {}
    for k, group in enumerate(assignment):
        for t in group:
            if not (0 <= t < n_targets):
                return f"robot {k} got target index {t}, outside 0..{n_targets - 1}"
            if t in owner:
                return f"target {t} assigned to robots {owner[t]} and {k}"
            owner[t] = k
    missed = [t for t in range(n_targets) if t not in owner]
    if missed:
        return f"targets {missed} assigned to no robot"
    return None


@dataclass
class Pipeline:
    """A (sharing, tour, path) triple of layer objects; :meth:`plan` runs it on a world."""

    sharing: object
    tour: object
    path: object
    name: str | None = None
    #: plan a robot's legs in one call when the path layer offers ``find_paths`` (same plans)
    batch_paths: bool = True
    #: warm up (compile) on a scratch copy of the layers before the first plan (module docstring)
    warmup_first: bool = True
    #: wall seconds of the warm-up run, None before it (or when it was skipped)
    warmup_s: float | None = field(default=None, init=False, compare=False, repr=False)
    _warm_state: str = field(default="cold", init=False, compare=False, repr=False)
    #: ``(n, pipeline)``: worlds with more than ``n`` targets are planned by ``pipeline`` (preset ``ising``)
    at_scale: tuple | None = field(default=None, compare=False, repr=False)

    @property
    def _batch_paths(self) -> bool:
        return self.batch_paths and callable(getattr(self.path, "find_paths", None))

    def __post_init__(self) -> None:
        for layer in ("sharing", "tour", "path"):
            obj = getattr(self, layer)
            if not callable(getattr(obj, METHODS[layer], None)):
                raise TypeError(f"{layer} layer {obj!r} has no {METHODS[layer]}() method")
        if self.name is None:
            self.name = "+".join(getattr(getattr(self, layer), "name", type(getattr(self, layer)).__name__)
                                 for layer in ("sharing", "tour", "path"))

    def warmup(self, world: World | None = None, seed=0) -> float:
        """Compile what planning ``world`` (default: a 10x10 world with 3 robots and 10 targets)
        needs, by planning it on a deep copy of the layers; returns the wall seconds, copy included
        (0 when already warm).  The real layers are not touched, so later plans are unchanged."""
        if self._warm_state != "cold":
            return 0.0
        if world is None:
            from mrmt_env.generation import generate_world

            world = generate_world(seed=0)
        t0 = _clock()
        try:
            memo = _shared_frozen_arrays((self, world))
            scratch, world = copy.deepcopy((self, world), memo)
        except Exception as exc:  # a layer holding something uncopyable (a device handle): not warmed
            self._warm_state = f"skipped: the layers cannot be deep-copied ({type(exc).__name__}: {exc})"
            return 0.0
        scratch.warmup_first = False
        if isinstance(seed, np.random.Generator):  # a copy: the caller's generator must not move
            seed = copy.deepcopy(seed)
        from ising_backend.audit.record import suspended

        with suspended():  # the scratch run decides nothing of the plan: not audited
            scratch.plan(world, seed=seed)
        self.warmup_s = _clock() - t0
        self._warm_state = "warm"
        return self.warmup_s

    def plan(self, world: World, seed=None) -> Plan:
        """Plan every robot's route on ``world`` (see the module docstring)."""
        if not isinstance(world, World):
            raise TypeError(f"world must be a mrmt_env.world.World, got {type(world).__name__}")
        try:
            rng = np.random.default_rng(seed)
        except (TypeError, ValueError) as exc:
            raise ValueError(
                f"seed = {seed!r} is not a numpy seed (None, an integer >= 0, a sequence of them, or a Generator): {exc}"
            ) from exc
        if self.at_scale is not None and len(world.targets) > self.at_scale[0]:
            plan = self.at_scale[1].plan(world, seed=seed)
            plan.stats["planned_by"] = self.at_scale[1].name
            return plan
        warmup_s = 0.0
        if self.warmup_first and self._warm_state == "cold":
            warmup_s = self.warmup(world, seed if seed is not None else 0)
        with stopwatch() as total:
            acc = {"sharing": _Account(), "tour": _Account(), "path": _Account()}
            stats: dict = {}
            failures: list[str] = []
            dist = world.distance_matrix
            r, n = world.n_robots, world.n_targets

            # ---- 1. target sharing
            assignment: tuple = (tuple(range(n)),)
            if r > 1 or getattr(self.sharing, "orders_routes", False):
                t0 = _clock()
                res: SharingResult = answer("sharing", self.sharing, dist, r, self.tour, rng)
                acc["sharing"].add(res.compute, _clock() - t0)
                merge_stats(stats, res.stats)
                problem = res.failure
                if not problem:
                    assignment = tuple(tuple(int(x) for x in g) for g in res.assignment)
                    problem = _assignment_problem(assignment, r, n)
                if problem:
                    failures.append(f"sharing: {problem}")
                    assignment = tuple(() for _ in range(r))

            # ---- 2./3. per robot: tour, then path legs
            routes = []
            for k in range(r):
                group = assignment[k]
                start = world.robots[k]
                ordered = list(group)
                if len(group) >= 2:
                    idx = np.concatenate([[k], r + np.asarray(group, dtype=np.int64)])
                    local = dist[np.ix_(idx, idx)]
                    t0 = _clock()
                    tres: TourResult = answer("tour", self.tour, local, rng)
                    acc["tour"].add(tres.compute, _clock() - t0)
                    if tres.stats:
                        merge_stats(stats, tres.stats)
                    problem = tres.failure
                    if not problem and sorted(tres.order) != list(range(1, len(group) + 1)):
                        problem = f"tour layer returned order {list(tres.order)}, not a permutation of 1..{len(group)}"
                    if problem:
                        failures.append(f"robot {k} tour: {problem}")
                        ordered = []
                    else:
                        ordered = [group[i - 1] for i in tres.order]
                cells = np.empty((len(ordered) + 1, 2), dtype=np.int64)  # the start, then the stops
                cells[0] = start
                cells[1:] = world.targets[ordered]
                pieces = [start.reshape(1, 2)]
                reached: list[int] = []
                batched: list = []
                batch = None
                if self._batch_paths and ordered:  # the legs the layer plans in one call
                    t0 = _clock()
                    batch = self.path.find_paths(world, cells, rng)
                    acc["path"].add(batch.compute, _clock() - t0)
                    if batch.paths:
                        merge_stats(stats, batch.stats)
                    batched = batch.paths
                for j in range(len(ordered)):
                    a, b = cells[j], cells[j + 1]
                    if j < len(batched):
                        path, failure = batched[j], None
                    else:
                        t0 = _clock()
                        if j == len(batched) and batch is not None and batch.failed is not None:
                            pres: PathResult = fall_back("path", self.path, (world, a, b, rng), batch.failed)
                        else:
                            pres = answer("path", self.path, world, a, b, rng)
                        acc["path"].add(pres.compute, _clock() - t0)
                        if pres.stats:
                            merge_stats(stats, pres.stats)
                        path, failure = pres.path, pres.failure
                    if path is None:
                        problem = failure or "path layer gave no path"
                    else:
                        problem = path_problem(world, path, a, b)
                    if problem:
                        failures.append(
                            f"robot {k} leg {j} ({a.tolist()} -> target {ordered[j]} at {b.tolist()}): {problem}"
                        )
                        break
                    pieces.append(np.asarray(path, dtype=np.int64)[1:])
                    reached.append(ordered[j])
                routes.append(RobotRoute(tuple(reached), np.concatenate(pieces, axis=0)))
            routes = tuple(routes)
            try:  # the one validity check: never hand out an illegal plan as a success
                validate_plan(world, Plan(routes=routes), require_complete=not failures)
            except PlanError as exc:
                routes = tuple(RobotRoute((), world.robots[k].reshape(1, 2)) for k in range(r))
                failures.append(f"invalid plan: {exc}")
        reports = {layer: a.total() for layer, a in acc.items()}
        layers_cpu = sum(rep.cpu_s for rep in reports.values())
        glue = max(total() - layers_cpu, 0.0)
        stats["layers"] = reports
        stats["glue_cpu_s"] = glue
        stats["pipeline"] = self.name
        if self._warm_state.startswith("skipped"):
            stats["warmup_skipped"] = self._warm_state
        compute = (reports["sharing"] + reports["tour"] + reports["path"]
                   + ComputeReport(cpu_s=glue, warmup_s=warmup_s))
        return Plan(routes=routes, compute=compute, success=not failures,
                    failure="; ".join(failures) if failures else None, stats=stats)

    def __repr__(self) -> str:
        return f"Pipeline(sharing={self.sharing!r}, tour={self.tour!r}, path={self.path!r})"


def make_pipeline(
    preset: str | None = None,
    *,
    sharing=None,
    tour=None,
    path=None,
    sharing_options: dict | None = None,
    tour_options: dict | None = None,
    path_options: dict | None = None,
    **shared,
) -> Pipeline:
    """Build a :class:`Pipeline` from a preset and/or layer names or objects.

    Args:
        preset: ``"fast"``, ``"strong"``, ``"ising"``, ``"ising-paper"``, ``"exact"``, ``"pyvrp"``, ``"ising-fleet"``,
            ``"ortools"`` (:data:`PRESETS`) or None.
        sharing, tour, path: a registry name or a layer object; overrides the
            preset's layer.  Without a preset all three are required.
        sharing_options, tour_options, path_options: keyword options for that
            layer's factory (only with a name).
        **shared: keywords passed to every layer factory that accepts them
            (e.g. ``chip=``); one no factory accepts is an error.

    Raises:
        ValueError: unknown preset, missing layer, options given with a layer object, an option a factory
            does not take or a bad option value, a shared keyword no factory accepts.
        registry.UnknownPlannerError: unknown or unavailable layer name (a ``ValueError``).
    """
    chosen = {"sharing": sharing, "tour": tour, "path": path}
    if preset is not None:
        if preset not in PRESETS:
            raise ValueError(f"unknown pipeline preset {preset!r}; presets: {', '.join(PRESETS)}")
        for layer, default in zip(("sharing", "tour", "path"), PRESETS[preset]):
            if chosen[layer] is None:
                chosen[layer] = default
    missing = [layer for layer, v in chosen.items() if v is None]
    if missing:
        raise ValueError(
            f"make_pipeline needs a preset ({', '.join(PRESETS)}) or all of sharing, tour, path; missing {missing}"
        )
    options = {"sharing": sharing_options, "tour": tour_options, "path": path_options}
    from ising_backend import IsingMachine, as_machine

    chip = shared.get("chip")
    if "chip" not in shared and any(isinstance(spec, str) and registry.accepts(registry.get_factory(layer, spec), "chip")
                                    for layer, spec in chosen.items()):
        shared = {**shared, "chip": as_machine()}  # one chip, and so one ledger, for every layer that uses one
    elif chip is not None and not isinstance(chip, IsingMachine):
        try:  # a bare sampler or minimal driver: wrapped once, so one ledger
            shared = {**shared, "chip": as_machine(chip)}
        except TypeError:  # not a machine at all: the layers' option checks name it
            pass
    used: set[str] = set()
    layers = {}
    for layer, spec in chosen.items():
        if isinstance(spec, str):
            factory = registry.get_factory(layer, spec)
            used.update(key for key in shared if registry.accepts(factory, key))
            layers[layer] = registry.create(layer, spec, options[layer], shared)
        else:
            if options[layer]:
                raise ValueError(f"{layer}_options given with a {layer} layer object {spec!r}; configure the object instead")
            layers[layer] = spec
    unused = sorted(set(shared) - used)
    if unused:
        raise ValueError(
            f"make_pipeline option(s) {unused} are accepted by no layer factory of "
            f"{'+'.join(str(chosen[k]) for k in ('sharing', 'tour', 'path'))}"
        )
    name = preset if preset is not None and all(
        chosen[layer] == d for layer, d in zip(("sharing", "tour", "path"), PRESETS[preset])
    ) else None
    at_scale = None
    if name == "ising" and not any(options.values()):  # the fleet search above FLEET_ABOVE targets, same chip
        at_scale = (FLEET_ABOVE, make_pipeline("ising-fleet", chip=shared["chip"]))
    return Pipeline(layers["sharing"], layers["tour"], layers["path"], name=name, at_scale=at_scale)
