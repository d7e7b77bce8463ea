"""Options of the patch-sliding Ising pathfinder (paper 5.1); reasons in docs/design/ising_path.md."""

from __future__ import annotations

from dataclasses import dataclass, field

from planners.ising.config import IsingConfig, check_choice, check_int, check_real
from planners.fallback import FALLBACK_MODES

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
class PathConfig(IsingConfig):
    """Options of :class:`~planners.ising.path.IsingPath`.

    Attributes:
        patch_size: side of the square patch centred on the robot (odd, >= 3).
        form: patch QUBO, ``"pair"`` (default) or ``"degree"``.
        weights: overrides of :data:`DEFAULT_WEIGHTS` ``[form]`` (all of them: :attr:`full_weights`).
        styles: spin-merging styles of the portfolio (default all four).
        num_reads: reads per mapped program (each read is one chip call).
        targets_per_call: ranked local targets whose programs share one submission.
        interior_targets: after the boundary cells, fall back to interior patch cells.
        backtrack: when no local target is left, step back along the committed walk.
        cut_loops: remove loops from the committed walk.
        max_attempts: local-target attempts per query (``None``: ``max(64, free cells)``).
        max_chip_calls: physical calls per query (``None``: attempts x styles x reads).
        target_order: ``"boundary_first"`` or ``"merged"``.
        target_key: what ranks local targets: ``"bfs"``, the world's obstacle-aware BFS distance
            to the goal (the field the world computes for its distance matrix anyway; the
            default), or ``"manhattan"`` distance to the goal (the paper's rule;
            docs/design/ising_path.md).
        scale: chip units per QUBO weight unit before merging (``None``: :data:`DEFAULT_SCALE`
            ``[form]``; the value used: :attr:`chip_scale`).
        pack: block-pack the portfolio's programs into shared chip programs.
        fallback: when the pipeline hands a query to A* (:data:`~planners.fallback.FALLBACK_MODES`):
            ``"unavailable"`` (the chip cannot answer), ``"failure"`` (also a failed search), ``"never"``.
    """

    patch_size: int = 5
    form: str = "pair"
    weights: dict | None = field(default=None, compare=True)
    styles: tuple = _MERGE_STYLES
    num_reads: int = 1
    targets_per_call: int = 1
    interior_targets: bool = True
    backtrack: bool = True
    cut_loops: bool = True
    max_attempts: int | None = None
    max_chip_calls: int | None = None
    target_order: str = "boundary_first"
    target_key: str = "bfs"
    scale: float | None = None
    pack: bool = False
    fallback: str = "unavailable"

    def __post_init__(self) -> None:
        check_choice("form", self.form, FORMS)
        check_choice("fallback", self.fallback, FALLBACK_MODES)
        check_choice("target_order", self.target_order, TARGET_ORDERS)
        check_choice("target_key", self.target_key, TARGET_KEYS)
        if isinstance(self.patch_size, bool) or int(self.patch_size) != self.patch_size \
                or self.patch_size < 3 or self.patch_size % 2 == 0:
            raise ValueError(f"patch_size must be an odd integer >= 3, got {self.patch_size!r}")
        known = DEFAULT_WEIGHTS[self.form]
        if self.weights:
            unknown = set(self.weights) - set(known)
            if unknown:
                raise ValueError(f"unknown weights {sorted(unknown)} for form {self.form!r} (known: {sorted(known)})")
            for k, v in self.weights.items():
                check_real(f"weight {k}", v)
            object.__setattr__(self, "weights", {k: float(v) for k, v in self.weights.items()})
        styles = tuple(self.styles) if self.styles is not None else _MERGE_STYLES
        bad = [s for s in styles if s not in _MERGE_STYLES]
        if not styles or bad:
            raise ValueError(f"styles must be a non-empty subset of {_MERGE_STYLES}, got {self.styles!r}")
        object.__setattr__(self, "styles", styles)
        for name in ("num_reads", "targets_per_call"):
            check_int(name, getattr(self, name), 1)
        for name in ("max_attempts", "max_chip_calls"):
            check_int(name, getattr(self, name), 1, none=True)
        if self.scale is not None:
            try:
                check_real("scale", self.scale, lo=0.0, lo_open=True)
            except ValueError:
                raise ValueError(f"scale must be a positive finite number, got {self.scale!r}") from None
            object.__setattr__(self, "scale", float(self.scale))
        object.__setattr__(self, "patch_size", int(self.patch_size))
        for name in ("interior_targets", "backtrack", "cut_loops", "pack"):
            object.__setattr__(self, name, bool(getattr(self, name)))

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

