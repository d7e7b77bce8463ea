"""Spin merging: make an out-of-range model fit the chip with spare spins (paper section 4.2).

Contract: :func:`merge_spins` rounds ``scale x`` the coefficients (never rescales to fit) and, by one of
:data:`MERGE_STYLES`, duplicates overloaded spins onto spare spins tied ferromagnetically until every
coefficient fits, else raises :class:`MergeError` naming the coefficient and the spin budget; aligned
copies have exactly the rounded logical energy, and :meth:`MergedModel.decode` takes each spin's
majority copy.  Oracle: ``tests/mapping_reference.py``; design notes: docs/design/mapping_kernels.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ising_backend.mapping._merge_kernel import (
    MERGE_COUPLING_UNFIT,
    MERGE_FIELD_UNFIT,
    MERGE_OK,
    MERGE_TOO_MANY_SPINS,
    STYLE_IDS,
    decode_copies,
    merge_batch,
    merge_styles,
)
from ising_backend.models import IsingModel
from ising_backend.spec import ChipSpec

__all__ = [
    "MERGE_STYLES", "MergedModel", "MergeError", "merge_spins", "saturate_mapping", "merge_error_message",
    # the compiled kernels (array in, array out; see ising_backend.mapping._merge_kernel)
    "STYLE_IDS", "MERGE_OK", "MERGE_FIELD_UNFIT", "MERGE_COUPLING_UNFIT", "MERGE_TOO_MANY_SPINS",
    "merge_batch", "merge_styles", "decode_copies",
]

MERGE_STYLES = ("overload", "max_coeff", "high_degree", "balanced")
_DEFAULT_SPEC = ChipSpec()  # frozen: shared by the calls that pass no spec


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

    def __getattr__(self, name):
        # ``copies`` of a model built by merge_spins is made from the flat layout on first use
        d = self.__dict__
        if name == "copies" and "_ptr" in d:
            ptr, idx = d["_ptr"][0], d["_idx"][0]
            copies = tuple(idx[ptr[i]:ptr[i + 1]].copy() for i in range(ptr.size - 1))
            d["copies"] = copies
            return copies
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    @classmethod
    def _from_layout(cls, logical, physical, ptr, idx, style, scale) -> "MergedModel":
        """Internal: from a flat copy layout ``ptr (1, n + 1)``, ``idx (1, N)`` (int64)."""
        self = object.__new__(cls)
        self.__dict__.update(logical=logical, physical=physical, style=style, scale=scale,
                             _ptr=ptr, _idx=idx, _nlog=np.array([logical.n], dtype=np.int64))
        return self

    def layout(self) -> tuple[np.ndarray, np.ndarray]:
        """The copies as a flat layout ``(ptr (n + 1,), idx (N,))`` int64: the copies of
        logical spin ``i`` are ``idx[ptr[i]:ptr[i + 1]]`` (the form the compiled decoder takes)."""
        d = self.__dict__
        if "_ptr" not in d:
            sizes = np.array([len(c) for c in self.copies], dtype=np.int64)
            ptr = np.zeros((1, sizes.size + 1), dtype=np.int64)
            np.cumsum(sizes, out=ptr[0, 1:])
            idx = np.zeros((1, max(int(ptr[0, -1]), self.physical.n)), dtype=np.int64)
            if sizes.size:
                idx[0, :ptr[0, -1]] = np.concatenate([np.asarray(c, dtype=np.int64) for c in self.copies])
            d["_ptr"], d["_idx"] = ptr, idx
            d["_nlog"] = np.array([self.logical.n], dtype=np.int64)
        return d["_ptr"][0], d["_idx"][0]

    def decode(self, spins, method: str = "majority") -> tuple[np.ndarray, np.ndarray]:
        """Physical spins ``(..., n_phys)`` (extra trailing padding allowed) -> logical.

        Returns ``(logical_spins int8 (..., n_logical), broken_ties int (...,))``.
        """
        if method not in ("majority", "first"):
            raise ValueError(f"method = {method!r} not in ('majority', 'first')")
        s = np.asarray(spins)
        N = self.physical.n
        if s.ndim == 0 or s.shape[-1] < N:
            got = s.shape[-1] if s.ndim else 0
            raise ValueError(f"spins have {got} entries; the physical model has {N}")
        lead = s.shape[:-1]
        if s.shape[-1] != N:
            s = s[..., :N]
        if s.dtype != np.int8:
            s = s.astype(np.int64)
        s = np.ascontiguousarray(s).reshape(1, math.prod(lead), N)
        if "_ptr" not in self.__dict__:
            self.layout()
        d = self.__dict__
        decoded, broken = decode_copies(s, d["_nlog"], d["_ptr"], d["_idx"], method == "first")
        return decoded[0].reshape(lead + (self.logical.n,)), broken[0].reshape(lead)


def _limit(rng) -> int:
    lim = min(-int(rng[0]), int(rng[1]))
    if lim < 1:
        raise MergeError(f"range {tuple(rng)} has no symmetric integer range")
    return lim


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
    spec = _DEFAULT_SPEC if spec is None else spec
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
    m = merge_styles(H, C, _STYLE_ARRAY[style], Lh, Lj, tie, spec.n_spins)
    if m.status[0] != MERGE_OK:
        raise MergeError(merge_error_message(int(m.status[0]), m.err[0], H, C, m.a[0], Lh, Lj, spec.n_spins, scale))
    hp, Jp, ptr, idx = m.h, m.J, m.ptr, m.idx
    offset = model.offset * scale + float(m.offset_add[0])
    if math.isfinite(offset):
        physical = IsingModel.trusted(hp[0], Jp[0], float(offset))
    else:  # the validating constructor names the non-finite offset
        physical = IsingModel(hp[0], Jp[0], offset)
    return MergedModel._from_layout(model, physical, ptr, idx, style, float(scale))


_STYLE_ARRAY = {s: np.array([STYLE_IDS[s]], dtype=np.int64) for s in MERGE_STYLES}


def merge_error_message(status: int, err, H, C, a, Lh: int, Lj: int, n_spins: int, scale: float = 1.0) -> str:
    """The :class:`MergeError` message of a failed :func:`~._merge_kernel.merge_styles` style.

    Args: the style's ``status`` and ``err`` row, the rounded ``H`` / ``C`` given to the
    kernel, the style's copy counts ``a`` at the failure, the limits, the spin budget and
    the scale (for the message).
    """
    n = len(H)
    if status == MERGE_TOO_MANY_SPINS:
        return f"model has {n} spins; the chip has {n_spins}: branch first"
    i, j = int(err[0]), int(err[1])
    if status == MERGE_FIELD_UNFIT:
        what = f"field h[{i}] = {H[i]} (scaled x{scale:g}) needs {-(-abs(H[i]) // Lh)} copies, has {a[i]}"
    elif status == MERGE_COUPLING_UNFIT:
        what = f"coupling J[{i}, {j}] = {C[i, j]} (scaled x{scale:g}) exceeds {Lj} x {a[i]} x {a[j]} copy pairs"
    else:
        raise ValueError(f"status = {status!r} is not a merge failure code (1, 2 or 3)")
    return (f"{what}; all {n_spins} chip spins are used ({n} logical + "
            f"{int(np.sum(a) - n)} copies): use saturate, a smaller scale or a larger chip")


def saturate_mapping(model: IsingModel, spec: ChipSpec | None = None, scale: float = 1.0) -> MergedModel:
    """The authors' fixed-scale saturating mapping as a copy-free :class:`MergedModel`."""
    from ising_backend.mapping.quantize import saturate

    spec = _DEFAULT_SPEC if spec is None else spec
    if model.n > spec.n_spins:
        raise MergeError(f"model has {model.n} spins; the chip has {spec.n_spins}: branch first")
    phys = saturate(model, scale, spec.h_range, spec.j_range)
    if phys.labels is not None:  # the physical view is unlabelled (trusted: phys is valid already)
        phys = IsingModel.trusted(phys.h, phys.J, phys.offset)
    n = model.n
    ptr = np.arange(n + 1, dtype=np.int64).reshape(1, n + 1)
    idx = np.arange(n, dtype=np.int64).reshape(1, n)
    return MergedModel._from_layout(model, phys, ptr, idx, "saturate", float(scale))
