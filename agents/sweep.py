"""Chip design-space sweeps: every chip spec of a grid x worlds x controllers x seeds.

:func:`chip_grid` turns ``KEY=V1,V2,...`` axes into the product of chip specs; :func:`run_sweep` runs every
controller that uses a chip once per spec (the others once) on the same worlds and one task runner, one row per
(spec, world, controller, seed). Reports and figures: :mod:`agents.sweep_report`.
Design notes: docs/design/sweep.md#chip_grid-and-run_sweep.
"""

from __future__ import annotations

import itertools
import json
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["SweepConfig", "SweepResult", "chip_grid", "parse_axes", "run_sweep", "spec_columns"]

#: Axes that are not ChipSpec fields: name -> how a positive integer sets the spec's fields.
ALIASES = {
    "n_cores": lambda v: {"n_chips": v, "cores_per_chip": 1},  # v single-core chips
    "coef_range": lambda v: {"h_range": (-v, v), "j_range": (-v, v)},  # the chip's coefficient range
}

#: Largest number of specs a sweep takes (a typo like n_spins=1..10000 should not start a week of work).
MAX_SPECS = 4096


def parse_axes(items) -> dict[str, list[str]]:
    """``["n_spins=16,32", "j_range=3,7"]`` -> ``{"n_spins": ["16", "32"], "j_range": ["3", "7"]}``.

    A range field's value is ``m`` (meaning ``(-m, m)``) or ``lo..hi``.  A key given twice, an
    empty value or an item without ``=`` is a ``ValueError`` naming it.
    """
    from agents.keyvalues import split_items

    axes: dict[str, list[str]] = {}
    for key, values in split_items(items, "sweep axis", "n_spins=32,45,64"):
        item = f"{key}={values}"
        vals = [v.strip() for v in values.split(",")]
        if not vals or any(not v for v in vals):
            raise ValueError(f"sweep axis {item!r} has an empty value")
        if len(set(vals)) != len(vals):
            raise ValueError(f"sweep axis {item!r} lists a value twice")
        axes[key] = vals
    return axes


def _apply(spec, key: str, value: str):
    from ising_backend import ChipSpec

    fields = ChipSpec.__dataclass_fields__
    if key not in fields and key not in ALIASES:  # the sweep's own axis names are valid too
        raise ValueError(f"unknown chip field {key!r} (a sweep axis); valid fields: "
                         f"{', '.join([*fields, *ALIASES])}")
    if key in ALIASES:
        n = value.strip()
        if not n.lstrip("+").isdigit() or int(n) < 1:
            raise ValueError(f"sweep axis {key}={value!r} must be a positive integer")
        return spec.replace(**ALIASES[key](int(n)))
    if ".." in value:  # an explicit range lo..hi
        lo, _, hi = value.partition("..")
        value = f"{lo},{hi}"
    return ChipSpec.from_options([(key, value)], base=spec)


def chip_grid(axes: dict[str, list[str]], base=None) -> list[tuple[dict, object]]:
    """The product of the axes as ``[(labels, ChipSpec), ...]`` in axis order (last axis fastest);
    ``labels`` maps each axis to its value as given.  Bad keys or values raise ``ValueError``
    listing the valid fields."""
    from ising_backend import ChipSpec, MachineSpec

    machine = base if isinstance(base, MachineSpec) else None  # a sampler held to each spec of the grid
    base = ChipSpec() if base is None else (base.spec if machine else base)
    n = 1
    for vals in axes.values():
        n *= len(vals)
    if n > MAX_SPECS:
        raise ValueError(f"the sweep grid has {n} chip specs; at most {MAX_SPECS}")
    grid = []
    for combo in itertools.product(*axes.values()):
        spec = base
        labels = dict(zip(axes, combo))
        for key, value in labels.items():
            try:
                spec = _apply(spec, key, value)
            except ValueError as exc:
                valid = ", ".join(sorted({*ChipSpec.__dataclass_fields__, *ALIASES}))
                msg = str(exc)
                raise ValueError(msg if "valid fields" in msg else f"{msg} (valid fields: {valid})") from None
        grid.append((labels, machine.replace_spec(spec) if machine else spec))
    return grid


def spec_columns(spec) -> dict:
    """A spec's CSV columns: every field (a symmetric range as its ``m``, else ``lo..hi``), ``n_cores``."""
    cols = {}
    for key, value in spec.to_dict().items():
        if key in ("h_range", "j_range"):
            lo, hi = value
            value = hi if lo == -hi else f"{lo}..{hi}"
        elif key == "beta_range":
            value = "" if value is None else f"{value[0]}..{value[1]}"
        cols[key] = value
    return cols


@dataclass(frozen=True)
class SweepConfig:
    """What a sweep runs: chip axes, controllers, worlds (env id + kwargs), seeds, step limit."""

    axes: dict = field(default_factory=dict)
    controllers: tuple = ("ising", "strong")
    n_worlds: int = 20
    world_seed: int = 0
    seeds: tuple = (0,)
    env_id: str = "mrmt_env/MRMT-v0"
    env_kwargs: dict = field(default_factory=dict)
    max_steps: int | None = None

    def __post_init__(self):
        from agents.evaluation import parse_controllers

        object.__setattr__(self, "controllers", tuple(parse_controllers(",".join(self.controllers))))
        if isinstance(self.n_worlds, bool) or int(self.n_worlds) != self.n_worlds or self.n_worlds < 1:
            raise ValueError(f"n_worlds = {self.n_worlds!r} must be an integer >= 1")
        if not self.seeds:
            raise ValueError("seeds must name at least one controller seed")


@dataclass
class SweepResult:
    """The rows of a sweep, its specs (``[(labels, ChipSpec)]``) and its configuration."""

    rows: list[dict]
    specs: list
    config: dict

    def to_csv(self, path) -> Path:
        from agents.evaluation import write_csv

        return write_csv(self.rows, path)

    def to_json(self, path) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps({"config": self.config, "rows": self.rows}, indent=1, default=float))
        return path


def _sweep_task(spec_id: int, labels: dict, chip, controller: str, seed: int, world_seed: int,
                env_id: str, env_kwargs: dict, max_steps: int) -> dict:
    """One episode of the sweep (runs in a worker); a controller that cannot be built on this chip
    gives a failed row with the reason instead of an exception."""
    from agents.evaluation import ROUTE_KEYS, _env_for, cached_controller, run_episode

    head = {"spec_id": spec_id, "spec": " ".join(f"{k}={v}" for k, v in labels.items())}
    head.update(spec_columns(chip) if chip is not None else {})
    row = {"controller": controller, "seed": int(seed), "world_seed": int(world_seed)}
    env = _env_for(env_id, env_kwargs, max_steps)
    try:
        ctrl = cached_controller(controller, seed, env, env_id, True, chip, env_kwargs)
    except ValueError as exc:  # the controller does not fit this chip
        row.update({k: None for k in ROUTE_KEYS})
        row["is_success"] = False
        row["error"] = str(exc).splitlines()[0][:300]
    else:
        row.update(run_episode(env, ctrl, world_seed))
        row["error"] = ""
    return {**head, **row}


def checked_grid(config: SweepConfig, base_chip=None) -> tuple[list, list]:
    """The sweep's chip grid (:func:`chip_grid`) and its controllers that run on a chip, or a ``ValueError``
    naming a bad axis value or a sweep without a chip controller (checked before anything compiles)."""
    from agents.evaluation import uses_chip

    grid = chip_grid(config.axes, base_chip)
    chipped = [c for c in config.controllers if uses_chip(c)]
    if not chipped:
        raise ValueError(f"none of the controllers {list(config.controllers)} runs on a chip; "
                         "add ising or a layer triple with an ising layer")
    return grid, chipped


def run_sweep(config: SweepConfig, run=None, base_chip=None, progress: bool = True) -> SweepResult:
    """Run the sweep on the task runner ``run`` (a :class:`agents.runner.RunConfig`)."""
    from agents.evaluation import resolve_max_steps
    from agents.runner import RunConfig, run_tasks
    from ising_backend import ChipSpec

    run = run or RunConfig(progress=progress)
    grid, chipped = checked_grid(config, base_chip)
    env_kwargs = dict(config.env_kwargs)
    max_steps = resolve_max_steps(config.env_id, env_kwargs, config.max_steps)
    worlds = [int(config.world_seed) + i for i in range(int(config.n_worlds))]
    tasks = []
    # specs innermost: every spec's host time is measured over the same stretch of the run (the
    # machine's load drifts), and each worker keeps one warm controller per spec
    for c in config.controllers:
        for s in config.seeds:
            for w in worlds:
                for spec_id, (labels, chip) in (enumerate(grid) if c in chipped else [(-1, ({}, None))]):
                    tasks.append((spec_id, labels, chip, c, int(s), w, config.env_id, env_kwargs, max_steps))
    rows = run_tasks(_sweep_task, tasks, run, desc="sweep", unit="ep")
    order = {c: k for k, c in enumerate(config.controllers)}
    rows.sort(key=lambda r: (order[r["controller"]], r["spec_id"], r["seed"], r["world_seed"]))
    cfg = {
        "axes": {k: list(v) for k, v in config.axes.items()},
        "controllers": list(config.controllers),
        "chip_controllers": chipped,
        "n_worlds": int(config.n_worlds),
        "world_seed": int(config.world_seed),
        "seeds": [int(s) for s in config.seeds],
        "env_id": config.env_id,
        "env_kwargs": env_kwargs,
        "max_steps": max_steps,
        "base_chip": (base_chip or ChipSpec()).to_dict(),
        "specs": [{"spec_id": i, "labels": labels, **spec_columns(chip)} for i, (labels, chip) in enumerate(grid)],
    }
    return SweepResult(rows=rows, specs=grid, config=cfg)
