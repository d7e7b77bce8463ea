"""Spin merging: make an out-of-range model fit the chip with spare spins (paper section 4.2).

When a coefficient exceeds the hardware range, *spin merging* duplicates an
overloaded logical spin onto a spare physical spin, ties the copies together
ferromagnetically, and splits the large fields/couplings between the copies so
every coefficient fits.  The styles give different hardware views of the same
logical model and are solved as a portfolio.

Procedure (common to all styles; the paper is silent on the details):

1. **Fixed-scale rounding.**  Coefficients are multiplied by ``scale`` (default
   1: the model is already in chip units) and rounded to integers.  Nothing is
   rescaled to fit: merging exists precisely to avoid crushing small terms.
2. **Duplication loop.**  With ``a_i`` copies of logical spin ``i``, field
   ``H_i`` fits if ``|H_i| <= L_h * a_i`` and coupling ``C_ij`` fits if
   ``|C_ij| <= L_j * a_i * a_j`` (it can be spread over all copy pairs).  While
   something does not fit, the style picks one spin and adds a copy; if the
   chip's ``n_spins`` are used up first, :class:`MergeError` names the coefficient
   that still does not fit and the spin budget.
3. **Ties.**  Every pair of copies of one spin gets coupling ``-tie`` (default
   the range limit ``L_j``: the strongest ferromagnetic bond), and
   ``tie x pairs`` is added to the offset, so a configuration with all copies
   aligned has exactly the rounded logical energy.
4. **Splitting** a field over the copies, or a coupling over the copy pairs
   (original copies first, then in creation order), either ``"spill"`` (fill the
   first slot up to the limit, the rest to the next: the original copy keeps the
   structure, duplicates take only the excess) or ``"even"`` (integer split as even
   as possible: every copy carries a share).  Integer totals are split exactly.

Styles (which spin to duplicate, how to split):

``overload``     the spin with the largest total excess ``sum(|c| - capacity)``
                 over its non-fitting terms; ``spill``.
``max_coeff``    an endpoint of the single worst term (largest ``|c| / capacity``;
                 of a coupling, the endpoint with fewer copies, then the larger
                 total ``|coupling|``); ``even``.
``high_degree``  among spins in non-fitting terms, the one with most non-zero
                 couplings (it spreads load over most neighbours); ``spill``.
``balanced``     among spins in non-fitting terms, the one with fewest copies so
                 far (ties: largest excess); ``even``.

Ties between candidates break on the lowest index.  Decoding
(:meth:`MergedModel.decode`) takes the majority of each spin's copies (a tie goes
to the original copy) or, with ``method="first"``, the original copy, and reports
the number of broken ties (logical spins whose copies disagree) per sample.

:func:`saturate_mapping` is the authors' baseline (fixed scale, round, clip at
the range) wrapped in the same :class:`MergedModel` interface with no copies.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .models import IsingModel
from .spec import ChipSpec

__all__ = ["MERGE_STYLES", "MergedModel", "MergeError", "merge_spins", "saturate_mapping"]

MERGE_STYLES = ("overload", "max_coeff", "high_degree", "balanced")
_SPLIT = {"overload": "spill", "max_coeff": "even", "high_degree": "spill", "balanced": "even"}


class MergeError(ValueError):
    """The model cannot be made to fit the chip by merging within the spin budget."""


@dataclass(frozen=True, eq=False)
class MergedModel:
    """A chip-legal physical view of a logical model.

    Attributes:
        logical: the original (unscaled, unrounded) logical model.
        physical: chip-legal integer :class:`IsingModel`; spin ``i < logical.n``
            is the original copy of logical spin ``i``, extra copies follow.
        copies: per logical spin, the physical indices of its copies (original first).
        style: the merge style (or ``"saturate"``).
        scale: the fixed scale applied before rounding.
    """

    logical: IsingModel
    physical: IsingModel
    copies: tuple
    style: str
    scale: float

    @property
    def n_extra(self) -> int:
        """Spare physical spins used as copies."""
        return self.physical.n - self.logical.n

    def decode(self, spins, method: str = "majority") -> tuple[np.ndarray, np.ndarray]:
        """Physical spins ``(..., n_phys)`` (extra trailing padding allowed) -> logical.

        Returns ``(logical_spins int8 (..., n_logical), broken_ties int (...,))``.
        """
        if method not in ("majority", "first"):
            raise ValueError(f"method = {method!r} not in ('majority', 'first')")
        s = np.asarray(spins)
        if s.shape[-1] < self.physical.n:
            raise ValueError(f"spins have {s.shape[-1]} entries; the physical model has {self.physical.n}")
        s = s[..., : self.physical.n].astype(np.int64)
        n = self.logical.n
        out = s[..., :n].copy()
        broken = np.zeros(s.shape[:-1], dtype=np.int64)
        for i, c in enumerate(self.copies):
            if len(c) == 1:
                continue
            vals = s[..., c]
            tot = vals.sum(axis=-1)
            broken += np.abs(tot) != len(c)
            if method == "majority":
                out[..., i] = np.where(tot > 0, 1, np.where(tot < 0, -1, vals[..., 0]))
        return out.astype(np.int8), broken


def _limit(rng) -> int:
    lim = min(-int(rng[0]), int(rng[1]))
    if lim < 1:
        raise MergeError(f"range {tuple(rng)} has no symmetric integer range")
    return lim


def _split(total: int, k: int, lim: int, mode: str) -> list[int]:
    """Split integer ``total`` into ``k`` integer pieces each of magnitude <= ``lim``."""
    sgn = 1 if total >= 0 else -1
    t = abs(int(total))
    if mode == "spill":
        pieces = []
        for _ in range(k):
            p = min(lim, t)
            pieces.append(p)
            t -= p
    else:
        q, r = divmod(t, k)
        pieces = [q + (1 if m < r else 0) for m in range(k)]
    return [sgn * p for p in pieces]


def merge_spins(model: IsingModel, style: str, spec: ChipSpec | None = None, scale: float = 1.0,
                tie: int | None = None) -> MergedModel:
    """Map ``model`` onto the chip by spin merging (see the module docstring).

    Raises:
        MergeError: the spin budget runs out before every coefficient fits.
    """
    if style == "saturate":
        return saturate_mapping(model, spec, scale)
    if style not in MERGE_STYLES:
        raise ValueError(f"style = {style!r} not in {MERGE_STYLES} (or 'saturate')")
    spec = ChipSpec() if spec is None else spec
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"scale = {scale!r} must be a positive finite number")
    Lh, Lj = _limit(spec.h_range), _limit(spec.j_range)
    tie = Lj if tie is None else tie
    if isinstance(tie, bool) or not isinstance(tie, (int, np.integer)) or not (1 <= tie <= Lj):
        raise MergeError(f"tie = {tie!r} must be an integer in [1, {Lj}] (the coupling range limit)")
    tie = int(tie)
    n = model.n
    if n > spec.n_spins:
        raise MergeError(f"model has {n} spins; the chip has {spec.n_spins}: branch first")
    H = np.rint(model.h * scale).astype(np.int64)
    C = np.rint(model.J * scale).astype(np.int64)
    absC = np.abs(C) + np.abs(C).T
    degree = (absC != 0).sum(axis=1)
    strength = absC.sum(axis=1)
    a = np.ones(n, dtype=np.int64)

    while True:
        cap_h = Lh * a
        cap_j = Lj * np.outer(a, a)
        ex_h = np.abs(H) - cap_h
        ex_j = np.triu(np.abs(C) - cap_j, 1)
        bad_h = ex_h > 0
        bad_j = ex_j > 0
        if not bad_h.any() and not bad_j.any():
            break
        if n + int((a - 1).sum()) >= spec.n_spins:
            if bad_h.any():
                i = int(np.argmax(np.where(bad_h, ex_h, -1)))
                what = f"field h[{i}] = {H[i]} (scaled x{scale:g}) needs {-(-abs(H[i]) // Lh)} copies, has {a[i]}"
            else:
                i, j = np.unravel_index(int(np.argmax(ex_j)), ex_j.shape)
                what = f"coupling J[{i}, {j}] = {C[i, j]} (scaled x{scale:g}) exceeds {Lj} x {a[i]} x {a[j]} copy pairs"
            raise MergeError(f"{what}; all {spec.n_spins} chip spins are used ({n} logical + "
                             f"{int((a - 1).sum())} copies): use saturate, a smaller scale or a larger chip")
        excess = np.where(bad_h, ex_h, 0).astype(np.float64)
        exj = np.where(bad_j, ex_j, 0)
        excess += exj.sum(axis=1) + exj.sum(axis=0)
        involved = excess > 0
        if style == "overload":
            pick = int(np.argmax(excess))
        elif style == "max_coeff":
            ratio_h = np.where(bad_h, np.abs(H) / cap_h, 0.0)
            ratio_j = np.where(bad_j, np.abs(C) / np.maximum(cap_j, 1), 0.0)
            if ratio_h.max() >= ratio_j.max():
                pick = int(np.argmax(ratio_h))
            else:
                i, j = np.unravel_index(int(np.argmax(ratio_j)), ratio_j.shape)
                key_i = (a[i], -strength[i], i)
                key_j = (a[j], -strength[j], j)
                pick = int(i if key_i <= key_j else j)
        elif style == "high_degree":
            key = np.where(involved, degree * 1e6 + excess, -1.0)
            pick = int(np.argmax(key))
        else:  # balanced
            key = np.where(involved, -a * 1e9 + excess, -np.inf)
            pick = int(np.argmax(key))
        a[pick] += 1

    # physical layout: originals 0..n-1, then copies in creation order (grouped by spin)
    copies = []
    nxt = n
    for i in range(n):
        c = [i] + list(range(nxt, nxt + a[i] - 1))
        nxt += a[i] - 1
        copies.append(np.array(c, dtype=np.int64))
    N = nxt
    mode = _SPLIT[style]
    hp = np.zeros(N)
    Jp = np.zeros((N, N))
    single = a == 1
    hp[:n] = np.where(single, H, 0)
    Jp[:n, :n] = np.where(np.outer(single, single), C, 0)
    for i in np.flatnonzero(~single):
        for p, v in zip(copies[i], _split(H[i], a[i], Lh, mode)):
            hp[p] = v
    multi = ~np.outer(single, single) & (C != 0)
    for i, j in zip(*np.nonzero(np.triu(multi, 1))):
        pairs = [(p, q) for p in copies[i] for q in copies[j]]
        for (p, q), v in zip(pairs, _split(C[i, j], len(pairs), Lj, mode)):
            lo, hi = (p, q) if p < q else (q, p)
            Jp[lo, hi] += v
    n_ties = 0
    for c in copies:
        for x in range(len(c)):
            for y in range(x + 1, len(c)):
                Jp[min(c[x], c[y]), max(c[x], c[y])] = -tie
                n_ties += 1
    physical = IsingModel(hp, Jp, model.offset * scale + tie * n_ties)
    return MergedModel(model, physical, tuple(copies), style, float(scale))


def saturate_mapping(model: IsingModel, spec: ChipSpec | None = None, scale: float = 1.0) -> MergedModel:
    """The authors' fixed-scale saturating mapping as a copy-free :class:`MergedModel`."""
    from .quantize import saturate

    spec = ChipSpec() if spec is None else spec
    if model.n > spec.n_spins:
        raise MergeError(f"model has {model.n} spins; the chip has {spec.n_spins}: branch first")
    phys = saturate(model, scale, spec.h_range, spec.j_range)
    copies = tuple(np.array([i], dtype=np.int64) for i in range(model.n))
    return MergedModel(model, IsingModel(phys.h, phys.J, phys.offset), copies, "saturate", float(scale))
