"""Options of recursive Ising target sharing (paper 5.3); reasons in docs/design/ising_sharing.md."""

from __future__ import annotations

from dataclasses import dataclass

from planners.fallback import FALLBACK_MODES
from planners.options import Options, option

__all__ = ["SharingConfig", "BUNDLE_ORDERS"]

BUNDLE_ORDERS = ("creation", "far_first", "near_first", "largest_first")
_QUANTIZE_RULES = ("linear", "clip95", "rank", "sqrt")  # ising_backend.QUANTIZE_RULES


@dataclass(frozen=True)
class SharingConfig(Options):
    """Options of :class:`~planners.ising.sharing.IsingSharing` (:meth:`~planners.options.Options.describe` lists
    them)."""

    rules: tuple = option(_QUANTIZE_RULES, tuple, words=_QUANTIZE_RULES, none=True,
                          meaning="quantization rules used as the mapping portfolio (None: all four)")
    reads: int = option(2, int, 1, meaning="chip reads per program")
    beam: int = option(3, int, 1, meaning="distinct chip candidates kept per robot split (1 = the paper's greedy "
                                          "recursion)")
    refine_beam: int = option(2, int, 1, meaning="distinct chip candidates kept per refinement split")
    max_states: int = option(9, int, 1, meaning="cap on candidate partial solutions carried along")
    weight_shift: float = option(0.5, float, meaning="split weights: the shift")
    weight_power: float = option(1.0, float, 0, lo_open=True, meaning="split weights: the power")
    robot_weight: float = option(1.0, float, 0, lo_open=True, meaning="split weights: the robots' factor")
    balance: float = option(0.0, float, 0, meaning="weight of the optional balance term of multi-robot splits")
    refine_stages: int = option(8, int, 0, meaning="cap on refinement stages after the robot splits (0 = none)")
    refine_above: int = option(3, int, 1, meaning="a robotless bundle with more targets than this is split")
    base_max: int | None = option(0, int, 0, none=True,
                                  meaning="a one-robot group with more targets than this is split (None: refine_above)")
    bundle_order: str = option("creation", str, words=BUNDLE_ORDERS, meaning="the order bundles are split in")
    pricing_tour: object = option("auto", object, none=True,
                                  meaning="what prices bundles: 'auto' (exact Held-Karp up to 13 targets, else a host "
                                          "3-opt tour), 'downstream' (or None; the paper's literal rule), a tour "
                                          "registry name or a TourSolver")
    reject_empty_robot_side: bool = option(False, bool,
                                           meaning="reject multi-robot splits that leave robots without targets")
    retries: int = option(2, int, 0, meaning="re-submissions of splits whose candidates were all invalid")
    max_frozen: int = option(4, int, 0, 10, meaning="spins a too-large split may freeze (spin-budget branching, 2^k "
                                                    "programs)")
    pair_rounds: int = option(3, int, 0, meaning="rounds of boundary refinement (pooled re-splits of neighbouring "
                                                 "robots' targets, priced exactly); 0 = none (the paper)")
    pair_neighbours: int = option(3, int, 1, meaning="each robot's nearest robots whose boundaries are refined")
    pair_shifts: tuple = option((-0.5, 0.0, 0.5, 1.0, 1.5), tuple,
                                meaning="weight shifts of the re-split programs (one program per shift and rule)")
    fallback: str = option("unavailable", str, words=FALLBACK_MODES,
                           meaning="when the pipeline hands a sharing call to SSA (planners.fallback.FALLBACK_MODES)")

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.rules is None:
            object.__setattr__(self, "rules", _QUANTIZE_RULES)
        if self.pricing_tour is None:
            object.__setattr__(self, "pricing_tour", "downstream")
        pt = self.pricing_tour  # a name, checked against the tour registry, or a solver
        if isinstance(pt, str):
            if pt not in ("auto", "downstream"):
                from planners import registry

                if pt not in registry.names("tour"):
                    raise ValueError(f"pricing_tour = {pt!r} must be 'auto', 'downstream' or a tour name "
                                     f"{tuple(registry.names('tour'))}")
        elif not callable(getattr(pt, "solve", None)):
            raise ValueError(f"pricing_tour = {pt!r} must be 'auto', 'downstream', a tour name or a TourSolver")

    @classmethod
    def paper(cls, **options) -> "SharingConfig":
        """The paper's configuration (section 5.3): no boundary refinement."""
        return cls(pair_rounds=0).replace(**options)

    @property
    def resolved_base_max(self) -> int:
        return self.refine_above if self.base_max is None else int(self.base_max)
