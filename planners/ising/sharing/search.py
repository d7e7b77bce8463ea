"""Recursive Ising target sharing: the search of paper 5.3 (Algorithm 3).

Contract: ``IsingSharing(chip, config).assign(dist, n_robots, tour, rng) -> SharingResult``;
a split that never decodes valid, a group beyond the spin budget or a refused
program is a failure result (``result.failure``), never an invented split.
Stages split every group with several robots, then refine one-robot groups and
bundles; each stage's splits x quantization rules are block-packed into one chip
submission (:func:`ising_backend.run_portfolio_batch`), decoded and scored on the
unquantized cut; a beam of distinct candidates is carried to the complete
assignments, which are compared by route cost.  Chip calls are metered
(:class:`ising_backend.MeteredSolver`); a chip that cannot answer hands the call to
SSA (flagged; :mod:`planners.ising.fallback`).  Choices and measurements: docs/design/ising_sharing.md.
"""

from __future__ import annotations

import numpy as np

from ising_backend import (
    BranchMapping, ChipProgramError, ChipUnavailableError, MeteredSolver, ModelError, QuantizeError, QuantizeMapping,
    SolverOutputError, ising_from_qubo, plan_packs, quantize_stack, run_portfolio_batch,
)
from planners.base import SharingResult, TourSolver
from planners.compute import ComputeReport
from planners.ising.config import ConfigAttributes, resolve_config
from planners.ising.fallback import counted, flag, unavailable_message, wants_fallback
from planners.ising.sharing.boundary import BoundaryRefinement
from planners.ising.sharing.bundles import BundlePricer, SharingFailure, assign_bundles
from planners.ising.sharing.coarse import CoarseSplit, CoarseSplits
from planners.ising.sharing.components import Components
from planners.ising.sharing.config import SharingConfig
from planners.ising.sharing.kernels import candidate_sides, fill_packs, map_stage, score_stage, split_model
from planners.ising.sharing.qubo import SplitProblem, build_split_qubo, choose_anchors, cut_value, decode_split

__all__ = ["IsingSharing", "PaperIsingSharing"]


class IsingSharing(ConfigAttributes, Components, CoarseSplits, BoundaryRefinement):
    """Recursive Ising target sharing on the emulated physical chip (module docstring).

    Args:
        chip: an :class:`ising_backend.EmulatedChip` or anything with its ``spec``,
            ``ledger`` and ``anneal_batch`` (default: a fresh ``EmulatedChip(ChipSpec())``).
        config: a :class:`SharingConfig`; keyword ``options`` override its fields.
    """

    name = "ising"
    config_class = SharingConfig
    defaults: SharingConfig | None = None  # None: SharingConfig()

    def __init__(self, chip=None, config: SharingConfig | None = None, **options) -> None:
        from ising_backend import ChipSpec, EmulatedChip

        self.config = resolve_config(SharingConfig, config, options, self.defaults)
        self.chip = EmulatedChip(ChipSpec()) if chip is None else chip
        from ising_backend import QUANTIZE_RULE_IDS

        spec = self.chip.spec
        self._rule_ids = np.array([QUANTIZE_RULE_IDS[r] for r in self.config.rules], dtype=np.int64)
        self._limits = tuple(float(min(-int(r[0]), int(r[1]))) for r in (spec.h_range, spec.j_range))

    def __repr__(self) -> str:
        return f"IsingSharing({self.config!r})"

    # ------------------------------------------------------------------ api

    def assign(self, dist, n_robots: int, tour: TourSolver, rng: np.random.Generator | None = None) -> SharingResult:
        dist = np.asarray(dist, dtype=float)
        if dist.ndim != 2 or dist.shape[0] != dist.shape[1]:
            raise ValueError(f"dist must be a square (R+N, R+N) matrix, got shape {dist.shape}")
        R = int(n_robots)
        if not 1 <= R <= dist.shape[0]:
            raise ValueError(f"n_robots must be in 1..{dist.shape[0]}, got {n_robots}")
        if rng is None:
            rng = np.random.default_rng()
        N = dist.shape[0] - R
        mapping = {r: {"candidates": 0, "valid": 0, "wins": 0} for r in self.config.rules}
        stats: dict = {
            "mapping": {"sharing": mapping},
            "stages": 0,
            "splits": 0,
            "trivial_splits": 0,
            "bundles": 0,
            "tour_solves": 0,
            "states": 0,
        }
        empty = tuple(() for _ in range(R))
        if not np.all(np.isfinite(dist)):
            return self._assign_components(dist, R, tour, rng, stats)
        if N == 0:
            return SharingResult(assignment=empty, compute=ComputeReport(), stats=stats)
        if R == 1:
            return SharingResult(assignment=(tuple(range(N)),), compute=ComputeReport(), stats=stats)

        self._meter = MeteredSolver(self.chip)
        pricer = BundlePricer(dist, tour, self.config.pricing_tour, rng, stats)
        cost = pricer.cost

        self._memo: dict = {}
        try:
            states = self._split_all(self.split_weights(dist, R), R, rng, stats)
            best = None
            for groups in states:
                sets = assign_bundles(dist, R, groups, cost, self.config.bundle_order, stats)
                if len(states) == 1:
                    best = (0.0, sets)
                    break
                total = sum(cost(k, sets[k]) for k in range(R))
                if best is None or total < best[0] - 1e-9:  # ties: the state with the larger cuts
                    best = (total, sets)
            sets = best[1]
            if self.config.pair_rounds:
                sets = self._refine_boundaries(dist, R, sets, cost, rng, stats)
            assignment = tuple(tuple(sorted(t - R for t in ts)) for ts in sets)
            self._memo = {}
        except (SharingFailure, ChipUnavailableError) as exc:
            self._memo = {}
            unavailable = isinstance(exc, ChipUnavailableError)
            reason = unavailable_message(exc) if unavailable else str(exc)
            compute = ComputeReport.from_ledger(self._meter.charged) + pricer.compute
            if wants_fallback(self.config.fallback, unavailable):  # SSA, the strong pipeline's sharing
                from planners.sharing_classical import SSASharing

                res = SSASharing().assign(dist, R, tour, rng)
                return SharingResult(assignment=res.assignment, compute=counted(compute, res.compute),
                                     stats=flag(stats, "sharing", reason))
            return SharingResult(assignment=empty, compute=compute, stats=stats, failure=reason)
        return SharingResult(assignment=assignment, compute=ComputeReport.from_ledger(self._meter.charged) + pricer.compute, stats=stats)

    def split_weights(self, dist: np.ndarray, R: int, shift: float | None = None) -> np.ndarray:
        """Edge weights ``w_ij`` of the split graph: ``dist ** weight_power`` minus
        ``shift`` (default ``weight_shift``) x its mean over node pairs, robot-target edges then
        multiplied by ``robot_weight`` (zero diagonal)."""
        w = np.asarray(dist, dtype=float) ** self.config.weight_power
        shift = self.config.weight_shift if shift is None else shift
        if shift:
            n = w.shape[0]
            mean = float(w[np.triu_indices(n, 1)].mean()) if n > 1 else 0.0
            w = w - shift * mean
            np.fill_diagonal(w, 0.0)
        if self.config.robot_weight != 1.0:
            w = w.copy()
            w[:R, R:] *= self.config.robot_weight
            w[R:, :R] *= self.config.robot_weight
        return w

    # -------------------------------------------------------------- helpers

    def _problem(self, dist, R, nodes, kind) -> SplitProblem:
        nodes = np.asarray(nodes, dtype=np.int64)
        balance = self.config.balance if kind == "robots" else 0.0
        if len(nodes) < 2 or balance:
            a, b = choose_anchors(dist, nodes, R)  # the reference (and its errors), and the balance term
            free = np.array([n for n in nodes if n != a and n != b], dtype=np.int64)
            q, Q, offset = None, None, None
        else:
            a, b, free, q, Q, offset = split_model(dist, nodes, R)
            a, b = int(a), int(b)
        limit = int(self.chip.spec.n_spins) + self.config.max_frozen
        if len(free) > limit:
            raise SharingFailure(
                f"a group of {len(nodes)} nodes needs {len(free)} free spins after anchor substitution; "
                f"the chip has {self.chip.spec.n_spins} spins and spin-budget branching freezes at most "
                f"max_frozen = {self.config.max_frozen} (at most {limit + 2} robots + targets per group)"
            )
        if q is None:
            q, Q, offset = build_split_qubo(dist, free, a, b, R, balance)
        return SplitProblem(nodes=nodes, a=a, b=b, free=free, q=q, Q=Q, offset=float(offset), kind=kind)

    def _split_all(self, w, R, rng, stats) -> list[list[np.ndarray]]:
        """All candidate partial solutions (lists of groups) after the split stages.

        Robot (refinement) stages keep up to ``beam`` (``refine_beam``)
        distinct valid chip candidates per split (best unquantized cuts
        first) and expand every state by them (at most ``max_states``
        states, ranked by the sum of their chosen cuts).  Every stage is one
        chip submission for the splits of all states.
        """
        states: list[tuple[float, list[np.ndarray]]] = [(0.0, [np.arange(w.shape[0])])]
        while True:  # robot stages: split every group holding more than one robot
            # groups are sorted node arrays: robots (nodes < R) come first
            todo = [(si, gi) for si, (_, st) in enumerate(states) for gi, g in enumerate(st) if g.searchsorted(R) >= 2]
            if not todo:
                break
            problems = self._stage(w, R, [states[si][1][gi] for si, gi in todo], "robots", rng, stats)
            states = self._expand(states, todo, problems, self.config.beam)
        for _ in range(self.config.refine_stages):
            base_max, above = self.config.resolved_base_max, self.config.refine_above
            todo = []
            for si, (_, st) in enumerate(states):
                for gi, g in enumerate(st):
                    nr = g.searchsorted(R)
                    if len(g) - nr > (base_max if nr else above):
                        todo.append((si, gi))
            if not todo:
                break
            problems = self._stage(w, R, [states[si][1][gi] for si, gi in todo], "refine", rng, stats)
            states = self._expand(states, todo, problems, self.config.refine_beam)
        stats["states"] += len(states)
        return [st for _, st in states]

    def _expand(self, states, todo, problems, width: int):
        """Replace the split groups of every state by up to ``width`` candidate splits each
        (a beam over the state's splits, then over all states: at most ``max_states``)."""
        expanded: list[tuple[float, list[np.ndarray]]] = []
        for si, (score, st) in enumerate(states):
            mine = {gi: p for (sj, gi), p in zip(todo, problems) if sj == si}
            if not mine:
                expanded.append((score, st))
                continue
            keys = sorted(mine)
            combos: list[tuple[float, tuple]] = [(0.0, ())]
            for gi in keys:
                combos = [(sc + c[0], combo + (c,)) for sc, combo in combos for c in mine[gi].cands[:width]]
                order = sorted(range(len(combos)), key=lambda i: (-combos[i][0], i))
                combos = [combos[i] for i in order[: self.config.max_states]]
            for _, combo in combos:
                chosen = dict(zip(keys, combo))
                groups: list[np.ndarray] = []
                for gi, g in enumerate(st):
                    if gi in chosen:
                        groups.extend([chosen[gi][1], chosen[gi][2]])
                    else:
                        groups.append(g)
                expanded.append((score + sum(c[0] for c in combo), groups))
        order = sorted(range(len(expanded)), key=lambda i: (-expanded[i][0], i))
        return [expanded[i] for i in order[: self.config.max_states]]

    def _stage(self, w, R, groups, kind, rng, stats) -> list[SplitProblem]:
        """Solve the splits of ``groups`` (one chip submission, plus retries); each problem's
        ``cands`` lists its distinct valid candidates, best unquantized cut first.

        The same group met again (in another partial solution, or an earlier
        stage) reuses its solved split from ``self._memo`` instead of a new chip call.
        """
        memo = self._memo
        keys = [(kind, tuple(int(v) for v in np.sort(g))) for g in groups]
        fresh: dict = {}
        for key, g in zip(keys, groups):
            if key not in memo and key not in fresh:
                too_big = len(g) - 2 > int(self.chip.spec.n_spins) + self.config.max_frozen
                fresh[key] = self._coarse_split(w, R, g, kind, rng, stats) if too_big else self._problem(w, R, g, kind)
        stats["stages"] += 1
        stats["splits"] += len(fresh)
        pending = []
        for p in fresh.values():
            if isinstance(p, CoarseSplit):  # solved on its clusters already
                continue
            if len(p.free) == 0:  # one partition only: nothing to solve
                stats["trivial_splits"] += 1
                side0, side1 = decode_split(p, np.zeros(0, dtype=np.int8))
                p.cands = [(cut_value(w, side0, side1), side0, side1, None)]
            else:
                pending.append(p)
        self._solve_all(w, R, pending, rng, stats)
        memo.update(fresh)
        return [memo[key] for key in keys]

    def _solve_all(self, w, R, pending, rng, stats) -> None:
        """Solve ``pending`` split problems on the chip, re-submitting those without a valid
        candidate up to ``retries`` times; still none is a :class:`SharingFailure`."""
        attempts = 0
        while pending:
            self._solve(w, R, pending, rng, stats)
            failed = [p for p in pending if not p.cands]
            if failed and attempts >= self.config.retries:
                p = failed[0]
                raise SharingFailure(
                    f"every chip candidate for the split of group {p.nodes.tolist()} was invalid "
                    f"after {attempts + 1} submissions"
                )
            attempts += 1
            pending = failed

    def _valid(self, R, side0, side1, kind) -> bool:
        if self.config.reject_empty_robot_side and kind == "robots":
            for side in (side0, side1):
                if (side < R).any() and not (side >= R).any():
                    return False
        return True

    def _solve_packed(self, w, R, problems, rng, stats) -> None:
        """The submission of :meth:`_solve` for splits that fit the chip, in compiled calls: every
        split x quantization rule mapped at once (:func:`.kernels.map_stage`), block-packed
        first-fit decreasing (:func:`ising_backend.plan_packs`) into one ``anneal_batch``, every
        read decoded, checked and scored at once (:func:`.kernels.score_stage`); each distinct
        valid partition becomes a candidate."""
        cfg = self.config
        spec = self.chip.spec
        seed = int(rng.integers(2**63 - 1))
        rules = cfg.rules
        nr = len(rules)
        P = len(problems)
        f = max(len(p.free) for p in problems)
        q = np.zeros((P, f))
        Q = np.zeros((P, f, f))
        free = np.zeros((P, f), dtype=np.int64)
        sizes = np.empty(P, dtype=np.int64)
        for k, p in enumerate(problems):
            n = len(p.free)
            sizes[k] = n
            q[k, :n] = p.q
            Q[k, :n, :n] = p.Q
            free[k, :n] = p.free
        status, qh, qJ = map_stage(q, Q, sizes, self._rule_ids, *self._limits)
        if status.any():  # a non-finite quantized coefficient: the checked path names it
            for k, p in enumerate(problems):
                try:
                    quantize_stack(ising_from_qubo(p.q, p.Q, p.offset), rules, spec.h_range, spec.j_range)
                except (QuantizeError, ModelError) as exc:
                    raise SharingFailure(f"a split program could not be quantized: {exc}") from exc
        prog_sizes = np.repeat(sizes, nr)
        # a faulty chip's programs stay clear of the stuck spins its health probe found
        capacity = max(int(getattr(self.chip, "usable_spins", spec.n_spins)), int(prog_sizes.max()))
        packs = plan_packs(prog_sizes.tolist(), capacity)
        width = max(int(prog_sizes[pk].sum()) for pk in packs)
        pack_of = np.empty(P * nr, dtype=np.int64)
        for b, pk in enumerate(packs):
            pack_of[pk] = b
        order = np.array([j for pk in packs for j in pk], dtype=np.int64)  # placement order within packs
        h, J, where = fill_packs(qh, qJ, prog_sizes, order, pack_of, len(packs), width)
        try:
            spins, _ = self._meter.anneal_batch(h, J, num_reads=cfg.reads, seed=seed)
        except SolverOutputError as exc:  # a broken chip: nothing to decode
            raise SharingFailure(f"the chip returned malformed samples: {exc}") from exc
        except ChipProgramError as exc:  # a mapped program the chip cannot take: a clear failure
            raise SharingFailure(f"the chip refused a mapped split program: {exc}") from exc
        anchors = np.array([(p.a, p.b) for p in problems], dtype=np.int64)
        reject = np.array([cfg.reject_empty_robot_side and p.kind == "robots" for p in problems])
        n_valid, best, c_split, c_cut, c_side = score_stage(spins, where, sizes, nr, free, anchors, w, R, reject)
        mapping = stats["mapping"]["sharing"]
        cands: list = [[] for _ in problems]
        s0, n0, s1, n1 = candidate_sides(c_split, c_side, free, sizes, anchors)
        for m, (k, cut, a, b) in enumerate(zip(c_split.tolist(), c_cut.tolist(), n0.tolist(), n1.tolist())):
            cands[k].append((cut, s0[m, :a], s1[m, :b], None))
        for rule, v in zip(rules, n_valid.sum(axis=0).tolist()):
            mapping[rule]["candidates"] += cfg.reads * P
            mapping[rule]["valid"] += v
        best = best.tolist()
        for k, p in enumerate(problems):
            if not cands[k]:
                continue
            top = min(best[k])
            tol = 1e-9 * max(1.0, abs(top))
            winners = [rule for rule, rb in zip(rules, best[k]) if rb <= top + tol]
            # ties between rules (common: several rules find the same split) are
            # broken at random so integer win counts stay unbiased
            win = winners[int(rng.integers(len(winners)))] if len(winners) > 1 else winners[0]
            mapping[win]["wins"] += 1
            c = cands[k]
            order = sorted(range(len(c)), key=lambda i: (-c[i][0], i))
            p.cands = [c[i] for i in order]

    def _solve(self, dist, R, problems, rng, stats) -> None:
        """One chip submission for every mapped program of ``problems``.

        Each split's reduced QUBO is converted to Ising form and mapped by
        every quantization rule; :func:`ising_backend.run_portfolio_batch`
        block-packs all programs of the stage into as few chip programs as fit
        (first-fit decreasing, ``pack=True``), dispatches them in one
        ``anneal_batch``, decodes, filters and scores each split's candidates
        on the unquantized cut (objective ``-cut``: lower is better).
        """
        if max(len(p.free) for p in problems) <= self.chip.spec.n_spins:
            return self._solve_packed(dist, R, problems, rng, stats)
        models = [ising_from_qubo(p.q, p.Q, p.offset) for p in problems]
        if max(len(p.free) for p in problems) > self.chip.spec.n_spins:
            # spin-budget branching: freeze the excess spins, 2^k reduced programs per rule
            mappings = [BranchMapping(None, QuantizeMapping(rule), name=rule) for rule in self.config.rules]
        else:
            mappings = [QuantizeMapping(rule) for rule in self.config.rules]

        def decoder(p):
            return lambda spins: decode_split(p, spins)

        found: list[dict] = [{} for _ in problems]  # distinct valid partitions per split

        def validator(k, p):
            def check(cand) -> bool:
                ok = self._valid(R, cand[0], cand[1], p.kind)
                if ok:
                    found[k].setdefault(cand[1].tobytes(), cand)
                return ok

            return check

        def objective(cand):
            return -cut_value(dist, cand[0], cand[1])

        try:
            results = run_portfolio_batch(
                models,
                mappings,
                self._meter,
                decode=[decoder(p) for p in problems],
                is_valid=[validator(k, p) for k, p in enumerate(problems)],
                objective=objective,
                num_reads=self.config.reads,
                seed=int(rng.integers(2**63 - 1)),
                pack=True,
            )
        except SolverOutputError as exc:  # a broken chip: nothing to decode
            raise SharingFailure(f"the chip returned malformed samples: {exc}") from exc
        except ChipProgramError as exc:  # a mapped program the chip cannot take: a clear failure
            raise SharingFailure(f"the chip refused a mapped split program: {exc}") from exc
        mapping = stats["mapping"]["sharing"]
        for k, (p, res) in enumerate(zip(problems, results)):
            for rule in self.config.rules:
                out = res.outcomes[rule]
                mapping[rule]["candidates"] += int(out.reads)
                mapping[rule]["valid"] += int(out.valid)
            if res.best is None:
                continue
            winners = [rule for rule in self.config.rules if res.outcomes[rule].win > 0]
            # ties between rules (common: several rules find the same split) are
            # broken at random so integer win counts stay unbiased
            win = winners[int(rng.integers(len(winners)))] if len(winners) > 1 else winners[0]
            mapping[win]["wins"] += 1
            cands = [(cut_value(dist, c[0], c[1]), c[0], c[1], None) for c in found[k].values()]
            order = sorted(range(len(cands)), key=lambda i: (-cands[i][0], i))
            p.cands = [cands[i] for i in order]


class PaperIsingSharing(IsingSharing):
    """:class:`IsingSharing` with the paper's configuration (:meth:`SharingConfig.paper`)."""

    name = "ising-paper"
    defaults = SharingConfig.paper()
