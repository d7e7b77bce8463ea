"""The chip submissions of Ising target sharing (paper 5.3): a stage's splits on the chip.

Every split of a stage x every quantization rule of the portfolio goes into one chip submission:
mapped at once, block-packed first-fit decreasing into shared chip programs, every read decoded,
checked and scored on the unquantized cut; each distinct valid partition becomes a candidate,
best cut first.  Splits beyond the chip take spin-budget branching through
:func:`ising_backend.run_portfolio_batch`.  Splits with no valid candidate are re-submitted up to
``retries`` times; then the sharing fails (:class:`~.bundles.SharingFailure`).
"""

from __future__ import annotations

import numpy as np

from ising_backend import (
    QUANTIZE_RULE_IDS, BranchMapping, ChipProgramError, MachineLink, QuantizeMapping, SolverOutputError,
    ising_from_qubo, run_portfolio_batch,
)
from planners.ising.sharing.bundles import SharingFailure
from planners.ising.sharing.engine import STAGE_NONFINITE, STAGE_OK, run_stage
from planners.ising.sharing.qubo import cut_value, decode_split

__all__ = ["StageSolver", "stage_refusal"]


def stage_refusal(status: int) -> str:
    """The failure of a stage :func:`.engine.run_stage` would not submit (its ``status``)."""
    if status == STAGE_NONFINITE:
        return "a split program could not be quantized: a coefficient is not finite (distances too large to add)"
    return "the chip refused a mapped split program: a quantized coefficient is outside the chip's range"


class StageSolver:
    """:class:`~planners.ising.sharing.IsingSharing`'s chip side, a component: ``StageSolver(config,
    chip)``; ``meter`` is the running sharing call's :class:`ising_backend.MeteredSolver`."""

    def __init__(self, config, chip):
        self.config = config
        self.chip = chip
        self.rule_ids = np.array([QUANTIZE_RULE_IDS[r] for r in config.rules], dtype=np.int64)
        self.limits = tuple(float(v) for v in chip.spec.coefficient_limits)
        # how a stage's compiled call (.engine.run_stage) reaches the chip: any machine
        self.link = MachineLink(chip)
        self.kernel_args = self.link.kernel_args
        self.meter = None

    def capacity(self) -> int:
        """Spins per packed program: the chip's, or those clear of the stuck spins a faulty chip's
        health probe found (the emulator's kernel runs only on healthy chips)."""
        if self.link.direct:
            return int(self.chip.spec.n_spins)
        return int(getattr(self.chip, "usable_spins", self.chip.spec.n_spins))

    def solve_all(self, w, R, pending, rng, stats) -> None:
        """Solve ``pending`` split problems on the chip, re-submitting those without a valid
        candidate up to ``retries`` times; still none is a :class:`SharingFailure`."""
        attempts = 0
        while pending:
            self.solve(w, R, pending, rng, stats)
            failed = [p for p in pending if not p.cands]
            if failed and attempts >= self.config.retries:
                p = failed[0]
                raise SharingFailure(
                    f"every chip candidate for the split of group {p.nodes.tolist()} was invalid "
                    f"after {attempts + 1} submissions"
                )
            attempts += 1
            pending = failed

    def valid(self, R, side0, side1, kind) -> bool:
        if self.config.reject_empty_robot_side and kind == "robots":
            for side in (side0, side1):
                if (side < R).any() and not (side >= R).any():
                    return False
        return True

    def solve_packed(self, w, R, problems, rng, stats) -> None:
        """The submission of :meth:`solve` for splits that fit the chip: every split x quantization
        rule mapped, block-packed first-fit decreasing into one submission, every read decoded,
        checked and scored on the unquantized cut -- in one compiled call
        (:func:`.engine.run_stage`, on any machine); each distinct valid partition becomes a
        candidate."""
        cfg = self.config
        seed = int(rng.integers(2**63 - 1))
        rules = cfg.rules
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
        anchors = np.array([(p.a, p.b) for p in problems], dtype=np.int64)
        reject = np.array([cfg.reject_empty_robot_side and p.kind == "robots" for p in problems])
        self.link.charged = self.meter.charged
        try:
            out = run_stage(q, Q, sizes, self.rule_ids, *self.limits, self.capacity(), cfg.reads,
                            np.uint64(seed), *self.kernel_args, free, anchors, w, R, reject)
        except SolverOutputError as exc:  # a broken machine behind the callback: nothing to decode
            raise SharingFailure(f"the chip returned malformed samples: {exc}") from exc
        except ChipProgramError as exc:
            raise SharingFailure(f"the chip refused a mapped split program: {exc}") from exc
        if out[0] != STAGE_OK:
            raise SharingFailure(stage_refusal(out[0]))
        self.link.settle([out[1]], [out[2]], self.meter.charged)
        n_valid, best, c_split, c_cut, s0, n0, s1, n1 = out[3:]
        mapping = stats["mapping"]["sharing"]
        cands: list = [[] for _ in problems]
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

    def solve(self, dist, R, problems, rng, stats) -> None:
        """One chip submission for every mapped program of ``problems``.

        Each split's reduced QUBO is converted to Ising form and mapped by
        every quantization rule; :func:`ising_backend.run_portfolio_batch`
        block-packs all programs of the stage into as few chip programs as fit
        (first-fit decreasing, ``pack=True``), dispatches them in one
        ``anneal_batch``, decodes, filters and scores each split's candidates
        on the unquantized cut (objective ``-cut``: lower is better).
        """
        if max(len(p.free) for p in problems) <= self.chip.spec.n_spins:
            return self.solve_packed(dist, R, problems, rng, stats)
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
                ok = self.valid(R, cand[0], cand[1], p.kind)
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
                self.meter,
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
