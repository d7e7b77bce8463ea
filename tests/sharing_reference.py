"""The stage submission of Ising target sharing through ``anneal_batch``: the oracle of ``submit_stage``.

``reference_solve_packed(sharing, w, R, problems, rng, stats)`` does what
``StageSolver.solve_packed`` does in one submission (``planners.ising.sharing.stage_steps.submit_stage``)
with separate calls: map every split by every rule, pack first-fit decreasing, anneal through the
metered chip, score, name refused programs.  The mapping (``ising_backend``'s public
``ising_from_qubo`` and ``quantize_stack``, one split at a time), the decoding, the validity rule and
the scoring of the reads are written here, independently of the compiled steps
(``ising_backend.pack_qubo_stack``, ``planners.ising.sharing.split_problem``' ``score_stage`` and
``candidate_sides``).  Test code only: the package never imports it.
"""

from __future__ import annotations

import numpy as np

from ising_backend import (
    ChipProgramError, ModelError, QuantizeError, SolverOutputError, fill_packs, ising_from_qubo, quantize_stack,
)
from mapping_reference import plan_packs_ref as plan_packs
from planners.ising.sharing.bundles import SharingFailure
from sharing_search_reference import cut_value, decode_split, keep_candidates

__all__ = ["reference_solve_packed"]


def reference_solve_packed(self, w, R, problems, rng, stats) -> None:
    """``self.solve_packed(w, R, problems, rng, stats)`` (``self`` a ``StageSolver``) through
    :func:`_submit_checked`."""
    cfg = self.config
    seed = int(rng.integers(2**63 - 1))
    rules = cfg.rules
    P = len(problems)
    n_valid, best, cands = _submit_checked(self, w, R, problems, seed)
    mapping = stats["mapping"]["sharing"]
    for rule, v in zip(rules, n_valid.sum(axis=0).tolist()):
        mapping[rule]["programs"] += P
        mapping[rule]["reads"] += cfg.reads * P
        mapping[rule]["valid"] += v
    keep_candidates(problems, rules, best.tolist(), cands, rng, mapping)


def _map_programs(self, problems) -> list:
    """Every split's program under every rule (row ``p * rules + r``): its QUBO in Ising form, quantized
    into the chip's ranges; a split that cannot be quantized is a :class:`SharingFailure`."""
    spec = self.chip.spec
    programs = []
    for p in problems:
        try:
            h, J = quantize_stack(ising_from_qubo(p.q, p.Q, p.offset), self.config.rules, spec.h_range, spec.j_range)
        except (QuantizeError, ModelError) as exc:
            raise SharingFailure(f"a split program could not be quantized: {exc}") from exc
        programs.extend(zip(h, J))
    return programs


def _valid(side0, side1, R: int, reject_empty_robot_side: bool) -> bool:
    """The validity rule: with ``reject_empty_robot_side`` no side may hold robots but no target."""
    if not reject_empty_robot_side:
        return True
    return not any(len(side) and all(v < R for v in side) for side in (side0, side1))


def _submit_checked(self, w, R, problems, seed):
    """The submission through ``anneal_batch``: map, pack, anneal, then score every read.  Returns
    ``(n_valid (P, rules), best (P, rules): the best -cut of each rule's valid reads (inf: none), cands)``,
    ``cands[p]`` the split's distinct valid partitions ``(cut, side0, side1, None)`` in first-read order
    (rule by rule, read by read).  Errors become :class:`SharingFailure`."""
    cfg = self.config
    spec = self.chip.spec
    rules = cfg.rules
    nr = len(rules)
    P = len(problems)
    programs = _map_programs(self, problems)
    prog_sizes = np.array([len(h) for h, _ in programs], dtype=np.int64)
    f = int(prog_sizes.max())
    qh, qJ = np.zeros((len(programs), f)), np.zeros((len(programs), f, f))
    for j, (h, J) in enumerate(programs):
        qh[j, :len(h)], qJ[j, :len(h), :len(h)] = h, J
    # a faulty chip's programs stay clear of the stuck spins its health probe found
    capacity = max(int(getattr(self.chip, "usable_spins", spec.n_spins)), f)
    packs = plan_packs(prog_sizes.tolist(), capacity)
    width = max(int(prog_sizes[pk].sum()) for pk in packs)
    pack_of = np.empty(len(programs), dtype=np.int64)
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
    n_valid = np.zeros((P, nr), dtype=np.int64)
    best = np.full((P, nr), np.inf)
    cands: list = [[] for _ in problems]
    for k, p in enumerate(problems):
        n = len(p.free)
        reject = cfg.reject_empty_robot_side and p.kind == "robots"
        seen = set()
        for r in range(nr):
            pack, first = where[k * nr + r]
            for t in range(cfg.reads):
                block = spins[pack, t, first:first + n]
                side0, side1 = decode_split(p, block)
                if not _valid(side0, side1, R, reject):
                    continue
                cut = cut_value(w, side0, side1)
                n_valid[k, r] += 1
                best[k, r] = min(best[k, r], -cut)
                if block.tobytes() not in seen:  # a partition already read is one candidate
                    seen.add(block.tobytes())
                    cands[k].append((cut, side0, side1, None))
    return n_valid, best, cands
