"""Options of the clustered Ising tour construction (paper 5.2); reasons in docs/design/ising_tour.md."""

from __future__ import annotations

import math
from dataclasses import dataclass

from planners.fallback import FALLBACK_MODES
from planners.options import Options, option

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
class TourConfig(Options):
    """Options of :class:`~planners.ising.tour.IsingTour` (:meth:`~planners.options.Options.describe` lists them)."""

    backend: str = option("chip", str, words=BACKENDS,
                          meaning="'logical' (the paper's clustered one-hot construction on the logical solver), "
                                  "'chip' (move-selection local search on the physical chip, .selection) or "
                                  "'chip-onehot' (the paper's one-hot programs quantized for the chip, kept to "
                                  "measure its negative finding)")
    local_limit: int = option(7, int, 1, meaning="largest cluster solved as one local TSP")
    max_clusters: int = option(8, int, 1, meaning="ordering limit K")
    refine: str = option("largest", str, words=REFINE_RULES, meaning="which cluster a refinement split takes")
    cluster_distance: str = option("min", str, words=CLUSTER_DISTANCES, meaning="linkage between clusters")
    exit_cost: str = option("min", str, words=EXIT_COSTS, meaning="a cluster's exit cost; exit_weight scales it")
    exit_weight: float = option(1.0, float, 0, meaning="weight of the exit cost")
    patch_size: int = option(6, int, 1, meaning="most targets in a refinement patch")
    patience: int | None = option(None, int, 0, none=True,
                                  meaning="consecutive non-improving patches before stopping (None: windows + 1)")
    num_reads: int = option(1, int, 1, meaning="reads per program")
    max_retries: int = option(3, int, 0, meaning="re-issues of a program that gave no valid candidate")
    penalty_factor: float = option(1.0, float, 1,
                                   meaning="one-hot penalty A = penalty_factor * w_max + 1 (A > w_max keeps ground "
                                           "states valid)")
    max_branch_bits: int = option(4, int, 0, meaning="most frozen spins for spin-budget branching (4 -> 16 programs)")
    chip_quantize: str = option("linear", str, words=_QUANTIZE_RULES,
                                meaning="quantization rule for backend='chip-onehot'")
    chip_rules: tuple = option(("linear", "rank"), tuple, words=_QUANTIZE_RULES,
                               meaning="mapping portfolio of the move-selection programs (backend='chip'; distinct)")
    max_moves: int = option(8, int, 1,
                            meaning="most candidate moves per selection program (capped by the chip's spins)")
    max_segment: int = option(3, int, 1, meaning="longest segment an or-opt move relocates")
    max_overlap: int = option(4, int, 0, meaning="a candidate move overlaps at most this many better-gain "
                                                 "candidates of its program")
    max_rounds: int = option(500, int, 1, meaning="most selection rounds per start")
    chip_restart: str = option("auto", str, words=CHIP_RESTARTS,
                               meaning="later starts of backend='chip': 'random' orders, 'kick's of the best route, "
                                       "or 'auto' (random up to 16 targets, kicks beyond)")
    n_starts: int = option(4, int, 1, meaning="independent constructions, the cheapest final tour kept")
    start_patience: int | None = option(None, int, 1, none=True,
                                        meaning="stop after this many non-improving starts in a row (None: all)")
    accept_equal: bool = option(False, bool, meaning="also accept equal-cost patch reorders (not the paper's rule)")
    share_clusters: bool = option(False, bool, meaning="reuse the first start's clustering in later starts")
    solver_options: dict | None = option(None, dict, none=True,
                                         meaning="keyword options of the default logical solver (over "
                                                 "DEFAULT_SOLVER_OPTIONS)")
    fallback: str = option("unavailable", str, words=FALLBACK_MODES,
                           meaning="when the pipeline hands a solve to 3-opt (planners.fallback.FALLBACK_MODES)")

    def __post_init__(self) -> None:
        super().__post_init__()
        if len(set(self.chip_rules)) != len(self.chip_rules):  # each rule is one program: named twice, counts merge
            raise ValueError(f"chip_rules = {self.chip_rules} names a rule twice (each rule is one program of every "
                             "round)")
        object.__setattr__(self, "solver_options", {**DEFAULT_SOLVER_OPTIONS, **(self.solver_options or {})})

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

