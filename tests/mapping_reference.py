"""Pure-Python/numpy oracles of the compiled mapping kernels (``ising_backend.mapping.merge`` / ``quantize``).

The implementations the package used before its hot paths were compiled, kept unchanged as the
specification: the tests hold the kernels bit-identical to them and ``benchmarks/host_kernels.py``
times both.  Test code only: the package never imports it.
"""

from __future__ import annotations

import numpy as np

from ising_backend.mapping.merge import MergedModel, MergeError, _limit
from ising_backend.models import IsingModel
from ising_backend.mapping.quantize import QUANTIZE_RULES, QuantizeError
from ising_backend.mapping.quantize import _limit as _q_limit
from ising_backend.mapping.quantize import _pair
from ising_backend.spec import ChipSpec

__all__ = ["merge_spins_ref", "decode_ref", "quantize_ref", "saturate_ref", "plan_packs_ref", "freeze_order_ref", "branch_ref"]

_SPLIT = {"overload": "spill", "max_coeff": "even", "high_degree": "spill", "balanced": "even"}
_MERGE_STYLES = ("overload", "max_coeff", "high_degree", "balanced")


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


def merge_spins_ref(model: IsingModel, style: str, spec: ChipSpec | None = None, scale: float = 1.0,
                    tie: int | None = None) -> MergedModel:
    """Reference :func:`.merge.merge_spins` (merge styles only)."""
    if style not in _MERGE_STYLES:
        raise ValueError(f"style = {style!r} not in {_MERGE_STYLES} (or 'saturate')")
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


def decode_ref(copies, n_physical: int, spins, method: str = "majority") -> tuple[np.ndarray, np.ndarray]:
    """Reference :meth:`.merge.MergedModel.decode` (``copies``: per logical spin, its physical indices)."""
    if method not in ("majority", "first"):
        raise ValueError(f"method = {method!r} not in ('majority', 'first')")
    s = np.asarray(spins)
    if s.shape[-1] < n_physical:
        raise ValueError(f"spins have {s.shape[-1]} entries; the physical model has {n_physical}")
    s = s[..., :n_physical].astype(np.int64)
    n = len(copies)
    out = s[..., :n].copy()
    broken = np.zeros(s.shape[:-1], dtype=np.int64)
    for i, c in enumerate(copies):
        if len(c) == 1:
            continue
        vals = s[..., c]
        tot = vals.sum(axis=-1)
        broken += np.abs(tot) != len(c)
        if method == "majority":
            out[..., i] = np.where(tot > 0, 1, np.where(tot < 0, -1, vals[..., 0]))
    return out.astype(np.int8), broken


def quantize_ref(model: IsingModel, rule: str, h_range=(-7, 7), j_range=(-7, 7), *, keep_sign: bool = True,
                 percentile: float = 95.0) -> IsingModel:
    """Reference :func:`.quantize.quantize`."""
    if rule not in QUANTIZE_RULES:
        raise QuantizeError(f"rule = {rule!r} not in {QUANTIZE_RULES} (saturate() is the fixed-scale rule)")
    Lh, Lj = _q_limit(h_range, "h_range"), _q_limit(j_range, "j_range")
    if not (np.isfinite(percentile) and 0 < percentile <= 100):
        raise QuantizeError(f"percentile = {percentile!r} must be in (0, 100]")
    n = model.n
    iu = np.triu_indices(n, 1)
    c = np.concatenate([model.h, model.J[iu]])
    top = np.abs(c).max(initial=0.0)
    if 0 < top < np.inf:  # exact power-of-four scale: the same ratios, no underflow of tiny ones
        e = int(np.frexp(top)[1])
        c = np.ldexp(c, -(e + (e & 1)))
    lim = np.concatenate([np.full(n, float(Lh)), np.full(iu[0].size, float(Lj))])
    q = np.zeros_like(c)
    nz = c != 0
    if nz.any():
        if rule == "rank":
            rel = np.abs(c[nz]) / lim[nz]
            uniq, inv = np.unique(rel, return_inverse=True)
            frac = inv / (uniq.size - 1) if uniq.size > 1 else np.ones(inv.size)
            q[nz] = np.sign(c[nz]) * np.rint(1 + (lim[nz] - 1) * frac)
        else:
            v = np.sign(c) * np.sqrt(np.abs(c)) if rule == "sqrt" else c
            rel = np.abs(v[nz]) / lim[nz]
            a = np.percentile(rel, percentile) if rule == "clip95" else rel.max()
            with np.errstate(over="ignore"):  # a ratio past the float range saturates like any large one
                q = np.clip(np.rint(v / a), -lim, lim)
        if keep_sign:
            small = nz & (q == 0)
            q[small] = np.sign(c[small])
    h = q[:n]
    J = np.zeros((n, n))
    J[iu] = q[n:]
    return IsingModel(h, J, 0.0, model.labels)


def saturate_ref(model: IsingModel, scale: float, h_range=(-7, 7), j_range=(-7, 7)) -> IsingModel:
    """Reference :func:`.quantize.saturate`."""
    if not (np.isfinite(scale) and scale > 0):
        raise QuantizeError(f"scale = {scale!r} must be a positive finite number")
    h_range, j_range = _pair(h_range, "h_range"), _pair(j_range, "j_range")
    h = np.clip(np.rint(model.h * scale), h_range[0], h_range[1])
    J = np.clip(np.rint(model.J * scale), j_range[0], j_range[1])
    return IsingModel(h, J, model.offset * scale, model.labels)


def plan_packs_ref(sizes, capacity: int) -> list[list[int]]:
    """First-fit decreasing of ``sizes`` into packs of ``capacity`` (the oracle of ``ising_backend.pack_layout``):
    programs by decreasing size, ties by index, each into the first pack with room; packs ascending."""
    sizes = [int(v) for v in sizes]
    order = sorted(range(len(sizes)), key=lambda k: (-sizes[k], k))
    packs: list[list[int]] = []
    room: list[int] = []
    for k in order:
        for p in range(len(packs)):
            if room[p] >= sizes[k]:
                packs[p].append(k)
                room[p] -= sizes[k]
                break
        else:
            packs.append([k])
            room.append(capacity - sizes[k])
    return [sorted(p) for p in packs]


def freeze_order_ref(model: IsingModel) -> np.ndarray:
    """Spins by decreasing ``|h_i| + sum_j |J_ij|``, lowest index first on ties (the oracle of
    ``ising_backend.mapping.branching.freeze_strength`` / ``frozen_spins``)."""
    strength = np.abs(model.h) + np.abs(model.J_sym).sum(axis=1)
    return np.argsort(-strength, kind="stable")


def branch_ref(model: IsingModel, budget: int) -> list[tuple[IsingModel, np.ndarray, np.ndarray, np.ndarray]]:
    """``ising_backend.branch`` in numpy: ``(reduced model, free, frozen, values)`` per branch, the ``k = n - budget``
    strongest spins frozen (sorted), branch ``m`` setting ``frozen[t]`` to +1 when bit ``t`` of ``m`` is set."""
    k = max(0, model.n - budget)
    frozen = np.sort(freeze_order_ref(model)[:k])
    free = np.setdiff1d(np.arange(model.n), frozen)
    out = []
    for m in range(2 ** k):
        z = np.array([1.0 if (m >> t) & 1 else -1.0 for t in range(k)])
        h = model.h[free] + model.J_sym[np.ix_(free, frozen)] @ z
        off = model.offset + float(model.h[frozen] @ z) + float(z @ model.J[np.ix_(frozen, frozen)] @ z)
        out.append((IsingModel(h, model.J[np.ix_(free, free)], off), free, frozen, z.astype(np.int8)))
    return out
