"""The fleet search (``ising-fleet``) as a plain Python loop over route lists: the oracle of the compiled search.

``reference_fleet(dist, r, config, chip, rng)`` makes the decisions ``IsingFleetSharing.assign`` must make:
SSA's routes, then the local search (candidate moves in the kernel's listing order, the pick, the selection
QUBO quantized by every rule, one ``anneal_batch`` per round through a metered solver, the best valid read
applied), then the kicks (``ruin_recreate``, the same draws) with record-to-record acceptance.  Routes are
lists of nodes here; gains are route costs before minus after (exact, and so the kernel's bits, on the
integer BFS distances the tests use); spans, clashes, the pick, the QUBO and the scoring are computed here,
independently of ``planners.ising.moves`` (kinds, granular neighbourhood, search) and ``planners.ising.moves.selection``.  Test code only.
"""

from __future__ import annotations

import numpy as np

from ising_backend import MeteredSolver, ising_from_qubo, quantize_stack
from planners.ising.fleet.recreate import ruin_recreate
from planners.sharing_classical import SSASharing

__all__ = ["reference_fleet"]


def _cost(d, routes) -> float:
    return sum(float(d[a, b]) for k, g in enumerate(routes) for a, b in zip([k] + g[:-1], g))


def _where(routes, r):
    """``owner``, ``pos`` of every node (robot ``k`` at position 0 of route ``k``)."""
    owner, pos = {}, {}
    for k, g in enumerate(routes):
        owner[k], pos[k] = k, 0
        for i, x in enumerate(g):
            owner[x], pos[x] = k, i + 1
    return owner, pos


def _moved(routes, r, move):
    """A copy of ``routes`` with move ``(kind, a, b)`` applied by node."""
    kind, a, b = move
    out = [list(g) for g in routes]
    owner, pos = _where(routes, r)

    def place(x):  # (route, index in its list) of a target; a robot's "index" is -1
        return owner[x], pos[x] - 1

    if kind == 0:  # relocate a right after b
        ka, ia = place(a)
        del out[ka][ia]
        kb = owner[b]
        ib = -1 if b < r else out[kb].index(b)
        out[kb].insert(ib + 1, a)
    elif kind == 1:  # swap a and b
        (ka, ia), (kb, ib) = place(a), place(b)
        out[ka][ia], out[kb][ib] = b, a
    elif kind == 2:  # the tails after a and after b swap
        (ka, ia), (kb, ib) = place(a), place(b)
        ta, tb = out[ka][ia + 1:], out[kb][ib + 1:]
        out[ka] = out[ka][:ia + 1] + tb
        out[kb] = out[kb][:ib + 1] + ta
    else:  # reverse the segment after a up to b
        (k, ia), (_, ib) = place(a), place(b)
        out[k][ia + 1:ib + 1] = out[k][ia + 1:ib + 1][::-1]
    return out


def _candidates(d, routes, r, neigh):
    """Improving moves ``(kind, a, b)``, their spans ``((route, lo, hi), (route, lo, hi) or None)`` and
    gains, in the kernel's listing order."""
    owner, pos = _where(routes, r)
    length = [len(g) for g in routes]
    nxt = {}
    prv = {}
    for k, g in enumerate(routes):
        chain = [k] + g
        for x, y in zip(chain[:-1], chain[1:]):
            nxt[x], prv[y] = y, x
    before = _cost(d, routes)
    moves, spans, gains = [], [], []

    def offer(move, s1, s2):
        gain = before - _cost(d, _moved(routes, r, move))
        if gain > 1e-9 and np.isfinite(gain):
            if s2 is not None and s1[0] == s2[0]:
                s1, s2 = (s1[0], min(s1[1], s2[1]), max(s1[2], s2[2])), None
            moves.append(move)
            spans.append((s1, s2))
            gains.append(gain)

    for u in range(r, d.shape[0]):
        pu, ou = prv[u], owner[u]
        for v in neigh[u]:
            v = int(v)
            if v < 0 or v == u:
                continue
            for side in range(2):
                w = v if side == 0 else (prv[v] if v >= r else -1)
                if w < 0 or w == pu or w == u or nxt.get(w, -1) == u:
                    continue
                offer((0, u, w), (ou, pos[u] - 1, pos[u]), (owner[w], pos[w], pos[w]))
            if v < r:
                continue
            ov = owner[v]
            if ov != ou:
                offer((1, u, v), (ou, pos[u] - 1, pos[u]), (ov, pos[v] - 1, pos[v]))
                b = prv[v]
                offer((2, u, b), (ou, pos[u], length[ou]), (ov, pos[b], length[ov]))
            else:
                a, b = (u, v) if pos[u] < pos[v] else (v, u)
                if pos[b] > pos[a] + 1:
                    offer((3, a, b), (ou, pos[a], pos[b]), None)
    return moves, spans, np.array(gains, dtype=np.float64)


def _clash(s, t) -> bool:
    return any(x is not None and y is not None and x[0] == y[0] and x[1] <= y[2] and y[1] <= x[2]
               for x in s for y in t)


def _round(d, routes, r, neigh, cfg, chip, rng, capacity, stats):
    """One round: the routes after the chip's best valid read (``None``: no valid read selects a move)."""
    moves, spans, gains = _candidates(d, routes, r, neigh)
    if not moves:
        return "optimum"
    keep: list[int] = []
    for m in sorted(range(len(gains)), key=lambda i: (-gains[i], i)):
        if len(keep) == capacity:
            break
        if sum(_clash(spans[m], spans[o]) for o in keep) <= cfg.max_overlap:
            keep.append(m)
    K = len(keep)
    clash = np.array([[a != b and _clash(spans[keep[a]], spans[keep[b]]) for b in range(K)] for a in range(K)])
    g = gains[keep]
    Q = np.triu(np.where(clash, np.minimum(g[:, None], g[None, :]) + 1.0, 0.0), k=1)
    h, J = quantize_stack(ising_from_qubo(-g, Q), cfg.chip_rules, chip.spec.h_range, chip.spec.j_range)
    spins, _ = chip.anneal_batch(h, J, num_reads=cfg.num_reads, seed=int(rng.integers(0, 2**63 - 1)))
    stats["rounds"] += 1
    best, taken = 0.0, None
    for p in range(spins.shape[0]):
        for rd in range(spins.shape[1]):
            chosen = [a for a in range(K) if spins[p, rd, a] > 0]
            if any(clash[a, b] for i, a in enumerate(chosen) for b in chosen[:i]):
                continue
            total = sum(float(g[a]) for a in chosen)
            if total > best + 1e-9:
                best, taken = total, chosen
    if taken is None:
        return None
    for a in taken:
        routes = _moved(routes, r, moves[keep[a]])
    return routes


def _local_search(d, routes, r, neigh, cfg, chip, rng, stats):
    capacity = min(int(chip.usable_spins), cfg.max_moves)
    failures = 0
    while True:
        new = _round(d, routes, r, neigh, cfg, chip, rng, max(1, capacity >> failures), stats)
        if isinstance(new, str):
            return routes
        if new is None:
            failures += 1
            if failures > cfg.max_retries:
                return routes
            continue
        failures = 0
        routes = new


def _linked(routes, r, m):
    nxt, prv = np.full(m, -1, dtype=np.int64), np.full(m, -1, dtype=np.int64)
    for k, g in enumerate(routes):
        x = k
        for t in g:
            nxt[x], prv[t] = t, x
            x = t
    return nxt, prv


def _lists(nxt, r):
    out = []
    for k in range(r):
        g, x = [], int(nxt[k])
        while x >= 0:
            g.append(x)
            x = int(nxt[x])
        out.append(g)
    return out


def reference_fleet(dist, r, cfg, chip, rng):
    """``(groups, stats)``: the routes (target indices per robot) ``IsingFleetSharing(chip, cfg)`` must
    return for ``rng``, and the rounds it ran (module docstring)."""
    d = np.asarray(dist, dtype=np.float64)
    m = d.shape[0]
    n = m - r
    metered = MeteredSolver(chip, decision="fleet_moves")
    routes = [[r + t for t in g] for g in SSASharing().assign(dist, r).assignment]
    order = np.argsort(d[r:], axis=1, kind="stable")
    k = min(cfg.neighbours, m - 1)
    neigh = np.vstack([np.full((r, k), -1), order[:, 1:k + 1]])
    stats = {"rounds": 0}
    routes = _local_search(d, routes, r, neigh, cfg, metered, rng, stats)
    best, best_cost = routes, _cost(d, routes)
    ruin = max(2, cfg.ruin or max(5, 2 * n // r))
    for _ in range(cfg.kicks):
        nxt, prv = _linked(routes, r, m)
        seed_target = r + int(rng.integers(n))
        q = min(int(rng.integers(2, ruin + 1)), n)
        ruin_recreate(d, nxt, prv, r, seed_target, order[seed_target - r, 1:], q, rng.permutation(q))
        cand = _local_search(d, _lists(nxt, r), r, neigh, cfg, metered, rng, stats)
        new = _cost(d, cand)
        if new <= best_cost * (1.0 + cfg.slack) + 1e-9:
            routes = cand
            if new < best_cost - 1e-9:
                best, best_cost = cand, new
    return [tuple(x - r for x in g) for g in best], stats
