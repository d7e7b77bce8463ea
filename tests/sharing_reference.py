"""The stage submission of Ising target sharing through ``anneal_batch``: the oracle of ``run_stage``.

``reference_solve_packed(sharing, w, R, problems, rng, stats)`` does what
``StageSolver.solve_packed`` does in one compiled call (``planners.ising.sharing.engine.run_stage``)
with separate calls: map every split by every rule, pack first-fit decreasing, anneal through the
metered chip, score, name refused programs.  Test code only: the package never imports it.
"""

from __future__ import annotations

import numpy as np

from ising_backend import (
    ChipProgramError, ModelError, QuantizeError, SolverOutputError, fill_packs, ising_from_qubo, plan_packs,
    quantize_stack,
)
from planners.ising.sharing.bundles import SharingFailure
from planners.ising.sharing.kernels import candidate_sides, map_stage, score_stage
from sharing_search_reference import keep_candidates, problem_arrays

__all__ = ["reference_solve_packed"]


def reference_solve_packed(self, w, R, problems, rng, stats) -> None:
    """``self.solve_packed(w, R, problems, rng, stats)`` (``self`` a ``StageSolver``) through
    :func:`_submit_checked`."""
    cfg = self.config
    seed = int(rng.integers(2**63 - 1))
    rules = cfg.rules
    P = len(problems)
    q, Q, free, sizes, anchors, reject = problem_arrays(cfg, problems)
    n_valid, best, c_split, c_cut, s0, n0, s1, n1 = _submit_checked(
        self, w, R, problems, q, Q, free, sizes, anchors, reject, seed)
    mapping = stats["mapping"]["sharing"]
    cands: list = [[] for _ in problems]
    for m, (k, cut, a, b) in enumerate(zip(c_split.tolist(), c_cut.tolist(), n0.tolist(), n1.tolist())):
        cands[k].append((cut, s0[m, :a], s1[m, :b], None))
    for rule, v in zip(rules, n_valid.sum(axis=0).tolist()):
        mapping[rule]["candidates"] += cfg.reads * P
        mapping[rule]["valid"] += v
    best = best.tolist()
    keep_candidates(problems, rules, best, cands, rng, mapping)


def _submit_checked(self, w, R, problems, q, Q, free, sizes, anchors, reject, seed):
    """The submission through ``anneal_batch``: map, pack, anneal, score; errors become
    :class:`SharingFailure`."""
    cfg = self.config
    spec = self.chip.spec
    rules = cfg.rules
    nr = len(rules)
    P = len(problems)
    status, qh, qJ = map_stage(q, Q, sizes, self.rule_ids, *self.limits)
    if status.any():  # a non-finite quantized coefficient: the checked path names it
        for p in problems:
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
        spins, _ = self.meter.anneal_batch(h, J, num_reads=cfg.reads, seed=seed)
    except SolverOutputError as exc:  # a broken chip: nothing to decode
        raise SharingFailure(f"the chip returned malformed samples: {exc}") from exc
    except ChipProgramError as exc:  # a mapped program the chip cannot take: a clear failure
        raise SharingFailure(f"the chip refused a mapped split program: {exc}") from exc
    nfix, fixed = np.zeros(P, dtype=np.int64), np.zeros(free.shape, dtype=np.int8)  # splits that fit: no branch
    n_valid, best, c_split, c_cut, c_side = score_stage(spins, where, sizes, nr, free, anchors, w, R, reject, nfix,
                                                        fixed)
    s0, n0, s1, n1 = candidate_sides(c_split, c_side, free, sizes, anchors)
    return n_valid, best, c_split, c_cut, s0, n0, s1, n1
