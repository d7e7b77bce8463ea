"""The split stages of Ising target sharing (paper 5.3, Algorithm 3): the sharing's search component.

``SplitSearch(config, chip, stages)``: :meth:`split_all` splits every group holding several robots,
stage by stage (one chip submission per stage through ``stages``, a :class:`~.submit.StageSolver`),
then refines one-robot groups, carrying a beam of distinct candidates; a group met again reuses its
solved split (``memo``, per sharing call); a group beyond the chip is split on clusters
(:func:`~.coarse.coarse_split`).  It serves every world the compiled sharing
(:mod:`.compiled_assign`) does not take; the tests hold the two to the same decisions.
"""

from __future__ import annotations

import numpy as np

from planners.ising.sharing.bundles import SharingFailure
from planners.ising.sharing.coarse import CoarseSplit, coarse_split
from planners.ising.sharing.kernels import split_model
from planners.ising.sharing.qubo import SplitProblem, build_split_qubo, choose_anchors, cut_value, decode_split

__all__ = ["SplitSearch"]


class SplitSearch:
    """The split stages on one chip (module docstring)."""

    def __init__(self, config, chip, stages):
        self.config = config
        self.chip = chip
        self.stages = stages
        self.memo: dict = {}

    def problem(self, dist, R, nodes, kind) -> SplitProblem:
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

    def split_all(self, w, R, rng, stats) -> list[list[np.ndarray]]:
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
            problems = self.stage(w, R, [states[si][1][gi] for si, gi in todo], "robots", rng, stats)
            states = self.expand(states, todo, problems, self.config.beam)
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
            problems = self.stage(w, R, [states[si][1][gi] for si, gi in todo], "refine", rng, stats)
            states = self.expand(states, todo, problems, self.config.refine_beam)
        stats["states"] += len(states)
        return [st for _, st in states]

    def expand(self, states, todo, problems, width: int):
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

    def stage(self, w, R, groups, kind, rng, stats) -> list[SplitProblem]:
        """Solve the splits of ``groups`` (one chip submission, plus retries); each problem's
        ``cands`` lists its distinct valid candidates, best unquantized cut first.

        The same group met again (in another partial solution, or an earlier
        stage) reuses its solved split from ``self.memo`` instead of a new chip call.
        """
        memo = self.memo
        keys = [(kind, tuple(int(v) for v in np.sort(g))) for g in groups]
        fresh: dict = {}
        for key, g in zip(keys, groups):
            if key not in memo and key not in fresh:
                too_big = len(g) - 2 > int(self.chip.spec.n_spins) + self.config.max_frozen
                fresh[key] = coarse_split(self, w, R, g, kind, rng, stats) if too_big else self.problem(w, R, g, kind)
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
        self.stages.solve_all(w, R, pending, rng, stats)
        memo.update(fresh)
        return [memo[key] for key in keys]
