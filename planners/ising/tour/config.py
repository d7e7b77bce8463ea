"""Options of the clustered Ising tour construction (paper 5.2); reasons in docs/design/ising_tour.md."""

from __future__ import annotations

import math

from dataclasses import dataclass

from planners.ising.config import IsingConfig, check_choice, check_int, check_real, check_rules
from planners.fallback import FALLBACK_MODES

__all__ = ["TourConfig", "REFINE_RULES", "CLUSTER_DISTANCES", "EXIT_COSTS", "BACKENDS", "DEFAULT_SOLVER_OPTIONS"]

REFINE_RULES = ("largest", "spare_first")
CLUSTER_DISTANCES = ("min", "mean", "medoid")
EXIT_COSTS = ("min", "mean")
BACKENDS = ("logical", "chip", "chip-onehot")
CHIP_RESTARTS = ("auto", "random", "kick")
_QUANTIZE_RULES = ("linear", "clip95", "rank", "sqrt")  # ising_backend.QUANTIZE_RULES

#: Default options of the logical tabu solver for this layer (tenure cap 10: one-hot moves flip four spins).
DEFAULT_SOLVER_OPTIONS = {"max_tenure": 10}


@dataclass(frozen=True)
class TourConfig(IsingConfig):
    """Options of :class:`~planners.ising.tour.IsingTour`.

    Attributes:
        backend: ``"logical"`` (the paper's clustered one-hot construction on the logical solver),
            ``"chip"`` (move-selection local search on the physical chip, :mod:`.selection`) or
            ``"chip-onehot"`` (the paper's one-hot programs quantized for the physical chip: the
            paper's negative finding, kept to measure it).
        local_limit: largest cluster solved as one local TSP (7).
        max_clusters: ordering limit ``K`` (8).
        refine: which cluster a refinement split takes (``"largest"`` or ``"spare_first"``).
        cluster_distance: ``"min"`` (default), ``"mean"`` or ``"medoid"``.
        exit_cost: ``"min"`` or ``"mean"``; ``exit_weight`` scales it.
        patch_size: most targets in a refinement patch (6).
        patience: consecutive non-improving patches before stopping (``None``: windows + 1).
        num_reads: reads per program.
        max_retries: re-issues of a program that gave no valid candidate.
        penalty_factor: one-hot penalty ``A = penalty_factor * w_max + 1`` (>= 1).
        max_branch_bits: most frozen spins for spin-budget branching (4 -> 16 programs).
        chip_quantize: quantization rule for ``backend="chip-onehot"``.
        chip_rules: mapping portfolio of the move-selection programs (``backend="chip"``).
        max_moves: most candidate moves per selection program (capped by the chip's spins).
        max_segment: longest segment an or-opt move relocates.
        max_overlap: a candidate move overlaps at most this many better-gain candidates of its program.
        max_rounds: most selection rounds per start.
        chip_restart: later starts of ``backend="chip"``: ``"random"`` orders, ``"kick"``s of the
            best route, or ``"auto"`` (random up to 16 targets, kicks beyond).
        n_starts: independent constructions, the cheapest final tour kept (4).
        start_patience: stop after this many non-improving starts in a row (``None``: all).
        accept_equal: also accept equal-cost patch reorders (not the paper's rule).
        share_clusters: reuse the first start's clustering in later starts.
        solver_options: keyword options of the default logical solver.
        fallback: when the pipeline hands a solve to 3-opt (:data:`~planners.fallback.FALLBACK_MODES`).
    """

    backend: str = "chip"
    local_limit: int = 7
    max_clusters: int = 8
    refine: str = "largest"
    cluster_distance: str = "min"
    exit_cost: str = "min"
    exit_weight: float = 1.0
    patch_size: int = 6
    patience: int | None = None
    num_reads: int = 1
    max_retries: int = 3
    penalty_factor: float = 1.0
    max_branch_bits: int = 4
    chip_quantize: str = "linear"
    chip_rules: tuple = ("linear", "rank")
    max_moves: int = 8
    max_segment: int = 3
    max_overlap: int = 4
    max_rounds: int = 500
    chip_restart: str = "auto"
    n_starts: int = 4
    start_patience: int | None = None
    accept_equal: bool = False
    share_clusters: bool = False
    solver_options: dict | None = None
    fallback: str = "unavailable"

    def __post_init__(self) -> None:
        check_choice("backend", self.backend, BACKENDS)
        check_choice("fallback", self.fallback, FALLBACK_MODES)
        check_choice("refine", self.refine, REFINE_RULES)
        check_choice("cluster_distance", self.cluster_distance, CLUSTER_DISTANCES)
        check_choice("chip_quantize", self.chip_quantize, _QUANTIZE_RULES)
        check_choice("exit_cost", self.exit_cost, EXIT_COSTS)
        check_choice("chip_restart", self.chip_restart, CHIP_RESTARTS)
        object.__setattr__(self, "chip_rules", check_rules("chip_rules", self.chip_rules, _QUANTIZE_RULES))
        for nm, lo in (("local_limit", 1), ("max_clusters", 1), ("patch_size", 1), ("num_reads", 1),
                       ("max_retries", 0), ("max_branch_bits", 0), ("n_starts", 1),
                       ("max_moves", 1), ("max_segment", 1), ("max_rounds", 1), ("max_overlap", 0)):
            check_int(nm, getattr(self, nm), lo)
        check_int("patience", self.patience, 0, none=True)
        check_int("start_patience", self.start_patience, 1, none=True)
        check_real("penalty_factor", self.penalty_factor)
        if self.penalty_factor < 1.0:
            raise ValueError(f"penalty_factor = {self.penalty_factor!r} must be >= 1 "
                             "(A > w_max keeps ground states valid)")
        check_real("exit_weight", self.exit_weight, lo=0.0)
        object.__setattr__(self, "solver_options", {**DEFAULT_SOLVER_OPTIONS, **(self.solver_options or {})})
        for nm in ("penalty_factor", "exit_weight"):
            object.__setattr__(self, nm, float(getattr(self, nm)))
        for nm in ("accept_equal", "share_clusters"):
            object.__setattr__(self, nm, bool(getattr(self, nm)))

    @property
    def choices(self) -> tuple:
        """The mapping choices the statistics count (:func:`ising_backend.mapping_record`): the move-selection
        portfolio, the one-hot programs' quantization rule, or ``"logical"`` (programs not mapped)."""
        if self.backend == "chip":
            return self.chip_rules
        return (self.chip_quantize,) if self.backend == "chip-onehot" else ("logical",)

    @classmethod
    def paper(cls, **options) -> "TourConfig":
        """The paper's configuration (section 5.2): the clustered one-hot construction on the
        logical solver."""
        return cls(backend="logical").replace(**options)

    def fit_spins(self, n_spins: int, keep=()) -> "TourConfig":
        """This config with ``local_limit``, ``patch_size`` and ``max_clusters`` shrunk (never grown)
        until their one-hot models (``size^2`` variables) fit ``n_spins`` + ``max_branch_bits``;
        fields named in ``keep`` (given explicitly) are left as they are.  The paper's chip (45
        spins) keeps the defaults; measured in docs/design/sweep.md, growing them on larger chips
        made tours worse, so they are not grown."""
        side = max(1, math.isqrt(int(n_spins) + self.max_branch_bits))
        changes = {}
        for name, cap in (("local_limit", side), ("patch_size", side), ("max_clusters", side + 1)):
            if name not in keep and getattr(self, name) > cap:
                changes[name] = cap
        return self.replace(**changes) if changes else self

