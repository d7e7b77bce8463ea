"""Patch-sliding Ising pathfinding (paper section 5.1, Algorithm 1).

The chip is the local path generator inside a receding-horizon loop; the host
places patches, ranks local targets, decodes, validates, scores and stitches.

Algorithm (one query ``find_path(world, start, goal, rng)``):

1. Centre a ``patch_size x patch_size`` patch (default 5x5) on the robot cell
   ``p``.  Only free, in-grid patch cells that are 4-connected to ``p`` inside
   the patch are modelled (a connected-component label of <= 25 cells, not a
   path: cells the robot cannot reach inside the patch could never be on a
   local path and would only waste spins).
2. Rank the local targets (paper: "by Manhattan distance to the final goal"):
   the goal itself if it is in the patch, then the patch-boundary cells
   (Chebyshev radius 2) by Manhattan distance to the goal, then, as the
   fall-back the paper leaves open, the interior cells by the same key
   (``interior_targets=True``; ``target_order="merged"`` ranks boundary and
   interior cells together).  Ties: fewer Manhattan moves from ``p``, then
   row-major order.  Cells already on the robot's committed walk, and targets
   that already failed from this position, are skipped.
3. For the best-ranked target ``g`` build the cell-based patch QUBO (eq. 6) on
   the modelled cells with ``p`` and ``g`` *pinned*: they are substituted with
   ``x = 1`` (folded into the neighbours' linear terms and the offset), not
   variables.  At most 23 variables on a 5x5 patch.
4. Map it with the four spin-merging styles (:data:`ising_backend.MERGE_STYLES`)
   and run the portfolio on the **emulated physical chip** through
   :func:`ising_backend.run_portfolio_batch`: one ``anneal_batch`` call for all
   styles (``targets_per_call`` > 1 puts several ranked targets' programs in the
   same call; every program x read is one chip call either way).
5. Decode each read (majority of merged copies, then ``x = (1 + s) / 2``); a
   candidate is valid only if the selected cells plus the endpoints form one
   simple, induced, 4-connected path from ``p`` to ``g`` (each selected cell has
   exactly two selected 4-neighbours, each endpoint one, and the walk from
   ``p`` covers all of them).  Invalid reads are rejected, never repaired.
   The best valid candidate by the **original** (unscaled, unmerged) patch
   energy is committed; equal-energy styles share one win drawn by ``rng``.
   No valid candidate: the next-ranked target (Algorithm 1's inner loop).
6. Append the segment to the walk (cut at the goal if the segment runs
   through it), move ``p`` to its end, repeat until ``p`` is the goal.

Patch QUBO (paper eq. 6, ``A E_end + A E_conn + B sum x``; weights are ours):

``form="pair"`` (default)
    ``E = -C sum_{4-nbr i~j} x_i x_j + Dg sum_{diag i~j} x_i x_j + B sum_i x_i
    + A_end sum_{e in {p, g}} (deg(e) - 1)^2`` with ``deg(e)`` the number of
    selected 4-neighbours of endpoint ``e``.  The adjacency reward is the
    connectivity term, the diagonal penalty discourages blobs and turns, ``B``
    is the length term, ``A_end`` makes each endpoint a path end.  Weights
    ``C : B : Dg : A_end = 1 : 1.375 : 0.25 : 0.5`` (:data:`DEFAULT_WEIGHTS`):
    with ``B - C = 0.375`` every extra cell costs, so among paths the shortest
    has the lowest energy; ``B > C`` makes dangling stubs and islands cost
    more than nothing; ``Dg`` and ``B`` keep 2x2 blocks above the empty
    selection.  Measured on 150 random patches (exact ground states): the
    ground state is the shortest in-patch path for every local path of <= 4
    moves -- all boundary targets of an unobstructed 5x5 patch -- but not for
    5+ moves (those targets fail and the next-ranked target is tried).  We
    tried ``B`` in 1.25..1.5, ``Dg`` 0.125..0.4, ``A_end`` 0.25..1 on the
    emulated chip: this point decodes valid most often (about 85 % of single
    reads on random boundary targets).
``form="degree"``
    ``E = A_end E_end + A sum_i (d_i - 2 x_i)^2 + B sum_i x_i``, the literal
    reading of eq. 6 with a quadratic degree penalty (``d_i`` = selected
    4-neighbours of cell ``i``, pinned cells count as selected), ``A = A_end = 1,
    B = 0.5``.  Its ground state is a valid path in only 42 % of 150 random
    patches (all 2-move targets, few longer ones) and it decodes valid on ~40 %
    of reads in the planner -- close to the paper's ~45 % per
    style -- so it is kept as the paper-like alternative.

Scale (``scale``, chip units per QUBO weight unit, :data:`DEFAULT_SCALE`).
The merge styles round ``scale x`` the Ising coefficients and then duplicate
overloaded spins (they never rescale).  For the pair form every Ising
coefficient is a multiple of 1/16, so ``scale=16`` is exact: the diagonal
penalty becomes 1, an adjacency coupling -4, and the endpoint fields exceed
+-7, which the merge styles absorb with 1-2 spare spins (the paper's
situation: "endpoint and connectivity penalties ... outside the supported
hardware range").  A smaller scale rounds small terms away (scale 8 loses 7
couplings per patch on average and decodes valid less often); a larger one
needs 5-11 copies and anneals worse.  The degree form uses ``scale=2`` (its
penalties are large; scale 4 needs ~7 copies and decodes valid on ~18 %).

Termination (the paper's loop ``while p != t`` has no guard):

* a segment may end only at a cell not yet on the walk (segments may pass
  over walked cells), and a failed (position, target) pair is never retried,
  so no committed segment ends where the robot has been and the loop cannot
  oscillate;
* when no untried local target is left at ``p`` (``backtrack=True``) the robot
  steps back along its own last committed segment (reversed, no chip call, no
  new move) and ranks again from there -- a depth-first search over segment
  ends; with nothing left to back up to, the query fails ("the goal may be
  unreachable");
* budgets: ``max_attempts`` local-target attempts (patch problems sent to the
  chip; default ``max(64, free cells)``, 80 on the paper's worlds: the
  depth-first search has at most one segment end per free cell) and
  ``max_chip_calls`` physical calls (default ``max_attempts x styles x
  reads``, 320); an attempt that would exceed either ends the query with a
  failure naming both.  On 3000 random 10x10 queries the most any query used
  was ~100 calls (26 attempts); on 20x20 worlds, 152.

Final path.  The committed walk can revisit cells (a segment may cross
earlier ones; backtracking retraces).  With ``cut_loops=True`` (default) every
closed loop is removed (:func:`cut_loops`): the result is a simple path whose
every step is a step the robot committed -- bookkeeping on its own walk, not a
repair (no new move is invented, nothing is searched).  ``cut_loops=False``
returns the raw walk (valid 4-neighbour, possibly with loops).

Failures never raise: a start/goal off the grid or on an obstacle, an
unreachable goal (the search exhausts the component), a spent budget,
malformed chip answers (wrong shape, values other than +-1), or a chip no
merge style can fit (the message quotes the first merge error) give
``PathResult(path=None, failure=...)``.  Bad constructor options raise
``ValueError`` naming the option and its limit.  Randomness comes only from ``rng``
(one chip seed per submission, tie breaks); the same seed gives the same path.

Statistics (``result.stats``, counts so they add across calls): ``chip_calls``,
``chip_batches``, ``patch_solves`` (local-target attempts sent to the chip),
``anneal_calls`` (submissions), ``segments``, ``backtracks``, ``direct_moves``
(1-move segments whose patch had no free variable, committed without the
chip), ``walk_length``, ``path_length``, and ``mapping["path"][style] =
{"programs", "valid", "wins", "map_errors"}`` (programs = reads of that style;
paper Table 5: valid rate = valid / programs, win share = wins / all wins).

Host cost: patch problems and their merged programs are memoised (LRU) per
planner, since patches recur along the legs of one world.  ``pack=True``
block-packs the portfolio's programs two to a 45-spin chip program
(:mod:`ising_backend.blocks`, the packing the paper uses for sharing): half the
calls, same decode statistics.  Off by default so that one program is one
call, as in the paper.

Measured (1000 queries, ``generate_world(q, n_robots=1, n_targets=1)``, robot
to target, default options): ``placement="centre"`` -- 1000/1000 solved, median
length 6 = BFS median 6 (93 % of paths shortest), median 8 chip calls (3.6 uJ),
valid rate ~72 % per style, win shares 24-27 %; ``placement="uniform"`` --
1000/1000, median length 7 = BFS 7 (87 % shortest), median 12 calls (5.4 uJ).
The remaining detours come from the greedy Manhattan ranking itself (an exact
local solver gives the same shortest share).  With 5 % read-out bit flips the
valid rate halves (~35 %) and the portfolio still solves 300/300 queries at
~25 % more calls.  ``benchmarks/RESULTS.md`` has the table.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

FORMS = ("pair", "degree")
TARGET_ORDERS = ("boundary_first", "merged")

#: Chip units per QUBO weight unit before the merge styles round (see the module docstring).
DEFAULT_SCALE = {"pair": 16.0, "degree": 2.0}

#: Default weights per formulation (see the module docstring for the reasons).
DEFAULT_WEIGHTS = {
    "pair": {"C": 1.0, "B": 1.375, "Dg": 0.25, "A_end": 0.5},
    "degree": {"A": 1.0, "A_end": 1.0, "B": 0.5},
}


# --------------------------------------------------------------------------- geometry
@dataclass(frozen=True)
class PatchFrame:
    """Fixed local structure of a ``size x size`` patch (cells row-major, ``size**2`` of them).

    ``adj4[i, j]``: cells i and j are 4-neighbours; ``diag[i, j]``: diagonal
    neighbours; ``ring``: cells on the patch boundary (Chebyshev radius
    ``size // 2`` from the centre); ``offsets``: ``(size**2, 2)`` offset of each
    cell from the centre.
    """

    size: int
    adj4: np.ndarray
    diag: np.ndarray
    ring: np.ndarray
    offsets: np.ndarray
    neighbours: tuple  # per cell, tuple of 4-neighbour cell indices

    @property
    def radius(self) -> int:
        return self.size // 2

    @property
    def n(self) -> int:
        return self.size * self.size


@lru_cache(maxsize=8)
def patch_frame(size: int) -> PatchFrame:
    if int(size) != size or size < 3 or size % 2 == 0:
        raise ValueError(f"patch_size must be an odd integer >= 3, got {size!r}")
    size = int(size)
    rad = size // 2
    rr, cc = np.divmod(np.arange(size * size), size)
    dr = np.abs(rr[:, None] - rr[None, :])
    dc = np.abs(cc[:, None] - cc[None, :])
    adj4 = (dr + dc) == 1
    diag = (dr == 1) & (dc == 1)
    offsets = np.stack([rr - rad, cc - rad], axis=1).astype(np.int64)
    ring = np.maximum(np.abs(offsets[:, 0]), np.abs(offsets[:, 1])) == rad
    neighbours = tuple(tuple(int(j) for j in np.flatnonzero(adj4[i])) for i in range(size * size))
    for a in (adj4, diag, ring, offsets):
        a.setflags(write=False)
    return PatchFrame(size, adj4, diag, ring, offsets, neighbours)


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


# --------------------------------------------------------------------------- QUBO
@dataclass(frozen=True)
class PatchQubo:
    """A patch problem with the two endpoints substituted (pinned, not variables).

    Energy of variable assignment ``x`` (0/1, one per entry of ``cells``):
    ``offset + q @ x + sum_{i<j} Q[i, j] x_i x_j`` (``Q`` strictly upper triangular).
    """

    cells: np.ndarray  # (n,) patch-frame indices of the variables
    q: np.ndarray  # (n,)
    Q: np.ndarray  # (n, n) strictly upper triangular
    offset: float
    start: int  # patch-frame index of the robot cell
    goal: int  # patch-frame index of the local target

    @property
    def n(self) -> int:
        return int(len(self.cells))

    def energy(self, x: np.ndarray) -> np.ndarray:
        """Original-objective energy of ``x`` (``(..., n)`` 0/1), vectorised over leading axes."""
        x = np.asarray(x, dtype=np.float64)
        return self.offset + x @ self.q + np.einsum("...i,ij,...j->...", x, self.Q, x)


def _add_form(q: np.ndarray, W: np.ndarray, M: np.ndarray, scale: float) -> None:
    """Add ``scale * x^T M x`` (``M`` symmetric) to (linear ``q``, symmetric pair matrix ``W``).

    Pair convention: energy = ``q @ x + sum_{i<j} W[i, j] x_i x_j``.
    """
    q += scale * np.diag(M)
    off = M - np.diag(np.diag(M))
    W += 2.0 * scale * off


def build_patch_qubo(
    frame: PatchFrame,
    allowed: np.ndarray,
    start: int,
    goal: int,
    form: str = "pair",
    weights: dict | None = None,
) -> PatchQubo:
    """The cell-based patch QUBO (paper eq. 6) over ``allowed`` patch cells, endpoints pinned.

    ``allowed`` (bool, ``frame.n``) marks the free patch cells that may carry the
    path; ``start`` and ``goal`` must be allowed and distinct.  The energy is
    built on the whole frame with the endpoints as ordinary 0/1 cells and then
    the endpoints are substituted with ``x = 1`` (their terms fold into the
    linear coefficients of their neighbours and into the offset).
    """
    if form not in FORMS:
        raise ValueError(f"form must be one of {FORMS}, got {form!r}")
    w = dict(DEFAULT_WEIGHTS[form])
    if weights:
        unknown = set(weights) - set(w)
        if unknown:
            raise ValueError(f"unknown weights {sorted(unknown)} for form {form!r} (known: {sorted(w)})")
        w.update(weights)
    if start == goal:
        raise ValueError("start and goal of a patch problem must differ")
    allowed = np.asarray(allowed, dtype=bool)
    if not (allowed[start] and allowed[goal]):
        raise ValueError("start and goal of a patch problem must be allowed cells")
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


# --------------------------------------------------------------------------- decode
def decode_paths(frame: PatchFrame, problem: PatchQubo, x: np.ndarray) -> list:
    """Decode 0/1 assignments ``x`` (``(S, n)``) into local paths.

    Returns, per sample, the ordered patch-frame cell indices from ``start`` to
    ``goal`` if the selected cells plus the two endpoints form exactly one
    simple 4-connected path (induced: every selected cell has exactly two
    selected 4-neighbours, each endpoint exactly one, and everything is
    reached walking from ``start``), else ``None``.
    """
    x = np.asarray(x).astype(bool)
    x = x.reshape(x.shape[0] if x.ndim > 1 else 1, problem.n)
    S = x.shape[0]
    sel = np.zeros((S, frame.n), dtype=bool)
    sel[:, problem.cells] = x
    sel[:, [problem.start, problem.goal]] = True
    deg = (sel.astype(np.int16) @ frame.adj4.astype(np.int16)) * sel
    want = np.where(sel, 2, 0)
    want[:, [problem.start, problem.goal]] = 1
    ok = (deg == want).all(axis=1)
    out: list = [None] * S
    nb = frame.neighbours
    for s in np.flatnonzero(ok):
        row = sel[s]
        path = [problem.start]
        prev, cur = -1, problem.start
        while cur != problem.goal:
            nxt = -1
            for j in nb[cur]:
                if row[j] and j != prev:
                    nxt = j
                    break
            if nxt < 0:  # cannot happen after the degree check, kept for safety
                break
            prev, cur = cur, nxt
            path.append(cur)
        if cur == problem.goal and len(path) == int(row.sum()):
            out[s] = path
    return out


# --------------------------------------------------------------------------- planner
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


class _LRU(OrderedDict):
    """A small least-recently-used cache (host-side memo of deterministic mapping work)."""

    def __init__(self, size: int):
        super().__init__()
        self.size = size

    def get_or(self, key, make):
        hit = self.get(key)
        if hit is None:
            hit = make()
            self[key] = hit
            if len(self) > self.size:
                self.popitem(last=False)
        else:
            self.move_to_end(key)
        return hit


def _cached_merge_mapping(style: str, scale: float, cache: _LRU):
    """A :class:`ising_backend.MergeMapping` whose results are memoised per logical model.

    Merging is a deterministic function of (model, style, scale, spec); patch
    problems recur (the same local obstacle pattern and local target), so the
    host maps each distinct one once.
    """
    from ising_backend import MergeMapping

    class _Cached(MergeMapping):
        def map(self, model, spec):
            key = (style, model.h.tobytes(), model.J.tobytes(), spec)
            return cache.get_or(key, lambda: MergeMapping.map(self, model, spec))

    return _Cached(style, scale=scale)


class _ChipOutputError(RuntimeError):
    """The chip's answer is not a (programs, reads, spins) array of +-1."""


class _CheckedChip:
    """Pass-through to the chip that checks the shape and values of every answer."""

    def __init__(self, chip):
        from ising_backend import CallLedger

        self.chip = chip
        self.spec = chip.spec
        self.charged = CallLedger()  # this query's share of the chip's ledger, call by call

    def anneal_batch(self, h, J, num_reads=1, seed=None):
        before = self.chip.ledger.snapshot()
        spins, energies = self.chip.anneal_batch(h, J, num_reads=num_reads, seed=seed)
        # the call's own charge (EmulatedChip.last_call) adds up exactly; a ledger difference
        # of running float totals would depend on what ran on the chip before
        last = getattr(self.chip, "last_call", None)
        self.charged = self.charged + (last if last is not None else self.chip.ledger.since(before))
        spins = np.asarray(spins)
        want = (np.shape(h)[0], num_reads, np.shape(h)[1])
        if spins.shape != want or not np.isin(spins, (-1, 1)).all():
            raise _ChipOutputError(f"got shape {spins.shape}, expected {want} spins in {{-1, +1}}")
        return spins, energies


class IsingPath:
    """Patch-sliding Ising pathfinder (paper Algorithm 1); see the module docstring.

    Args:
        chip: the :class:`ising_backend.EmulatedChip` that runs every patch
            program (default: a fresh ``EmulatedChip(ChipSpec())``).
        patch_size: side of the square patch centred on the robot (odd, >= 3).
        form: patch QUBO, ``"pair"`` (default) or ``"degree"``.
        weights: overrides of :data:`DEFAULT_WEIGHTS` ``[form]``.
        styles: spin-merging styles of the portfolio (default all of
            ``ising_backend.MERGE_STYLES``).
        num_reads: reads per mapped program (each read is one chip call).
        targets_per_call: ranked local targets whose programs share one
            anneal submission (``len(styles) * targets_per_call`` programs).
        interior_targets: after the boundary cells, fall back to interior
            patch cells as local targets.
        backtrack: when no local target is left, step back along the robot's
            own committed walk to the previous segment end.
        cut_loops: remove loops from the committed walk (see the module docstring).
        max_attempts: budget of local-target attempts (patch problems sent to
            the chip) per query; default ``max(64, free cells of the world)``.
        max_chip_calls: budget of physical chip calls per query; default
            ``max_attempts x len(styles) x num_reads``.
        target_order: ``"boundary_first"`` (goal, boundary cells, then interior
            cells) or ``"merged"`` (boundary and interior ranked together).
        scale: chip units per QUBO weight unit before merging
            (default :data:`DEFAULT_SCALE` ``[form]``).
        pack: block-pack the portfolio's programs into shared 45-spin chip
            programs (fewer calls; off = one program per call, as in the paper).
    """

    name = "ising"

    def __init__(
        self,
        chip=None,
        patch_size: int = 5,
        form: str = "pair",
        weights: dict | None = None,
        styles=None,
        num_reads: int = 1,
        targets_per_call: int = 1,
        interior_targets: bool = True,
        backtrack: bool = True,
        cut_loops: bool = True,
        max_attempts: int | None = None,
        max_chip_calls: int | None = None,
        target_order: str = "boundary_first",
        scale: float | None = None,
        pack: bool = False,
    ):
        from ising_backend import ChipSpec, EmulatedChip, MERGE_STYLES

        if form not in FORMS:
            raise ValueError(f"form must be one of {FORMS}, got {form!r}")
        self.form = form
        if target_order not in TARGET_ORDERS:
            raise ValueError(f"target_order must be one of {TARGET_ORDERS}, got {target_order!r}")
        self.target_order = target_order
        self.scale = float(DEFAULT_SCALE[form] if scale is None else scale)
        if not (np.isfinite(self.scale) and self.scale > 0):
            raise ValueError(f"scale must be a positive finite number, got {scale!r}")
        self.pack = bool(pack)
        self._problem_cache = _LRU(4096)
        self._merge_cache = _LRU(4 * 4096)
        self._mappings = None
        self.chip = EmulatedChip(ChipSpec()) if chip is None else chip
        self.frame = patch_frame(patch_size)
        w = dict(DEFAULT_WEIGHTS[form])
        if weights:
            unknown = set(weights) - set(w)
            if unknown:
                raise ValueError(f"unknown weights {sorted(unknown)} for form {form!r} (known: {sorted(w)})")
            for k, v in weights.items():
                if not np.isfinite(v):
                    raise ValueError(f"weight {k} = {v!r} must be finite")
            w.update(weights)
        self.weights = w
        styles = tuple(MERGE_STYLES if styles is None else styles)
        bad = [s for s in styles if s not in MERGE_STYLES]
        if not styles or bad:
            raise ValueError(f"styles must be a non-empty subset of {MERGE_STYLES}, got {styles!r}")
        self.styles = styles
        for name, value in (("num_reads", num_reads), ("targets_per_call", targets_per_call),
                            ("max_attempts", max_attempts), ("max_chip_calls", max_chip_calls)):
            if value is None and name.startswith("max_"):
                continue
            if int(value) != value or value < 1:
                raise ValueError(f"{name} must be a positive integer, got {value!r}")
        self.num_reads = int(num_reads)
        self.targets_per_call = int(targets_per_call)
        self.interior_targets = bool(interior_targets)
        self.backtrack = bool(backtrack)
        self.cut_loops = bool(cut_loops)
        self.max_attempts = None if max_attempts is None else int(max_attempts)
        self.max_chip_calls = None if max_chip_calls is None else int(max_chip_calls)
        n_spins = self.chip.spec.n_spins
        if self.frame.n - 2 > n_spins:
            raise ValueError(
                f"patch_size = {patch_size} gives up to {self.frame.n - 2} patch variables; "
                f"the chip has {n_spins} spins (spec.n_spins)"
            )

    def __repr__(self) -> str:
        return (f"IsingPath(patch_size={self.frame.size}, form={self.form!r}, styles={self.styles}, "
                f"num_reads={self.num_reads}, targets_per_call={self.targets_per_call})")

    # ------------------------------------------------------------------ mapping
    def _solve(self, solver, problems: list, rng: np.random.Generator) -> list:
        """One portfolio submission: every problem x every merge style, ``num_reads`` reads each."""
        from ising_backend import run_portfolio_batch

        models = [m for _, m in problems]
        problems = [pr for pr, _ in problems]
        fr = self.frame

        def decoder(pr):
            def decode(spins):
                return decode_paths(fr, pr, (np.asarray(spins) > 0)[None])[0]
            return decode

        if self._mappings is None:
            self._mappings = [_cached_merge_mapping(st, self.scale, self._merge_cache) for st in self.styles]
        mappings = self._mappings
        return run_portfolio_batch(models, mappings, solver, decode=[decoder(p) for p in problems],
                                   num_reads=self.num_reads, seed=int(rng.integers(0, 2**63 - 1)),
                                   pack=self.pack)

    def _problem(self, comp: np.ndarray, target: int):
        """The patch problem (and its logical Ising model) for a free-cell mask and local target, memoised."""
        from ising_backend import QuboModel

        def make():
            pr = build_patch_qubo(self.frame, comp, self.frame.n // 2, target, self.form, self.weights)
            model = QuboModel(pr.q, pr.Q, pr.offset).to_ising() if pr.n else None
            return pr, model

        return self._problem_cache.get_or((np.packbits(comp).tobytes(), target), make)

    # ------------------------------------------------------------------ ranking
    def _ranked_targets(self, pos, goal, comp, excluded) -> list:
        fr = self.frame
        idx = np.flatnonzero(comp)
        idx = idx[idx != fr.n // 2]
        cells = fr.offsets[idx] + np.asarray(pos)
        keep = np.array([(int(r), int(c)) not in excluded for r, c in cells], dtype=bool)
        idx, cells = idx[keep], cells[keep]
        if len(idx) == 0:
            return []
        is_goal = (cells == np.asarray(goal)).all(axis=1)
        ring = fr.ring[idx]
        cls = np.where(is_goal, 0, np.where(ring, 1, 2))
        if not self.interior_targets:
            sel = cls < 2
            idx, cells, cls = idx[sel], cells[sel], cls[sel]
        to_goal = np.abs(cells - np.asarray(goal)).sum(axis=1)
        from_pos = np.abs(fr.offsets[idx]).sum(axis=1)
        if self.target_order == "merged":  # interior cells compete on distance, boundary wins ties
            order = np.lexsort((idx, from_pos, cls, to_goal, cls != 0))
        else:
            order = np.lexsort((idx, from_pos, to_goal, cls))
        return [(int(idx[k]), (int(cells[k, 0]), int(cells[k, 1]))) for k in order]

    # ------------------------------------------------------------------ main loop
    def find_path(self, world, start, goal, rng: np.random.Generator | None = None):
        """A 4-neighbour path from ``start`` to ``goal`` built from chip-generated patch segments."""
        from planners.base import PathResult
        from planners.compute import ComputeReport

        grid = world.grid
        h, w = grid.shape
        s = (int(start[0]), int(start[1]))
        g = (int(goal[0]), int(goal[1]))
        for name, (r, c) in (("start", s), ("goal", g)):
            if not (0 <= r < h and 0 <= c < w):
                return PathResult(None, failure=f"{name} cell [{r}, {c}] is off the {h}x{w} grid")
            if grid[r, c]:
                return PathResult(None, failure=f"{name} cell [{r}, {c}] is an obstacle")
        rng = np.random.default_rng() if rng is None else rng
        fr = self.frame
        rad = fr.radius
        centre = fr.n // 2
        padded = np.pad(np.asarray(grid, dtype=bool), rad, constant_values=True)
        solver = _CheckedChip(self.chip)
        mapping = {st: {"programs": 0, "valid": 0, "wins": 0, "map_errors": 0} for st in self.styles}
        counts = {"patch_solves": 0, "anneal_calls": 0, "segments": 0, "backtracks": 0, "direct_moves": 0}

        per_target = len(self.styles) * self.num_reads  # chip calls of one local-target attempt
        max_attempts = self.max_attempts if self.max_attempts is not None else max(64, int((~grid).sum()))
        max_calls = self.max_chip_calls if self.max_chip_calls is not None else max_attempts * per_target
        pos = s
        walk = [s]
        visited = {s}
        stack: list = []  # committed segments (lists of cells), most recent last
        failed: set = set()  # (position, local target) pairs that gave no valid candidate
        failure = None
        first_map_error = None

        while pos != g:
            used = solver.charged.physical_calls
            if counts["patch_solves"] >= max_attempts or used + per_target > max_calls:
                failure = (f"gave up at [{pos[0]}, {pos[1]}] before reaching goal [{g[0]}, {g[1]}]: budget spent "
                           f"({counts['patch_solves']} patch solves of max_attempts={max_attempts}, "
                           f"{used} chip calls of max_chip_calls={max_calls})")
                break
            allowed = ~padded[pos[0]:pos[0] + fr.size, pos[1]:pos[1] + fr.size].reshape(-1)
            comp = component_of(fr, allowed, centre)
            excluded = visited | {t for (p, t) in failed if p == pos}
            ranked = self._ranked_targets(pos, g, comp, excluded)
            if not ranked:
                if self.backtrack and stack:
                    seg = stack.pop()
                    walk.extend(reversed(seg[:-1]))
                    pos = seg[0]
                    counts["backtracks"] += 1
                    continue
                failure = (f"no path found from [{s[0]}, {s[1]}] to [{g[0]}, {g[1]}]: every local target "
                           f"reachable from [{pos[0]}, {pos[1]}] was visited or failed"
                           + (" and backtracking is exhausted" if self.backtrack else " (backtrack=False)")
                           + " (the goal may be unreachable)")
                break
            # calls left in the budget limit how many targets share this submission
            room = max(1, (max_calls - used) // per_target)
            room = min(room, max_attempts - counts["patch_solves"])
            batch = ranked[: min(self.targets_per_call, room)]
            problems = [self._problem(comp, li) for li, _ in batch]
            # a problem without variables (the target is the robot's only patch neighbour) needs no chip
            results: list = [[] for _ in batch]
            on_chip = []
            for k, (pr, _) in enumerate(problems):
                if pr.n == 0:
                    path = decode_paths(fr, pr, np.zeros((1, 0)))[0]
                    if path is not None:
                        results[k].append((pr.offset, None, path))
                else:
                    on_chip.append(k)
            if on_chip:
                try:
                    outs = self._solve(solver, [problems[k] for k in on_chip], rng)
                except _ChipOutputError as exc:
                    failure = f"the chip returned malformed samples: {exc}"
                    break
                counts["anneal_calls"] += 1
                counts["patch_solves"] += len(on_chip)
                for k, res in zip(on_chip, outs):
                    for st, o in res.outcomes.items():
                        mapping[st]["programs"] += o.reads
                        mapping[st]["valid"] += o.valid
                        mapping[st]["map_errors"] += int(o.error is not None)
                        if o.error is not None and first_map_error is None:
                            first_map_error = f"{st}: {o.error}"
                    if res.success:
                        tol = 1e-9 * max(1.0, abs(res.best_score))
                        winners = [st for st in self.styles if res.outcomes[st].best_score <= res.best_score + tol]
                        results[k].append((res.best_score, winners, res.best))
            chosen = None
            for k, (li, target) in enumerate(batch):
                if results[k]:
                    chosen = results[k][0]
                    break
                failed.add((pos, target))
            if chosen is None:
                continue
            _, winners, path = chosen
            if winners:  # equal-scoring styles: one win, to a style drawn by rng (no order bias)
                win = winners[int(rng.integers(len(winners)))] if len(winners) > 1 else winners[0]
                mapping[win]["wins"] += 1
            else:
                counts["direct_moves"] += 1
            seg = [(pos[0] + int(fr.offsets[i, 0]), pos[1] + int(fr.offsets[i, 1])) for i in path]
            if g in seg:  # the segment passes the goal: the robot stops there
                seg = seg[: seg.index(g) + 1]
            walk.extend(seg[1:])
            visited.update(seg)
            stack.append(seg)
            counts["segments"] += 1
            pos = seg[-1]

        delta = solver.charged
        compute = ComputeReport.from_ledger(delta)
        stats = {
            "chip_calls": int(delta.physical_calls),
            "chip_batches": int(delta.batches),
            **counts,
            "walk_length": len(walk) - 1,
            "mapping": {"path": mapping},
        }
        if failure is not None:
            n_err = sum(m["map_errors"] for m in mapping.values())
            if n_err and not any(m["programs"] for m in mapping.values()):
                failure = (f"no patch program could be mapped onto the chip ({n_err} mapping errors; "
                           f"first: {first_map_error}); search state: {failure}")
            elif n_err:
                failure += f"; {n_err} patch program(s) could not be mapped onto the chip, first: {first_map_error}"
            return PathResult(None, compute=compute, failure=failure, stats=stats)
        cells = cut_loops(walk) if self.cut_loops else walk
        path = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
        # final check (never hand out an invalid path)
        steps = np.abs(np.diff(path, axis=0)).sum(axis=1)
        if (steps != 1).any() or grid[path[:, 0], path[:, 1]].any() or tuple(path[0]) != s or tuple(path[-1]) != g:
            return PathResult(None, compute=compute, stats=stats,
                              failure="internal error: the stitched walk is not a valid 4-neighbour path")
        stats["path_length"] = len(path) - 1
        return PathResult(path, compute=compute, stats=stats)
