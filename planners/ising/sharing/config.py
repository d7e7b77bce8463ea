"""Options of recursive Ising target sharing (paper 5.3); reasons in docs/design/ising_sharing.md."""

from __future__ import annotations

from dataclasses import dataclass

from planners.ising.config import IsingConfig, check_choice, check_int, check_real
from planners.fallback import FALLBACK_MODES

__all__ = ["SharingConfig", "BUNDLE_ORDERS"]

BUNDLE_ORDERS = ("creation", "far_first", "near_first", "largest_first")
_QUANTIZE_RULES = ("linear", "clip95", "rank", "sqrt")  # ising_backend.QUANTIZE_RULES


@dataclass(frozen=True)
class SharingConfig(IsingConfig):
    """Options of :class:`~planners.ising.sharing.IsingSharing`.

    Attributes:
        rules: quantization rules used as the mapping portfolio (default all four).
        reads: chip reads per program.
        beam: distinct chip candidates kept per robot split (1 = the paper's greedy recursion).
        refine_beam: distinct chip candidates kept per refinement split.
        max_states: cap on candidate partial solutions carried along.
        weight_shift, weight_power, robot_weight: split weights.
        balance: weight of the optional balance term of multi-robot splits.
        refine_stages: cap on refinement stages after the robot splits (0 = none).
        refine_above: a robotless bundle with more targets than this is split.
        base_max: a one-robot group with more targets than this is split (``None``: ``refine_above``).
        bundle_order: see :data:`BUNDLE_ORDERS`.
        pricing_tour: what prices bundles: ``"auto"`` (exact Held-Karp up to 13 targets,
            else a host 3-opt tour), ``"downstream"`` (or ``None``; the paper's literal rule),
            a tour registry name or a ``TourSolver``.
        reject_empty_robot_side: reject multi-robot splits that leave robots without targets.
        retries: re-submissions of splits whose candidates were all invalid.
        max_frozen: spins a too-large split may freeze (spin-budget branching, 2^k programs).
        pair_rounds: rounds of boundary refinement (pooled re-splits of neighbouring robots'
            targets, priced exactly); 0 = none (the paper).
        pair_neighbours: each robot's nearest robots whose boundaries are refined.
        pair_shifts: weight shifts of the re-split programs (one program per shift and rule).
        fallback: when the pipeline hands a sharing call to SSA (:data:`~planners.fallback.FALLBACK_MODES`).
    """

    rules: tuple = _QUANTIZE_RULES
    reads: int = 2
    beam: int = 3
    refine_beam: int = 2
    max_states: int = 9
    weight_shift: float = 0.5
    weight_power: float = 1.0
    robot_weight: float = 1.0
    balance: float = 0.0
    refine_stages: int = 8
    refine_above: int = 3
    base_max: int | None = 0
    bundle_order: str = "creation"
    pricing_tour: object = "auto"
    reject_empty_robot_side: bool = False
    retries: int = 2
    max_frozen: int = 4
    pair_rounds: int = 3
    pair_neighbours: int = 3
    pair_shifts: tuple = (-0.5, 0.0, 0.5, 1.0, 1.5)
    fallback: str = "unavailable"

    def __post_init__(self) -> None:
        check_choice("fallback", self.fallback, FALLBACK_MODES)
        rules = tuple(_QUANTIZE_RULES if self.rules is None else self.rules)
        if not rules:
            raise ValueError("rules must name at least one quantization rule")
        for r in rules:
            if r not in _QUANTIZE_RULES:
                raise ValueError(f"unknown quantization rule {r!r}; expected one of {_QUANTIZE_RULES}")
        object.__setattr__(self, "rules", rules)
        for name, lo in (("reads", 1), ("beam", 1), ("refine_beam", 1), ("max_states", 1),
                         ("refine_stages", 0), ("refine_above", 1), ("retries", 0),
                         ("pair_rounds", 0), ("pair_neighbours", 1)):
            check_int(name, getattr(self, name), lo)
        check_int("base_max", self.base_max, 0, none=True)
        check_int("max_frozen", self.max_frozen, 0, hi=10)
        check_choice("bundle_order", self.bundle_order, BUNDLE_ORDERS)
        shifts = tuple(self.pair_shifts)
        if not shifts:
            raise ValueError("pair_shifts must hold at least one weight shift")
        for v in shifts:
            check_real("pair_shifts entry", v)
        object.__setattr__(self, "pair_shifts", tuple(float(v) for v in shifts))
        check_real("balance", self.balance, lo=0.0)
        check_real("weight_power", self.weight_power, lo=0.0, lo_open=True)
        check_real("robot_weight", self.robot_weight, lo=0.0, lo_open=True)
        check_real("weight_shift", self.weight_shift)
        if self.pricing_tour is None:
            object.__setattr__(self, "pricing_tour", "downstream")
        pt = self.pricing_tour
        if isinstance(pt, str):
            if pt not in ("auto", "downstream"):
                from planners import registry

                if pt not in registry.names("tour"):
                    raise ValueError(f"pricing_tour = {pt!r}: not 'auto', 'downstream' or a tour name "
                                     f"{tuple(registry.names('tour'))}")
        elif not callable(getattr(pt, "solve", None)):
            raise ValueError(f"pricing_tour must be 'auto', 'downstream', a tour name or a TourSolver, got {pt!r}")
        for name in ("balance", "weight_power", "robot_weight", "weight_shift"):
            object.__setattr__(self, name, float(getattr(self, name)))
        object.__setattr__(self, "reject_empty_robot_side", bool(self.reject_empty_robot_side))

    @classmethod
    def paper(cls, **options) -> "SharingConfig":
        """The paper's configuration (section 5.3): no boundary refinement."""
        return cls(pair_rounds=0).replace(**options)

    @property
    def resolved_base_max(self) -> int:
        return self.refine_above if self.base_max is None else int(self.base_max)
