"""The evaluation runner: episodes x controllers x seeds on the same worlds.

Every episode gives one row: the env's deterministic route metrics joined with the controller's compute for that
episode (:func:`compute_record`: CPU, chip calls and time, latency, energy, retries, fallbacks). Episode ``i`` of
every controller and seed runs world ``world_seed + i``; controllers are spec strings (:func:`make_controller`);
episodes run on the task runner (:mod:`agents.runner`).
Design notes (every column, every spec): docs/design/evaluation.md#the-evaluation-runner.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from agents.controllers import (  # noqa: F401  (re-exported: the evaluation API of before)
    DEFAULT_ENV_ID, LEARNED_PREFIXES, PIPELINE_PRESETS, check_chip_use, make_controller, parse_controllers,
    planner_pipeline, uses_chip, validate_controller_spec,
)
from agents.errors import ControllerError
from agents.runner import RunConfig, run_tasks
from planners.compute import ComputeReport

__all__ = [
    "ControllerError",
    "DEFAULT_ENV_ID",
    "PIPELINE_PRESETS",
    "ROUTE_KEYS",
    "COMPUTE_KEYS",
    "compute_record",
    "parse_controllers",
    "validate_controller_spec",
    "make_controller",
    "run_episode",
    "EvaluationResult",
    "evaluate",
]

#: Route metrics copied from the env's final ``info``.
ROUTE_KEYS = (
    "route_cost",
    "makespan",
    "steps",
    "targets_visited",
    "n_targets",
    "is_success",
    "invalid_moves",
    "conflicts",
)

#: Compute columns of every row (see the module docstring).
COMPUTE_KEYS = (
    "cpu_s",
    "emulation_s",
    "host_cpu_s",
    "chip_calls",
    "chip_batches",
    "logical_calls",
    "chip_time_s",
    "chip_time_parallel_s",
    "latency_s",
    "latency_parallel_s",
    "accelerator_energy_j",
    "host_energy_j",
    "total_energy_j",
    "retries",
    "fallbacks",
    "warmup_s",
)


def compute_record(report: ComputeReport) -> dict:
    """The compute columns (:data:`COMPUTE_KEYS`) of one episode's report (from ``report.to_record()``)."""
    record = report.to_record()
    return {key: record[key] for key in COMPUTE_KEYS}


# --------------------------------------------------------------------- episodes
def run_episode(env, controller, world_seed: int | None, index: int = 0) -> dict:
    """Run one episode of ``controller`` in ``env``; return its row (without labels).

    The env is reset with ``seed=world_seed``; the controller is told the
    episode starts (and, if it has ``begin_episode(env, index)``, given the
    env after the reset).  A controller with ``uses_action_masks`` gets
    ``action_masks`` (``info["action_mask"]`` or ``env.action_masks()``).
    The row has :data:`ROUTE_KEYS`, ``truncated``, ``episode_return`` and the
    compute columns of the controller's ``episode_compute(index)``.
    """
    obs, info = env.reset(seed=world_seed)
    begin = getattr(controller, "begin_episode", None)
    if begin is not None:
        begin(env.unwrapped, index)
    masked = bool(getattr(controller, "uses_action_masks", False))
    start = True
    total = 0.0
    terminated = truncated = False
    while not (terminated or truncated):
        kwargs = {}
        if masked:
            mask = info.get("action_mask")
            kwargs["action_masks"] = env.unwrapped.action_masks() if mask is None else mask
        action, _ = controller.predict(obs, episode_start=start, deterministic=True, **kwargs)
        start = False
        obs, reward, terminated, truncated, info = env.step(action)
        total += float(reward)
    row = {k: info[k] for k in ROUTE_KEYS if k in info}
    for k in ROUTE_KEYS:
        v = row.get(k)
        if isinstance(v, (np.bool_, bool)):
            row[k] = bool(v)
        elif isinstance(v, (np.integer,)):
            row[k] = int(v)
    row["truncated"] = bool(truncated and not terminated)
    row["episode_return"] = total
    report = controller.episode_compute(index)
    plans = controller.episode_plans(index) if hasattr(controller, "episode_plans") else []
    row["n_plans"] = len(plans)
    row["plan_route_cost"] = plans[0].route_cost if plans else None
    row["plan_success"] = bool(plans[0].success) if plans else None
    row.update(compute_record(report))
    return row


# worker-side caches: one env and one controller per (spec, seed, env) in each process
_ENVS: dict = {}
_CONTROLLERS: dict = {}


def _env_for(env_id: str, env_kwargs: dict, max_steps: int | None = None):
    key = (env_id, json.dumps(env_kwargs, sort_keys=True, default=str), max_steps)
    env = _ENVS.get(key)
    if env is None:
        import gymnasium as gym

        import mrmt_env  # noqa: F401  (registers the ids)

        limit = {} if max_steps is None else {"max_episode_steps": int(max_steps)}
        env = _ENVS[key] = gym.make(env_id, **env_kwargs, **limit)
    return env


#: The paper's world (the registered ids' defaults) that :func:`step_limit` scales from.
_BASE_WORLD = {"height": 10, "width": 10, "n_targets": 10}


def resolve_max_steps(env_id: str, env_kwargs: dict, max_steps) -> int:
    """``max_steps`` checked, or :func:`step_limit` when it is ``None``."""
    return step_limit(env_id, env_kwargs) if max_steps is None else check_max_steps(max_steps)


def check_max_steps(max_steps) -> int:
    if isinstance(max_steps, bool) or int(max_steps) != max_steps or max_steps < 1:
        raise ValueError(f"max_steps = {max_steps!r} must be an integer >= 1")
    return int(max_steps)


def step_limit(env_id: str, env_kwargs: dict) -> int:
    """The default episode step limit: the id's registered limit, scaled by how much bigger
    than the id's own world the requested one is (grid height + width, and target count).

    ``mrmt_env/MRMT-v0`` keeps its 200 steps on 10x10 with 10 targets; 200x200 gets 4000.
    """
    import gymnasium as gym

    import mrmt_env  # noqa: F401  (registers the ids)

    spec = gym.spec(env_id)
    base = {**_BASE_WORLD, **spec.kwargs}
    limit = spec.max_episode_steps or 200
    world = {**base, **{k: v for k, v in env_kwargs.items() if k in _BASE_WORLD}}
    grow = max(1.0, (world["height"] + world["width"]) / (base["height"] + base["width"]))
    grow *= max(1.0, world["n_targets"] / max(base["n_targets"], 1))
    return int(math.ceil(limit * grow))


#: Reset seed of the untimed warm-up episode (outside any evaluated range in practice).
WARMUP_WORLD_SEED = 2**31 - 1


def _episode_task(spec, seed: int, world_seed: int, env_id: str, env_kwargs: dict, warmup: bool = True,
                  chip=None, max_steps: int | None = None) -> dict:
    env = _env_for(env_id, env_kwargs, max_steps)
    name = spec if isinstance(spec, str) else spec[0]
    ctrl = cached_controller(spec, seed, env, env_id, warmup, chip, env_kwargs)
    row = {"controller": name, "seed": int(seed), "world_seed": int(world_seed)}
    row.update(run_episode(env, ctrl, world_seed))
    return row


def cached_controller(spec, seed: int, env, env_id: str, warmup: bool = True, chip=None, env_kwargs=None):
    """This worker's controller for ``(spec, seed, env_id, chip)``, built (and warmed up with one
    untimed episode in ``env``) on first use; ``spec`` is a spec string or ``(name, factory)``."""
    name, factory = (spec, None) if isinstance(spec, str) else spec
    ckey = (name, seed, env_id, chip)
    ctrl = _CONTROLLERS.get(ckey)
    if ctrl is None:
        ctrl = (make_controller(name, seed=seed, env_id=env_id, chip=chip, env_kwargs=env_kwargs) if factory is None
                else factory(seed))
        if warmup:  # first use in this process pays numba/torch start-up: not part of any episode
            run_episode(env, ctrl, WARMUP_WORLD_SEED)
        _CONTROLLERS[ckey] = ctrl
    return ctrl


def write_csv(rows: list[dict], path) -> Path:
    """``rows`` as CSV, columns in order of first appearance (a key a row lacks is empty)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    cols: list[str] = []
    for r in rows:
        cols += [k for k in r if k not in cols]
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=cols)
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k) for k in cols})
    return path


@dataclass
class EvaluationResult:
    """Rows of an evaluation (one dict per episode) with writers and a summary."""

    rows: list[dict]
    controllers: list[str] = field(default_factory=list)
    config: dict = field(default_factory=dict)

    def by_controller(self, spec: str) -> list[dict]:
        return [r for r in self.rows if r["controller"] == spec]

    def columns(self) -> list[str]:
        cols: list[str] = []
        for r in self.rows:
            for k in r:
                if k not in cols:
                    cols.append(k)
        return cols

    def to_csv(self, path) -> Path:
        return write_csv(self.rows, path)

    def to_json(self, path) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, "w") as f:
            json.dump({"config": self.config, "rows": self.rows, "summary": self.summary()}, f, indent=1, default=float)
        return path

    def summary(self) -> list[dict]:
        """Per controller: episodes, success rate and medians of cost, latency and energy.

        ``route_cost`` and ``makespan`` are medians over the *successful*
        episodes (a truncated episode's cost is not a route cost);
        ``route_cost_all`` is over every episode and ``targets_visited_frac``
        the mean fraction of targets visited.  Compute medians are over every
        episode.
        """
        out = []
        for spec in self.controllers or sorted({r["controller"] for r in self.rows}):
            rows = self.by_controller(spec)
            if not rows:
                continue

            ok_rows = [r for r in rows if r.get("is_success")]

            def med(key, rows=rows):
                vals = [float(r[key]) for r in rows if r.get(key) is not None]
                return float(np.median(vals)) if vals else math.nan

            out.append(
                {
                    "controller": spec,
                    "episodes": len(rows),
                    "success_rate": float(np.mean([bool(r.get("is_success")) for r in rows])),
                    "route_cost": med("route_cost", ok_rows),
                    "makespan": med("makespan", ok_rows),
                    "route_cost_all": med("route_cost"),
                    "targets_visited_frac": float(
                        np.mean([r["targets_visited"] / max(r["n_targets"], 1) for r in rows])
                    ) if all("targets_visited" in r and "n_targets" in r for r in rows) else math.nan,
                    "cpu_s": med("cpu_s"),
                    "emulation_s": med("emulation_s"),
                    "host_cpu_s": med("host_cpu_s"),
                    "chip_calls": med("chip_calls"),
                    "logical_calls": med("logical_calls"),
                    "chip_time_s": med("chip_time_s"),
                    "chip_time_parallel_s": med("chip_time_parallel_s"),
                    "latency_s": med("latency_s"),
                    "accelerator_energy_j": med("accelerator_energy_j"),
                    "host_energy_j": med("host_energy_j"),
                    "total_energy_j": med("total_energy_j"),
                }
            )
        return out

    def format_summary(self) -> str:
        """The summary as a fixed-width text table (medians over episodes)."""
        rows = self.summary()
        width = max([18, *(len(s["controller"]) for s in rows)])  # the whole label: never cut
        head = (
            ("controller", f"{{:<{width}}}", lambda s: s["controller"]),
            ("eps", "{:>5}", lambda s: s["episodes"]),
            ("success", "{:>8}", lambda s: f"{100 * s['success_rate']:.0f}%"),
            ("visited", "{:>8}", lambda s: _fmt(100 * s["targets_visited_frac"], "{:.0f}%")),
            ("cost", "{:>6}", lambda s: _fmt(s["route_cost"], "{:.1f}")),
            ("makespan", "{:>8}", lambda s: _fmt(s["makespan"], "{:.1f}")),
            ("host cpu", "{:>9}", lambda s: _si(s["host_cpu_s"], "s")),
            ("emulation", "{:>9}", lambda s: _si(s["emulation_s"], "s")),
            ("chip(seq)", "{:>9}", lambda s: _si(s["chip_time_s"], "s")),
            ("chip(8c)", "{:>9}", lambda s: _si(s["chip_time_parallel_s"], "s")),
            ("accel E", "{:>9}", lambda s: _si(s["accelerator_energy_j"], "J")),
            ("host E", "{:>9}", lambda s: _si(s["host_energy_j"], "J")),
        )
        lines = [" ".join(fmt.format(name) for name, fmt, _ in head)]
        for s in rows:
            lines.append(" ".join(fmt.format(get(s)) for _, fmt, get in head))
        lines.append(
            "(cost, makespan: medians over successful episodes; visited: mean share of targets visited; "
            "others: medians over all episodes;\n host cpu = measured host time less emulation (the chip emulator's own run time), "
            "chip = the chip's time (50 us per call), E = energy: accel = chip calls x 0.45 uJ, host = host cpu x 15 W)"
        )
        return "\n".join(lines)


def _fmt(v, pattern):
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else pattern.format(v)


def _si(v: float, unit: str) -> str:
    if v is None or math.isnan(v):
        return "-"
    v = float(f"{v:.3g}")  # round first: 999.6 us is shown as 1 ms, not "1e+03 us"
    if v == 0:
        return f"0 {unit}"
    for scale, prefix in ((1, ""), (1e-3, "m"), (1e-6, "u"), (1e-9, "n")):
        if abs(v) >= scale * (1 - 1e-9):  # 0.001 computed as 0.000999... is still 1 ms
            return f"{v / scale:.3g} {prefix}{unit}"
    return f"{v:.2e} {unit}"


def _custom_entry(entry):
    try:
        name, factory = entry
    except (TypeError, ValueError):
        raise ControllerError(
            f"controller {entry!r} must be a spec string or a (name, factory) pair with factory(seed) -> controller"
        ) from None
    if not isinstance(name, str) or not callable(factory):
        raise ControllerError(f"custom controller {entry!r} must be (name: str, factory: callable)")
    return (name, factory)


def evaluate(
    controllers,
    n_worlds: int = 10,
    seeds=(0,),
    world_seed: int = 0,
    env_id: str = DEFAULT_ENV_ID,
    env_kwargs: dict | None = None,
    run: RunConfig | None = None,
    warmup: bool = True,
    chip=None,
    max_steps: int | None = None,
) -> EvaluationResult:
    """Run every controller on worlds ``world_seed .. world_seed + n_worlds - 1`` for each seed.

    Args:
        controllers: spec strings or one comma-separated string (see
            :func:`make_controller`); an entry may also be a ``(name,
            factory)`` pair with ``factory(seed) -> controller`` (picklable,
            e.g. a module-level function or ``functools.partial``, when
            the runner is not inline).
        n_worlds: episodes per controller and seed (one world each).
        seeds: controller seeds.
        world_seed: first env reset seed.
        env_id, env_kwargs: the Gymnasium env (``gymnasium.make(env_id, **env_kwargs)``).
        run: the runner (:class:`agents.runner.RunConfig`: ``inline``, ``process`` or ``ray``,
            workers, Ray address, progress bar on stderr); default ``RunConfig.from_jobs(2)``, two
            worker processes with a bar.  ``RunConfig.from_jobs(1, progress=False)`` runs inline,
            quietly.
        warmup: before a controller's first timed episode in a process, run
            one untimed episode (reset seed :data:`WARMUP_WORLD_SEED`) so
            numba compilation/cache loading and torch start-up are not
            charged to the first evaluated episode.
        chip: an :class:`ising_backend.ChipSpec` for the planners' Ising layers (default the
            paper's chip); refused when no controller runs on a chip.
        max_steps: the episode step limit (truncation); default :func:`step_limit`, the env
            id's limit scaled up with the world's size and target count.

    Returns:
        :class:`EvaluationResult` with rows ordered by controller, seed, world.
    """
    if isinstance(controllers, str):
        entries = parse_controllers(controllers)
    else:
        entries = [validate_controller_spec(c) if isinstance(c, str) else _custom_entry(c) for c in controllers]
    specs = [e if isinstance(e, str) else e[0] for e in entries]
    if len(set(specs)) != len(specs):
        raise ControllerError(f"controller names must be unique, got {specs}")
    if isinstance(n_worlds, bool) or int(n_worlds) != n_worlds or n_worlds < 1:
        raise ValueError(f"n_worlds must be an integer >= 1, got {n_worlds!r}")
    seeds = [int(s) for s in (seeds if np.iterable(seeds) else [seeds])]
    if not seeds:
        raise ValueError("seeds must name at least one seed")
    run = RunConfig.from_jobs(2) if run is None else run
    if not isinstance(run, RunConfig):
        raise TypeError(f"run must be an agents.runner.RunConfig, got {type(run).__name__}")
    env_kwargs = dict(env_kwargs or {})
    check_chip_use(entries, chip)
    max_steps = resolve_max_steps(env_id, env_kwargs, max_steps)
    tasks = [
        (entry, s, int(world_seed) + i, env_id, env_kwargs, bool(warmup), chip, max_steps)
        for entry in entries
        for s in seeds
        for i in range(int(n_worlds))
    ]
    if run.backend == "inline":  # start from fresh controllers and envs, as a new pool's workers do
        _CONTROLLERS.clear()
        _ENVS.clear()
    rows = run_tasks(_episode_task, tasks, run, desc="episodes", unit="ep")
    order = {s: i for i, s in enumerate(specs)}
    rows.sort(key=lambda r: (order[r["controller"]], r["seed"], r["world_seed"]))
    config = {
        "controllers": specs,
        "n_worlds": int(n_worlds),
        "seeds": seeds,
        "world_seed": int(world_seed),
        "env_id": env_id,
        "env_kwargs": env_kwargs,
        "chip": None if chip is None else chip.to_dict(),
        "max_steps": max_steps,
    }
    return EvaluationResult(rows=rows, controllers=specs, config=config)
