"""Options of the patch-sliding Ising pathfinder (paper 5.1); reasons in docs/design/ising_path.md."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planners.fallback import FALLBACK_MODES
from planners.options import Options, option

__all__ = ["PathConfig", "FORMS", "TARGET_ORDERS", "TARGET_KEYS", "DEFAULT_SCALE", "DEFAULT_WEIGHTS"]

FORMS = ("pair", "degree")
TARGET_ORDERS = ("boundary_first", "merged")
TARGET_KEYS = ("manhattan", "bfs")

#: Chip units per QUBO weight unit before the merge styles round.
DEFAULT_SCALE = {"pair": 16.0, "degree": 2.0}

#: Default weights per formulation.
DEFAULT_WEIGHTS = {
    "pair": {"C": 1.0, "B": 1.375, "Dg": 0.25, "A_end": 0.5},
    "degree": {"A": 1.0, "A_end": 1.0, "B": 0.5},
}

_MERGE_STYLES = ("overload", "max_coeff", "high_degree", "balanced")  # ising_backend.MERGE_STYLES


@dataclass(frozen=True)
class PathConfig(Options):
    """Options of :class:`~planners.ising.path.IsingPath` (:meth:`~planners.options.Options.describe` lists them)."""

    patch_size: int = option(5, int, 3, meaning="side of the square patch centred on the robot (odd, >= 3)")
    form: str = option("pair", str, words=FORMS, meaning="patch QUBO, 'pair' (default) or 'degree'")
    weights: dict | None = option(None, dict, none=True,
                                  meaning="overrides of DEFAULT_WEIGHTS[form] (all of them: full_weights)")
    styles: tuple = option(_MERGE_STYLES, tuple, words=_MERGE_STYLES, none=True,
                           meaning="spin-merging styles of the portfolio (None: all four)")
    num_reads: int = option(1, int, 1, meaning="reads per mapped program (each read is one chip call)")
    targets_per_call: int = option(1, int, 1, meaning="ranked local targets whose programs share one submission")
    interior_targets: bool = option(True, bool, meaning="after the boundary cells, fall back to interior patch cells")
    backtrack: bool = option(True, bool, meaning="when no local target is left, step back along the committed walk")
    cut_loops: bool = option(True, bool, meaning="remove loops from the committed walk")
    max_attempts: int | None = option(None, int, 1, none=True,
                                      meaning="local-target attempts per query (None: max(64, free cells))")
    max_chip_calls: int | None = option(None, int, 1, none=True,
                                        meaning="physical calls per query (None: attempts x styles x reads)")
    target_order: str = option("boundary_first", str, words=TARGET_ORDERS, meaning="'boundary_first' or 'merged'")
    target_key: str = option("bfs", str, words=TARGET_KEYS,
                             meaning="what ranks local targets: 'bfs', the world's obstacle-aware distance to the goal "
                                     "(default), or 'manhattan' distance (the paper's rule; docs/design/ising_path.md)")
    scale: float | None = option(None, float, 0, none=True, lo_open=True,
                                 meaning="chip units per QUBO weight unit before merging (None: DEFAULT_SCALE[form]; "
                                         "the value used: chip_scale)")
    pack: bool = option(False, bool, meaning="block-pack the portfolio's programs into shared chip programs")
    fallback: str = option("unavailable", str, words=FALLBACK_MODES,
                           meaning="when the pipeline hands a query to A*: 'unavailable' (the chip cannot answer), "
                                   "'failure' (also a failed search), 'never'")

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.patch_size % 2 == 0:
            raise ValueError(f"patch_size = {self.patch_size!r} must be an odd integer >= 3")
        if self.styles is None:
            object.__setattr__(self, "styles", _MERGE_STYLES)
        if self.weights:  # the weights a form takes: a constraint between two options
            known = DEFAULT_WEIGHTS[self.form]
            bad = [k for k, v in self.weights.items() if k not in known or isinstance(v, (bool, np.bool_))
                   or not isinstance(v, (int, float, np.integer, np.floating)) or not np.isfinite(v)]
            if bad:
                raise ValueError(f"weights = {self.weights!r} must map some of {', '.join(known)} (form "
                                 f"{self.form!r}) to finite numbers")
            object.__setattr__(self, "weights", {k: float(v) for k, v in self.weights.items()})

    @classmethod
    def paper(cls, **options) -> "PathConfig":
        """The paper's configuration (section 5.1): local targets ranked by Manhattan distance."""
        return cls(target_key="manhattan").replace(**options)

    @property
    def full_weights(self) -> dict:
        """Every weight of the form: the defaults with :attr:`weights` applied."""
        return {**DEFAULT_WEIGHTS[self.form], **(self.weights or {})}

    @property
    def chip_scale(self) -> float:
        """The scale in use: :attr:`scale`, or the form's default."""
        return DEFAULT_SCALE[self.form] if self.scale is None else self.scale

    def fit_spins(self, n_spins: int, keep=()) -> "PathConfig":
        """This config with ``patch_size`` shrunk (never grown) to the largest odd side whose
        patch (``side^2 - 2`` free cells) fits ``n_spins``, unless given explicitly (in ``keep``)."""
        side = self.patch_size
        if "patch_size" not in keep:
            while side > 3 and side * side - 2 > int(n_spins):
                side -= 2
        return self.replace(patch_size=side) if side != self.patch_size else self

