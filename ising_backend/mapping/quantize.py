"""Coefficient quantization to the chip's integer range (paper section 4.2).

Contract: :func:`quantize` maps a model's coefficients to integers in ``h_range`` / ``j_range`` by one of
:data:`QUANTIZE_RULES` (``linear``, ``clip95``, ``rank``, ``sqrt``): ``h`` and ``J`` share one factor,
zeros stay zero, signs are kept (with ``keep_sign`` a non-zero never rounds to 0), the offset is 0.
:func:`saturate` is the authors' fixed-scale baseline; :func:`quantize_stack` gives several rules at once.
Oracle: ``tests/mapping_reference.py``.  Design notes (what each rule keeps): docs/design/mapping_kernels.md.
"""

from __future__ import annotations

import numpy as np

from ising_backend.mapping._quantize_kernel import QUANT_NONFINITE, QUANT_OK, RULE_IDS, quantize_rules, saturate_arrays
from ising_backend.models import IsingModel

__all__ = [
    "QUANTIZE_RULES", "quantize", "quantize_stack", "saturate", "QuantizeError",
    # the compiled kernels (array in, array out; see ising_backend.mapping._quantize_kernel)
    "RULE_IDS", "QUANT_OK", "QUANT_NONFINITE", "quantize_rules", "saturate_arrays",
]

QUANTIZE_RULES = ("linear", "clip95", "rank", "sqrt")


class QuantizeError(ValueError):
    """A quantization request cannot be met (bad rule or range)."""


def _pair(rng, name) -> tuple[int, int]:
    """``rng`` as an integer ``(low, high)`` pair; anything else is an error (never truncated)."""
    if type(rng) is tuple and len(rng) == 2 and type(rng[0]) is int and type(rng[1]) is int:
        return rng  # the common case (a ChipSpec range), without the general check's array round trip
    vals = tuple(np.ravel(np.asarray(rng, dtype=object)))
    if len(vals) != 2 or not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in vals):
        raise QuantizeError(f"{name} = {rng!r} must be an integer (low, high) pair, e.g. (-7, 7)")
    return int(vals[0]), int(vals[1])


def _limit(rng, name) -> int:
    lo, hi = _pair(rng, name)
    lim = min(-lo, hi)
    if lim < 1:
        raise QuantizeError(f"{name} = {tuple(rng)} has no symmetric integer range (need low <= -1 and high >= 1)")
    return lim


def quantize(model: IsingModel, rule: str, h_range=(-7, 7), j_range=(-7, 7), *, keep_sign: bool = True,
             percentile: float = 95.0) -> IsingModel:
    """Integer, in-range copy of ``model`` under ``rule`` (see the module docstring).

    Args:
        model: the logical Ising model (real coefficients).
        rule: one of :data:`QUANTIZE_RULES`.
        h_range, j_range: the chip ranges (e.g. ``spec.h_range``).
        keep_sign: non-zero coefficients never round to 0.
        percentile: the clip point of ``clip95``.
    """
    if rule not in QUANTIZE_RULES:
        raise QuantizeError(f"rule = {rule!r} not in {QUANTIZE_RULES} (saturate() is the fixed-scale rule)")
    Lh, Lj = _limit(h_range, "h_range"), _limit(j_range, "j_range")
    if not (np.isfinite(percentile) and 0 < percentile <= 100):
        raise QuantizeError(f"percentile = {percentile!r} must be in (0, 100]")
    status, h, J = quantize_rules(model.h, model.J, _RULE_ARRAY[rule], float(Lh), float(Lj), bool(keep_sign),
                                  float(percentile))
    if status[0] != QUANT_OK:  # the validating constructor names the non-finite coefficient
        return IsingModel(h[0], J[0], 0.0, model.labels)
    return IsingModel.trusted(h[0], J[0], 0.0, model.labels)


_RULE_ARRAY = {r: np.array([RULE_IDS[r]], dtype=np.int64) for r in QUANTIZE_RULES}
_ALL_RULES = np.array([RULE_IDS[r] for r in QUANTIZE_RULES], dtype=np.int64)


def quantize_stack(model: IsingModel, rules=QUANTIZE_RULES, h_range=(-7, 7), j_range=(-7, 7), *,
                   keep_sign: bool = True, percentile: float = 95.0) -> tuple[np.ndarray, np.ndarray]:
    """:func:`quantize` of one model under several rules in one compiled call, as arrays.

    Returns ``(h (k, n), J (k, n, n))`` float64, row ``r`` equal to
    ``quantize(model, rules[r], ...)``'s ``h`` / ``J`` (default: all four rules, in
    :data:`QUANTIZE_RULES` order).

    Raises:
        QuantizeError: a bad rule, range or percentile.
        ModelError: a result is not finite (a non-zero coefficient whose relative size underflows).
    """
    for rule in rules:
        if rule not in QUANTIZE_RULES:
            raise QuantizeError(f"rule = {rule!r} not in {QUANTIZE_RULES} (saturate() is the fixed-scale rule)")
    Lh, Lj = _limit(h_range, "h_range"), _limit(j_range, "j_range")
    if not (np.isfinite(percentile) and 0 < percentile <= 100):
        raise QuantizeError(f"percentile = {percentile!r} must be in (0, 100]")
    ids = _ALL_RULES if tuple(rules) == QUANTIZE_RULES else np.array([RULE_IDS[r] for r in rules], dtype=np.int64)
    status, h, J = quantize_rules(model.h, model.J, ids, float(Lh), float(Lj), bool(keep_sign), float(percentile))
    bad = np.flatnonzero(status != QUANT_OK)
    if bad.size:
        IsingModel(h[bad[0]], J[bad[0]])  # raises ModelError naming the coefficient
    return h, J


def saturate(model: IsingModel, scale: float, h_range=(-7, 7), j_range=(-7, 7)) -> IsingModel:
    """Fixed-scale, saturating mapping (the authors' baseline): ``clip(rint(scale * c), range)``.

    Coefficients beyond the range are clipped (that is this rule's definition);
    small ones may round to zero.  The offset is scaled too.
    """
    if not (np.isfinite(scale) and scale > 0):
        raise QuantizeError(f"scale = {scale!r} must be a positive finite number")
    h_range, j_range = _pair(h_range, "h_range"), _pair(j_range, "j_range")
    h, J = saturate_arrays(model.h, model.J, float(scale), float(h_range[0]), float(h_range[1]),
                           float(j_range[0]), float(j_range[1]))
    offset = model.offset * scale
    if j_range[0] <= 0 <= j_range[1] and np.isfinite(offset):
        return IsingModel.trusted(h, J, float(offset), model.labels)
    # a J range without 0 turns the zero diagonal / lower triangle non-zero (refused or folded), or the
    # offset overflowed: the validating constructor handles (and names) these
    return IsingModel(h, J, offset, model.labels)
