"""The portfolio runner: multi-mapping dispatch, decode, filter, score (paper 4.2-4.3, Table 5).

Contract: :func:`run_portfolio` / :func:`run_portfolio_batch` turn each logical model into programs by
several :class:`Mapping` s (quantization rules, merge styles, branches, ...), dispatch them in one solver
call (optionally block-packed), decode every read, reject invalid candidates and score the rest on the
**original unquantized objective**: the best wins.  A mapping that cannot map a model is recorded as
failed and the rest still runs.  Design notes (statistics): docs/design/mapping_kernels.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from ising_backend.mapping.blocks import checked_layout, fill_packs
from ising_backend.mapping.branching import BranchError, branch
from ising_backend.machines.chip import ChipProgramError, stack_programs
from ising_backend.machines.logical import LogicalIsingSolver
from ising_backend.mapping.merge import MERGE_STYLES, MergeError, merge_spins, saturate_mapping
from ising_backend.models import IsingModel
from ising_backend.mapping.quantize import QUANTIZE_RULES, QuantizeError, quantize
from ising_backend.spec import ChipSpec

__all__ = [
    "MappedProgram", "Mapping", "QuantizeMapping", "MergeMapping", "SaturateMapping", "BranchMapping",
    "IdentityMapping", "quantize_portfolio", "merge_portfolio", "MappingOutcome", "PortfolioResult",
    "PortfolioStats", "run_portfolio", "run_portfolio_batch",
]

_MAPPING_ERRORS = (MergeError, QuantizeError, BranchError, ChipProgramError)


@dataclass(frozen=True, eq=False)
class MappedProgram:
    """One program to dispatch and its way back: ``to_logical(spins (..., n)) -> (logical int8, broken ties)``."""

    program: IsingModel
    to_logical: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


def _identity(n: int):
    def to_logical(spins):
        s = np.asarray(spins)[..., :n].astype(np.int8)
        return s, np.zeros(s.shape[:-1], dtype=np.int64)
    return to_logical


class Mapping:
    """Base class: ``name`` and ``map(model, spec) -> list[MappedProgram]``."""

    name: str = "mapping"

    def map(self, model: IsingModel, spec: ChipSpec) -> list[MappedProgram]:  # pragma: no cover - interface
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"


class IdentityMapping(Mapping):
    """The model as it is (already chip-legal, or for the logical solver)."""

    def __init__(self, name: str = "identity"):
        self.name = name

    def map(self, model, spec):
        return [MappedProgram(model, _identity(model.n))]


class QuantizeMapping(Mapping):
    """:func:`~ising_backend.mapping.quantize.quantize` with one rule."""

    def __init__(self, rule: str, keep_sign: bool = True):
        if rule not in QUANTIZE_RULES:
            raise ValueError(f"rule = {rule!r} not in {QUANTIZE_RULES}")
        self.name = rule
        self.rule = rule
        self.keep_sign = keep_sign

    def map(self, model, spec):
        q = quantize(model, self.rule, spec.h_range, spec.j_range, keep_sign=self.keep_sign)
        return [MappedProgram(q, _identity(model.n))]


class MergeMapping(Mapping):
    """:func:`~ising_backend.mapping.merge.merge_spins` with one style (decode: majority of copies)."""

    def __init__(self, style: str, scale: float = 1.0, tie: int | None = None, decode: str = "majority"):
        if style not in MERGE_STYLES:
            raise ValueError(f"style = {style!r} not in {MERGE_STYLES}")
        self.name = style
        self.style = style
        self.scale = scale
        self.tie = tie
        self.decode = decode

    def map(self, model, spec):
        mm = merge_spins(model, self.style, spec, scale=self.scale, tie=self.tie)
        return [MappedProgram(mm.physical, lambda s, mm=mm: mm.decode(s, self.decode))]


class SaturateMapping(Mapping):
    """The authors' fixed-scale, saturating mapping (clips by definition)."""

    def __init__(self, scale: float = 1.0, name: str = "saturate"):
        self.name = name
        self.scale = scale

    def map(self, model, spec):
        mm = saturate_mapping(model, spec, self.scale)
        return [MappedProgram(mm.physical, _identity(model.n))]


class BranchMapping(Mapping):
    """Spin-budget branches (:func:`~ising_backend.mapping.branching.branch`); each branch mapped by ``inner``."""

    def __init__(self, budget: int | None = None, inner: Mapping | None = None, name: str = "branch"):
        self.name = name
        self.budget = budget
        self.inner = IdentityMapping() if inner is None else inner

    def map(self, model, spec):
        budget = spec.n_spins if self.budget is None else self.budget
        out = []
        for br in branch(model, budget):
            for mp in self.inner.map(br.model, spec):
                def to_logical(s, br=br, mp=mp):
                    free, broken = mp.to_logical(s)
                    return br.decode(free), broken
                out.append(MappedProgram(mp.program, to_logical))
        return out


def quantize_portfolio(keep_sign: bool = True) -> list[Mapping]:
    """The paper's target-sharing portfolio: linear, clip95, rank, sqrt."""
    return [QuantizeMapping(r, keep_sign) for r in QUANTIZE_RULES]


def merge_portfolio(scale: float = 1.0, tie: int | None = None) -> list[Mapping]:
    """The paper's pathfinding portfolio: overload, max_coeff, high_degree, balanced."""
    return [MergeMapping(s, scale, tie) for s in MERGE_STYLES]


@dataclass
class MappingOutcome:
    """What one mapping produced for one problem."""

    programs: int = 0
    reads: int = 0
    valid: int = 0
    broken_ties: int = 0
    best_score: float = np.inf
    win: float = 0.0
    error: str | None = None

    @property
    def valid_rate(self) -> float:
        return self.valid / self.reads if self.reads else 0.0


@dataclass
class PortfolioResult:
    """Outcome of one logical problem.

    ``best`` is the selected candidate (``None`` if no mapping produced a valid
    one), ``best_score`` its original objective, ``best_spins`` its logical spins,
    ``best_mapping`` the first winning mapping; ``outcomes`` maps mapping name to
    :class:`MappingOutcome`; ``calls`` counts the solver calls (programs x reads)
    spent on this problem.
    """

    best: Any = None
    best_score: float = np.inf
    best_spins: np.ndarray | None = None
    best_mapping: str | None = None
    outcomes: dict = field(default_factory=dict)
    calls: int = 0

    @property
    def success(self) -> bool:
        return self.best_spins is not None


class PortfolioStats:
    """Aggregates :class:`PortfolioResult` s into the paper's Table 5 columns."""

    def __init__(self):
        self.problems = 0
        self.solved = 0
        self._rows: dict[str, dict] = {}

    def add(self, result: PortfolioResult) -> None:
        self.problems += 1
        self.solved += int(result.success)
        total_valid = sum(o.valid for o in result.outcomes.values())
        for name, o in result.outcomes.items():
            r = self._rows.setdefault(name, dict(problems=0, failed=0, programs=0, reads=0, valid=0,
                                                 solved=0, candidate_share_sum=0.0, wins=0.0, broken_ties=0))
            r["problems"] += 1
            r["failed"] += int(o.error is not None)
            r["programs"] += o.programs
            r["reads"] += o.reads
            r["valid"] += o.valid
            r["solved"] += int(o.valid > 0)
            r["candidate_share_sum"] += o.valid / total_valid if total_valid else 0.0
            r["wins"] += o.win
            r["broken_ties"] += o.broken_ties

    def table(self) -> list[dict]:
        """One row per mapping: valid rate, solved rate, candidate share, win share, ..."""
        total_wins = sum(r["wins"] for r in self._rows.values())
        rows = []
        for name, r in self._rows.items():
            rows.append({
                "mapping": name,
                "problems": r["problems"],
                "failed_maps": r["failed"],
                "reads": r["reads"],
                "valid_reads": r["valid"],
                "valid_rate": r["valid"] / r["reads"] if r["reads"] else 0.0,
                "solved_rate": r["solved"] / r["problems"] if r["problems"] else 0.0,
                "candidate_share": r["candidate_share_sum"] / r["problems"] if r["problems"] else 0.0,
                "wins": r["wins"],
                "win_share": r["wins"] / total_wins if total_wins else 0.0,
                "broken_ties": r["broken_ties"],
            })
        return rows

    @property
    def solved_rate(self) -> float:
        """Problems with at least one valid candidate / problems."""
        return self.solved / self.problems if self.problems else 0.0


def run_portfolio(model: IsingModel, mappings: Sequence[Mapping], solver, *, decode=None, is_valid=None,
                  objective=None, num_reads: int = 1, seed: int | None = None, pack: bool = False) -> PortfolioResult:
    """Run one logical model through a portfolio (see :func:`run_portfolio_batch`)."""
    return run_portfolio_batch([model], mappings, solver, decode=decode, is_valid=is_valid, objective=objective,
                               num_reads=num_reads, seed=seed, pack=pack)[0]


def _per_model(fn, k):
    if fn is None or callable(fn):
        return fn
    return fn[k]


def run_portfolio_batch(models: Sequence[IsingModel], mappings: Sequence[Mapping], solver, *, decode=None,
                        is_valid=None, objective=None, num_reads: int = 1, seed: int | None = None,
                        pack: bool = False) -> list[PortfolioResult]:
    """Map, dispatch (one solver call), decode, filter and score many problems.

    Args:
        models: logical Ising models (the original objective's view).
        mappings: the portfolio (mapping names must be distinct).
        solver: :class:`EmulatedChip` (physical calls) or :class:`LogicalIsingSolver`
            (projected logical calls); anything with ``anneal_batch`` and ``spec``.
        decode: ``decode(logical_spins int8 (n,)) -> candidate`` (``None`` = invalid);
            default: the spins themselves.  A list gives one per model.
        is_valid: ``is_valid(candidate) -> bool``; default: every decoded candidate.
        objective: ``objective(candidate) -> float`` on the original problem, lower is
            better; default: the logical model's energy of the spins.
        num_reads: reads per program.
        seed: solver seed for this call.
        pack: block-pack the programs into as few chip programs as fit
            ``spec.n_spins`` (fewer calls; chip only).

    Returns:
        One :class:`PortfolioResult` per model.
    """
    names = [m.name for m in mappings]
    if len(set(names)) != len(names):
        raise ValueError(f"mapping names must be distinct, got {names}")
    spec: ChipSpec = solver.spec
    budget = getattr(solver, "budget", spec.n_spins)  # the logical solver's budget may differ
    if budget != spec.n_spins:
        spec = spec.replace(n_spins=budget)
    results = [PortfolioResult(outcomes={name: MappingOutcome() for name in names}) for _ in models]
    jobs: list[tuple[int, str, MappedProgram]] = []
    for k, model in enumerate(models):
        for mp in mappings:
            try:
                progs = mp.map(model, spec)
            except _MAPPING_ERRORS as exc:
                results[k].outcomes[mp.name].error = str(exc)
                continue
            for p in progs:
                jobs.append((k, mp.name, p))
                results[k].outcomes[mp.name].programs += 1
    spins_per_job = _dispatch(solver, [p.program for _, _, p in jobs], num_reads, seed, pack)

    cache: list[dict] = [dict() for _ in models]
    for (k, name, p), raw in zip(jobs, spins_per_job):
        model = models[k]
        dec = _per_model(decode, k)
        val = _per_model(is_valid, k)
        obj = _per_model(objective, k)
        logical, broken = p.to_logical(raw)
        out = results[k].outcomes[name]
        results[k].calls += logical.shape[0]
        out.reads += logical.shape[0]
        out.broken_ties += int(np.sum(broken))
        for r in range(logical.shape[0]):
            s = logical[r]
            key = s.tobytes()
            hit = cache[k].get(key)
            if hit is None:
                cand = s if dec is None else dec(s)
                ok = cand is not None and (val is None or bool(val(cand)))
                score = (model.energy(s) if obj is None else float(obj(cand))) if ok else np.inf
                hit = (cand, ok, score)
                cache[k][key] = hit
            cand, ok, score = hit
            if not ok:
                continue
            out.valid += 1
            if score < out.best_score:
                out.best_score = score
            res = results[k]
            if score < res.best_score:
                res.best_score, res.best, res.best_spins, res.best_mapping = score, cand, s.copy(), name
    for res in results:
        if res.best_spins is None:
            continue
        tol = 1e-9 * max(1.0, abs(res.best_score))
        winners = [n for n in names if res.outcomes[n].best_score <= res.best_score + tol]
        for n in winners:
            res.outcomes[n].win = 1.0 / len(winners)
        res.best_mapping = next(n for n in names if n in winners)
    return results


def _dispatch(solver, programs: list[IsingModel], num_reads: int, seed, pack: bool) -> list[np.ndarray]:
    """Solve all programs in one solver call; returns per program ``spins (reads, n_p)``."""
    if not programs:
        return []
    if isinstance(solver, LogicalIsingSolver):
        return [r.spins for r in solver.solve_many(programs, num_reads=num_reads, seed=seed)]
    h, J = stack_programs(programs)
    if pack:  # first-fit decreasing onto the chip's spins (ising_backend.mapping.blocks)
        sizes = np.array([p.n for p in programs], dtype=np.int64)
        pack_of, order, n_packs, width = checked_layout(sizes, solver.spec.n_spins)
        h, J, where = fill_packs(h, J, sizes, order, pack_of, n_packs, width)
    else:
        where = np.stack([np.arange(len(programs)), np.zeros(len(programs), dtype=np.int64)], axis=1)
    spins, _ = solver.anneal_batch(h, J, num_reads=num_reads, seed=seed)
    return [spins[b, :, s0:s0 + p.n] for (b, s0), p in zip(where.tolist(), programs)]
