"""The Ising path search (paper Algorithm 1) as a plain Python loop: the oracle of the compiled loop.

``reference_find_path(planner, world, start, goal, rng)`` makes the decisions the package's
compiled loop (``planners.ising.path.engine.run_query``) must make, one readable step at a
time: rank the local targets, map each problem with every merge style (a style that does not fit
is skipped and counted), submit the fitting programs of the ``targets_per_call`` best-ranked
targets in one ``anneal_batch`` (block-packed with ``pack``), score, draw the win, stitch.  Test
code only: the package never imports it.
"""

from __future__ import annotations

import numpy as np

from ising_backend import (
    ChipUnavailableError, MeteredSolver, SolverOutputError, ising_from_qubo, merge_error_message, merge_styles,
)
from mapping_reference import plan_packs_ref as plan_packs
from planners.fallback import unavailable_message
from planners.ising.path.decode import decode_paths
from planners.ising.path.kernels import extract_path, rank_local_targets, score_patch_samples
from planners.ising.path.qubo import PatchFrame, PatchQubo, _resolve, build_patch_qubo

__all__ = ["reference_find_path", "build_patch_qubo_reference", "cut_loops", "component_of"]


def _program(planner, comp, target):
    """``(problem, model, mapped style indices, {style: error}, per style (h, J, ptr, idx))``."""
    cfg = planner.config
    pr = build_patch_qubo(planner.frame, comp, planner.frame.n // 2, target, cfg.form, cfg.full_weights)
    if not pr.n:
        return pr, None, [], {}, []
    model = ising_from_qubo(pr.q, pr.Q, pr.offset)
    H = np.rint(model.h * cfg.chip_scale).astype(np.int64)
    C = np.rint(model.J * cfg.chip_scale).astype(np.int64)
    Lh, Lj, n_spins = planner.runner.limits
    status, err, a, n_phys, h, J, _, ptr, idx = merge_styles(H, C, planner.runner.style_ids, Lh, Lj, Lj, n_spins)
    ok = [k for k in range(len(status)) if status[k] == 0]
    errors = {k: merge_error_message(int(status[k]), err[k], H, C, a[k], Lh, Lj, n_spins, cfg.chip_scale)
              for k in range(len(status)) if status[k] != 0}
    progs = [(h[k, : n_phys[k]], J[k, : n_phys[k], : n_phys[k]], ptr[k], idx[k]) for k in ok]
    return pr, model, ok, errors, progs


def _anneal(planner, solver, programs, seed):
    """Every program's ``(reads, width)`` spins from one submission (zero-padded or block-packed)."""
    cfg = planner.config
    sizes = [len(h) for h, *_ in programs]
    if cfg.pack and len(programs) > 1:
        packs = plan_packs(sizes, planner.runner.limits[2])
    else:
        packs = [[j] for j in range(len(programs))]
    width = max(sum(sizes[j] for j in pk) for pk in packs) if cfg.pack and len(programs) > 1 else max(
        max(p[0].shape[0] for p in programs), 0)
    h = np.zeros((len(packs), width))
    J = np.zeros((len(packs), width, width))
    where = {}
    for b, pk in enumerate(packs):
        s0 = 0
        for j in pk:
            n = sizes[j]
            h[b, s0:s0 + n] = programs[j][0]
            J[b, s0:s0 + n, s0:s0 + n] = programs[j][1]
            where[j] = (b, s0)
            s0 += n
    spins, _ = solver.anneal_batch(h, J, num_reads=cfg.num_reads, seed=seed)
    return [spins[where[j][0], :, where[j][1]: where[j][1] + sizes[j]] for j in range(len(programs))]


def reference_find_path(planner, world, start, goal, rng):
    """``planner.find_path(world, start, goal, rng)`` through the Python loop."""
    from planners.base import PathResult

    grid = world.grid
    h, w = grid.shape
    s = (int(start[0]), int(start[1]))
    g = (int(goal[0]), int(goal[1]))
    for name, (r, c) in (("start", s), ("goal", g)):
        if not (0 <= r < h and 0 <= c < w):
            return PathResult(None, failure=f"{name} cell [{r}, {c}] is off the {h}x{w} grid")
        if grid[r, c]:
            return PathResult(None, failure=f"{name} cell [{r}, {c}] is an obstacle")
    field = planner.fields.goal(world, g)
    return _search(planner, grid, s, g, rng, field)


def _search(planner, grid, s, g, rng, field):
    fr = planner.frame
    cfg = planner.config
    rad = fr.radius
    offsets = fr.offsets
    padded = planner.runner.padded(grid)
    solver = MeteredSolver(planner.chip)
    styles = cfg.styles
    mapping = {st: {"programs": 0, "reads": 0, "valid": 0, "wins": 0, "map_errors": 0} for st in styles}
    counts = {"patch_solves": 0, "anneal_calls": 0, "segments": 0, "backtracks": 0, "direct_moves": 0}
    max_attempts, per_target, max_calls = planner.runner.budgets(grid)
    pos, walk = s, [s]
    visited = np.zeros_like(padded)
    visited[s[0] + rad, s[1] + rad] = True
    stack, failed_at = [], {}
    failure, first_map_error = None, None
    while pos != g:
        used = solver.charged.physical_calls
        if counts["patch_solves"] >= max_attempts or used + per_target > max_calls:
            failure = (f"gave up at [{pos[0]}, {pos[1]}] before reaching goal [{g[0]}, {g[1]}]: budget spent "
                       f"({counts['patch_solves']} patch solves of max_attempts={max_attempts}, "
                       f"{used} chip calls of max_chip_calls={max_calls})")
            break
        excluded = visited.copy()
        for (r, c) in failed_at.get(pos, []):
            excluded[r + rad, c + rad] = True
        comp, ranked = rank_local_targets(padded, pos[0], pos[1], g[0], g[1], fr.size, planner.runner.nbr, fr.ring,
                                          excluded, cfg.interior_targets, cfg.target_order == "merged", field)
        if len(ranked) == 0:
            if cfg.backtrack and stack:
                seg = stack.pop()
                walk.extend(reversed(seg[:-1]))
                pos = seg[0]
                counts["backtracks"] += 1
                continue
            failure = (f"no path found from [{s[0]}, {s[1]}] to [{g[0]}, {g[1]}]: every local target "
                       f"reachable from [{pos[0]}, {pos[1]}] was visited or failed"
                       + (" and backtracking is exhausted" if cfg.backtrack else " (backtrack=False)")
                       + " (the goal may be unreachable)")
            break
        room = min(max(1, (max_calls - used) // per_target), max_attempts - counts["patch_solves"])
        batch = [int(li) for li in ranked[: min(cfg.targets_per_call, room)]]
        problems = [_program(planner, comp, li) for li in batch]
        for pr, _m, _ok, errors, _p in problems:
            if pr.n:
                for k, msg in errors.items():
                    mapping[styles[k]]["map_errors"] += 1
                    first_map_error = first_map_error or f"{styles[k]}: {msg}"
        on_chip = [b for b, p in enumerate(problems) if p[0].n and p[2]]
        spins = []
        if on_chip:
            seed = int(rng.integers(0, 2**63 - 1))
            try:
                spins = _anneal(planner, solver, [prog for b in on_chip for prog in problems[b][4]], seed)
            except SolverOutputError as exc:
                failure = f"the chip returned malformed samples: {exc}"
                break
            except ChipUnavailableError as exc:
                failure = unavailable_message(exc)
                counts["chip_unavailable"] = 1
                break
            counts["anneal_calls"] += 1
            counts["patch_solves"] += len(on_chip)
        chosen, direct, at, chosen_b = None, False, 0, 0
        for b, (pr, model, ok, _errors, progs) in enumerate(problems):
            if pr.n == 0:
                if chosen is None:
                    path = decode_paths(fr, pr, np.zeros((1, 0)))[0]
                    if path is not None:
                        chosen, direct, chosen_b = path, True, b
                continue
            if not ok:
                continue
            width = max(x.shape[1] for x in spins[at: at + len(ok)])
            sp = np.zeros((len(ok), cfg.num_reads, width), dtype=np.int8)
            for q, x in enumerate(spins[at: at + len(ok)]):
                sp[q, :, : x.shape[1]] = x
            ptr = np.stack([p[2] for p in progs])
            idx = np.zeros((len(ok), max(len(p[3]) for p in progs)), dtype=np.int64)
            for q, p in enumerate(progs):
                idx[q, : len(p[3])] = p[3]
            at += len(ok)
            n_valid, best, energy, logical = score_patch_samples(sp, ptr, idx, pr.n, pr.cells, pr.start, pr.goal,
                                                                 planner.runner.nbr, model.h, model.J, model.offset)
            for q, k in enumerate(ok):
                mapping[styles[k]]["programs"] += 1
                mapping[styles[k]]["reads"] += cfg.num_reads
                mapping[styles[k]]["valid"] += int(n_valid[q])
            if chosen is None and np.isfinite(energy).any():
                top = float(energy.min())
                q = int(np.argmin(energy))
                tol = 1e-9 * max(1.0, abs(top))
                winners = [ok[v] for v in range(len(ok)) if energy[v] <= top + tol]
                chosen = extract_path(logical[q, best[q]] > 0, pr.cells, pr.start, pr.goal, planner.runner.nbr).tolist()
                chosen_b = b
                win = winners[int(rng.integers(len(winners)))] if len(winners) > 1 else winners[0]
                mapping[styles[win]]["wins"] += 1
        for li in batch[: len(batch) if chosen is None else chosen_b]:  # ranked before the chosen one: failed
            failed_at.setdefault(pos, []).append((pos[0] + int(offsets[li, 0]), pos[1] + int(offsets[li, 1])))
        if chosen is None:
            continue
        if direct:
            counts["direct_moves"] += 1
        seg = [(pos[0] + int(offsets[i, 0]), pos[1] + int(offsets[i, 1])) for i in chosen]
        if g in seg:  # the segment passes the goal: the robot stops there
            seg = seg[: seg.index(g) + 1]
        walk.extend(seg[1:])
        for (r, c) in seg:
            visited[r + rad, c + rad] = True
        stack.append(seg)
        counts["segments"] += 1
        pos = seg[-1]
    return planner.runner.finish(grid, s, g, walk, counts, mapping, solver.charged, failure, first_map_error)


def _add_form(q: np.ndarray, W: np.ndarray, M: np.ndarray, scale: float) -> None:
    """Add ``scale * x^T M x`` (``M`` symmetric) to (linear ``q``, symmetric pair matrix ``W``).

    Pair convention: energy = ``q @ x + sum_{i<j} W[i, j] x_i x_j``.
    """
    q += scale * np.diag(M)
    off = M - np.diag(np.diag(M))
    W += 2.0 * scale * off


def build_patch_qubo_reference(
    frame: PatchFrame,
    allowed: np.ndarray,
    start: int,
    goal: int,
    form: str = "pair",
    weights: dict | None = None,
) -> PatchQubo:
    """:func:`planners.ising.path.qubo.build_patch_qubo` in plain numpy (the compiled builder's oracle)."""
    w, allowed = _resolve(form, weights, allowed, start, goal)
    n = frame.n
    A4 = (frame.adj4 & allowed[:, None] & allowed[None, :]).astype(np.float64)
    q = np.zeros(n)
    W = np.zeros((n, n))
    pinned = np.zeros(n, dtype=bool)
    pinned[[start, goal]] = True
    free_var = allowed & ~pinned
    if form == "pair":
        DG = (frame.diag & allowed[:, None] & allowed[None, :]).astype(np.float64)
        W += -w["C"] * A4 + w["Dg"] * DG
        q += w["B"] * free_var
        # endpoint terms: A_end * (deg(e) - 1)^2 for each pinned endpoint e
        for e in (start, goal):
            a = A4[e]
            _add_form(q, W, np.outer(a, a), w["A_end"])
            q += -2.0 * w["A_end"] * a
        offset = 2.0 * w["A_end"]
    else:  # degree form: A_end*E_end + A*sum_i (d_i - 2 x_i)^2 + B*sum x
        D = A4 * free_var[:, None]  # rows: free variable cells i, columns: their neighbours
        _add_form(q, W, D.T @ D, w["A"])  # sum_i d_i^2
        K = D  # -4 x_i d_i
        W += -4.0 * w["A"] * (K + K.T)
        q += 4.0 * w["A"] * free_var + w["B"] * free_var
        for e in (start, goal):
            a = A4[e]
            _add_form(q, W, np.outer(a, a), w["A_end"])
            q += -2.0 * w["A_end"] * a
        offset = 2.0 * w["A_end"]
    np.fill_diagonal(W, 0.0)
    var = np.flatnonzero(free_var)
    pins = np.array([start, goal])
    # substitute x_pin = 1
    qv = q[var] + W[np.ix_(var, pins)].sum(axis=1)
    offset += q[pins].sum() + W[start, goal]
    Qv = np.triu(W[np.ix_(var, var)], k=1)
    for a in (var, qv, Qv):
        a.setflags(write=False)
    return PatchQubo(var, qv, Qv, float(offset), int(start), int(goal))


def cut_loops(cells: list) -> list:
    """Remove every closed loop from a walk (cells as ``(r, c)`` tuples): a simple path.

    Walking the robot's own committed walk, a revisit of cell ``c`` drops the
    cells between the two visits.  Every step of the result is a step of the
    walk, so no new move is invented (bookkeeping, not repair).
    """
    out: list = []
    where: dict = {}
    for cell in cells:
        if cell in where:
            k = where[cell]
            for dropped in out[k + 1:]:
                del where[dropped]
            del out[k + 1:]
        else:
            where[cell] = len(out)
            out.append(cell)
    return out


def component_of(frame: PatchFrame, allowed: np.ndarray, start: int) -> np.ndarray:
    """Cells of the patch 4-connected to ``start`` through ``allowed`` cells (a label, not a path)."""
    reach = np.zeros(frame.n, dtype=bool)
    if not allowed[start]:
        return reach
    reach[start] = True
    stack = [start]
    nb = frame.neighbours
    while stack:
        i = stack.pop()
        for j in nb[i]:
            if allowed[j] and not reach[j]:
                reach[j] = True
                stack.append(j)
    return reach
