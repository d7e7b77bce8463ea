"""Recursive Ising target sharing: the search of paper 5.3 (Algorithm 3).

Contract: ``IsingSharing(chip, config).assign(dist, n_robots, tour, rng) -> SharingResult``;
a split that never decodes valid, a group beyond the spin budget or a refused
program is a failure result (``result.failure``), never an invented split.
Stages split every group with several robots, then refine one-robot groups and
bundles; each stage's splits x quantization rules are block-packed into one chip
submission (:mod:`.submit`), decoded and scored on the unquantized cut; a beam of
distinct candidates is carried to the complete assignments, which are compared by
route cost.  Then, beyond the paper (``pair_rounds``, 0 in ``PaperIsingSharing``), the
boundaries between neighbouring robots are re-split on the chip (:mod:`.boundary`).
Chip calls are metered
(:class:`ising_backend.MeteredSolver`); a chip that cannot answer hands the call to
SSA (flagged; :mod:`planners.ising.fallback`).  Choices and measurements: docs/design/ising_sharing.md.
"""

from __future__ import annotations

import numpy as np

from ising_backend import ChipProgramError, ChipUnavailableError, MachineLink, MeteredSolver, SolverOutputError
from planners.base import SharingResult, TourSolver
from planners.compute import ComputeReport
from planners.tours_classical import MAX_BRUTE_TARGETS
from planners.ising.config import ConfigAttributes, resolve_config
from planners.ising.fallback import counted, flag, unavailable_message, wants_fallback
from planners.ising.sharing.boundary import BoundaryRefinement
from planners.ising.sharing.bundles import BundlePricer, SharingFailure, assign_bundles
from planners.ising.sharing.coarse import CoarseSplit, CoarseSplits
from planners.ising.sharing.compiled_assign import ORDER_IDS, assign_kernel, pair_mean
from planners.ising.sharing.compiled_stages import COUNTERS, FAILED_SPLIT, REFUSED_STAGE
from planners.ising.sharing.components import Components
from planners.ising.sharing.config import SharingConfig
from planners.ising.sharing.kernels import split_model
from planners.ising.sharing.qubo import SplitProblem, build_split_qubo, choose_anchors, cut_value, decode_split
from planners.ising.sharing.submit import ChipSubmission, stage_refusal

__all__ = ["IsingSharing", "PaperIsingSharing"]


class IsingSharing(ConfigAttributes, ChipSubmission, Components, CoarseSplits, BoundaryRefinement):
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
        from ising_backend import ChipSpec, EmulatedChip, as_machine

        self.config = resolve_config(SharingConfig, config, options, self.defaults)
        self.chip = EmulatedChip(ChipSpec()) if chip is None else as_machine(chip)
        from ising_backend import QUANTIZE_RULE_IDS

        spec = self.chip.spec
        self._rule_ids = np.array([QUANTIZE_RULE_IDS[r] for r in self.config.rules], dtype=np.int64)
        self._limits = tuple(float(v) for v in spec.coefficient_limits)
        self._powered_for = None  # (dist, dist ** weight_power, its mean) of the running call
        # how a stage's compiled call (.engine.run_stage) reaches the chip: any machine
        self._link = MachineLink(self.chip)
        self._kernel_args = self._link.kernel_args
        cfg = self.config
        # the arguments of the whole sharing in one compiled call (.compiled_assign), where it applies
        self._compiled = None
        if not cfg.balance and cfg.pricing_tour == "auto":
            chip_args = (self._rule_ids, *self._limits, int(spec.n_spins), int(spec.n_spins), cfg.reads,
                         *self._kernel_args)
            opts = (cfg.beam, cfg.refine_beam, cfg.max_states, cfg.refine_stages, cfg.resolved_base_max,
                    cfg.refine_above, int(cfg.reject_empty_robot_side))
            pair_opts = (ORDER_IDS[cfg.bundle_order], cfg.pair_rounds, cfg.pair_neighbours)
            self._compiled = (chip_args, cfg.retries, int(spec.n_spins) + cfg.max_frozen, opts,
                              (cfg.weight_shift, cfg.robot_weight), np.array(cfg.pair_shifts), pair_opts)

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
        self._powered_for = None  # a new call: the split weights' base is recomputed
        pricer = None
        self._memo: dict = {}
        try:
            if self._compiled is not None and N <= MAX_BRUTE_TARGETS and R + N <= 62 \
                    and R + N - 2 <= self.chip.spec.n_spins:  # every group fits one program
                return self._assign_compiled(dist, R, rng, stats)
            pricer = BundlePricer(dist, tour, self.config.pricing_tour, rng, stats)
            cost = pricer.cost
            states = self._split_all(self.split_weights(dist, R), R, rng, stats)
            best = None
            for groups in states:
                sets = assign_bundles(dist, R, groups, pricer, self.config.bundle_order, stats)
                if len(states) == 1:
                    best = (0.0, sets)
                    break
                total = 0.0
                for k in range(R):  # left to right, as the compiled search sums
                    total += cost(k, sets[k])
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
            compute = ComputeReport.from_ledger(self._meter.charged)
            if pricer is not None:
                compute = compute + pricer.compute
            if wants_fallback(self.config.fallback, unavailable):  # SSA, the strong pipeline's sharing
                from planners.sharing_classical import SSASharing

                res = SSASharing().assign(dist, R, tour, rng)
                return SharingResult(assignment=res.assignment, compute=counted(compute, res.compute),
                                     stats=flag(stats, "sharing", reason))
            return SharingResult(assignment=empty, compute=compute, stats=stats, failure=reason)
        return SharingResult(assignment=assignment, compute=ComputeReport.from_ledger(self._meter.charged) + pricer.compute, stats=stats)

    def _assign_compiled(self, dist, R, rng, stats) -> SharingResult | None:
        """The sharing in one compiled call (:func:`.compiled_assign.assign_kernel`), charged and
        counted as the Python search would; where it stops (a split without a valid candidate, a
        refused stage) a :class:`SharingFailure` naming it, as the Python search raises."""
        cfg = self.config
        powered, mean = self._powered(dist)
        # room for every submission: each stage (splits down to single robots, refinement, pair rounds)
        # submits at most retries + 1 times
        subs = (2 * R + cfg.refine_stages + cfg.pair_rounds * R + 2) * (cfg.retries + 1)
        book = (np.zeros((len(cfg.rules), 3), dtype=np.int64), np.zeros(len(COUNTERS), dtype=np.int64),
                np.zeros(subs, dtype=np.int64), np.zeros(subs), np.zeros(3, dtype=np.int64))
        compiled = self._compiled
        if not self._link.direct:  # programs packed clear of the stuck spins a faulty chip found
            chip = compiled[0]
            compiled = (chip[:4] + (self._capacity(),) + chip[5:], *compiled[1:])
        self._link.charged = self._meter.charged
        try:
            ok, sets = assign_kernel(dist, powered, mean, R, rng, *compiled, book)
        except SolverOutputError as exc:  # a broken machine behind the callback: nothing to decode
            raise SharingFailure(f"the chip returned malformed samples: {exc}") from exc
        except ChipProgramError as exc:
            raise SharingFailure(f"the chip refused a mapped split program: {exc}") from exc
        mapping, counters, calls, emu, failure = book
        counts = dict(zip(COUNTERS, counters.tolist()))
        n = counts.pop("submissions")
        for key in ("pair_resplits", "pair_accepted"):  # present once the refinement made them
            if not counts[key]:
                del counts[key]
        for key, value in counts.items():
            stats[key] = stats.get(key, 0) + value
        for rule, (cands, valid, wins) in zip(cfg.rules, mapping.tolist()):
            stats["mapping"]["sharing"][rule] = {"candidates": cands, "valid": valid, "wins": wins}
        self._link.settle(calls[:n], emu[:n], self._meter.charged)
        if not ok:
            raise SharingFailure(self._stopped(R, *failure.tolist()))
        assignment = tuple(tuple(t - R for t in range(len(dist)) if m >> t & 1) for m in sets.tolist())
        return SharingResult(assignment=assignment, compute=ComputeReport.from_ledger(self._meter.charged), stats=stats)

    @staticmethod
    def _stopped(R: int, code: int, what: int, submissions: int) -> str:
        """Why the compiled sharing stopped (``book[4]`` of :func:`.compiled_assign.assign_kernel`), in
        the Python search's words."""
        if code == FAILED_SPLIT:
            nodes = [t for t in range(63) if what >> t & 1]
            return f"every chip candidate for the split of group {nodes} was invalid after {submissions} submissions"
        if code == REFUSED_STAGE:
            return stage_refusal(what)
        return f"internal error: the compiled sharing met a group outside its contract (check {what})"

    def split_weights(self, dist: np.ndarray, R: int, shift: float | None = None) -> np.ndarray:
        """Edge weights ``w_ij`` of the split graph: ``dist ** weight_power`` minus
        ``shift`` (default ``weight_shift``) x its mean over node pairs, robot-target edges then
        multiplied by ``robot_weight`` (zero diagonal)."""
        w, mean = self._powered(dist)
        shift = self.config.weight_shift if shift is None else shift
        if shift:
            w = w - shift * mean
            np.fill_diagonal(w, 0.0)
        else:
            w = w.copy()  # the caller's own array: the base is cached (and may be ``dist`` itself)
        if self.config.robot_weight != 1.0:
            w[:R, R:] *= self.config.robot_weight
            w[R:, :R] *= self.config.robot_weight
        return w

    def _powered(self, dist: np.ndarray) -> tuple[np.ndarray, float]:
        """``dist ** weight_power`` and its mean over node pairs ``i < j``, kept for the last ``dist``
        (a planning call asks for the weights of several shifts)."""
        cached = self._powered_for
        if cached is not None and cached[0] is dist:
            return cached[1], cached[2]
        power = self.config.weight_power
        w = np.asarray(dist, dtype=float)
        w = w ** power if power != 1.0 else w  # x ** 1.0 is x; the weights are never changed in place
        mean = float(pair_mean(w))  # the mean over pairs i < j, numpy's bits
        self._powered_for = (dist, w, mean)
        return w, mean

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
            for sc, combo in combos:  # sc: the combo's cuts summed left to right
                chosen = dict(zip(keys, combo))
                groups: list[np.ndarray] = []
                for gi, g in enumerate(st):
                    if gi in chosen:
                        groups.extend([chosen[gi][1], chosen[gi][2]])
                    else:
                        groups.append(g)
                expanded.append((score + sc, groups))
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


class PaperIsingSharing(IsingSharing):
    """:class:`IsingSharing` with the paper's configuration (:meth:`SharingConfig.paper`)."""

    name = "ising-paper"
    defaults = SharingConfig.paper()
