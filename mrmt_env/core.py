"""The simulator core: the one copy of the dynamics both environments use.

:class:`MRMTCore` holds one episode's state and advances it by one joint action; the Gymnasium env
(:mod:`mrmt_env.grid.env`) and the PettingZoo env (:mod:`mrmt_env.grid.pz`) only validate actions, wrap the
results in their API and handle the step limit. Robots may share cells: conflicts are counted, not forbidden.
Design notes (dynamics, speed): docs/design/envs.md#the-simulator-core.
"""

from __future__ import annotations

import gc

import numpy as np

from mrmt_env.distances import MOVES, bfs_distance_fields
from mrmt_env.generation import DEFAULT_DENSITY, generate_world
from mrmt_env.maps import check_layout
from mrmt_env.io import read_worlds
from mrmt_env.observation import ROBOT_CHANNEL0, TARGET_CHANNEL, encode_observation
from mrmt_env.render import render_ansi, render_rgb
from mrmt_env.world import World

__all__ = [
    "MRMTCore", "WorldSource", "action_between", "show", "actions_from_path", "check_render_mode", "check_step_limit",
    "render_ready", "N_ACTIONS", "ACTION_NAMES",
    "successor_table", "MAX_GRID_ENV_CELLS", "check_grid_env_cells",
]

N_ACTIONS = 5
ACTION_NAMES = ("stay", "up", "down", "left", "right")


def show(value, limit: int = 60) -> str:
    """``repr(value)`` on one line, at most ``limit`` characters (for error messages)."""
    text = " ".join(repr(value).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def check_step_limit(max_episode_steps):
    """``max_episode_steps`` as an int, or ``None``; ``ValueError`` naming it unless an integer >= 1."""
    if max_episode_steps is None:
        return None
    if isinstance(max_episode_steps, bool) or int(max_episode_steps) != max_episode_steps or max_episode_steps < 1:
        raise ValueError(f"max_episode_steps must be an integer >= 1 or None, got {max_episode_steps!r}")
    return int(max_episode_steps)


def check_render_mode(render_mode, render_modes) -> None:
    """Raise ``ValueError`` unless ``render_mode`` is ``None`` or one of ``render_modes``."""
    if render_mode is not None and render_mode not in render_modes:
        raise ValueError(f"render_mode must be one of {render_modes} or None, got {render_mode!r}")


def render_ready(started: bool, render_mode) -> bool:
    """A single env's ``render()`` guard: ``RuntimeError`` before ``reset()``; ``False`` (with gymnasium's
    warning) without a render mode."""
    if not started:
        raise RuntimeError("call reset() before render()")
    if render_mode is None:
        from gymnasium import logger

        logger.warn("render() called without a render_mode; pass render_mode='ansi' or 'rgb_array'",
                    stacklevel=2)  # attributed to the env's render(), as before
        return False
    return True


#: Largest grid (cells; 1024 x 1024) of the step-level grid envs: they keep a Python move table per
#: cell (about 200 MB at the limit) and copy a ``(2 + R) x H x W`` observation every step.  The world
#: model, the planners and the plan-level env take up to ``generation.MAX_GRID_CELLS``.
MAX_GRID_ENV_CELLS = 2**20


def check_grid_env_cells(height: int, width: int) -> None:
    """``ValueError`` naming the size and :data:`MAX_GRID_ENV_CELLS` if a grid env cannot hold the grid."""
    if height * width > MAX_GRID_ENV_CELLS:
        raise ValueError(
            f"a {height}x{width} grid has {height * width} cells; the step-level grid env takes at most "
            f"{MAX_GRID_ENV_CELLS} (MAX_GRID_ENV_CELLS, 1024 x 1024); plan such worlds with the planners or "
            "the plan-level env (mrmt_env/MRMT-Assign-v0)"
        )


def successor_table(grid: np.ndarray) -> list[tuple[int, ...]]:
    """``table[p][a]``: flat cell reached from flat cell ``p`` by action ``a``.

    A move off the grid or into an obstacle gives ``p`` itself (blocked).
    Built with numpy, then kept as Python tuples for the step's plain-int
    indexing (a 1024 x 1024 grid: about a second and 200 MB).
    """
    grid = np.asarray(grid, dtype=bool)
    h, w = grid.shape
    cells = np.arange(h * w, dtype=np.int64).reshape(h, w)
    table = np.repeat(cells[:, :, None], 1 + len(MOVES), axis=2)
    for a, (dr, dc) in enumerate(MOVES.tolist(), start=1):
        src = (slice(max(0, -dr), h - max(0, dr)), slice(max(0, -dc), w - max(0, dc)))
        dst = (slice(max(0, dr), h - max(0, -dr)), slice(max(0, dc), w - max(0, -dc)))
        table[src + (a,)] = np.where(grid[dst], cells[src], cells[dst])
    enabled = gc.isenabled()
    gc.disable()  # millions of new tuples would trigger many useless collections
    try:
        flat, out = table.reshape(h * w, -1), []
        for start in range(0, h * w, 1 << 16):  # in chunks: no list-of-lists copy of the whole table
            out.extend(map(tuple, flat[start:start + (1 << 16)].tolist()))
        return out
    finally:
        if enabled:
            gc.enable()


_DELTA_TO_ACTION = {(0, 0): 0, **{(int(dr), int(dc)): a for a, (dr, dc) in enumerate(MOVES.tolist(), start=1)}}


def action_between(cell, next_cell) -> int:
    """The action (0 stay, 1 up, 2 down, 3 left, 4 right) taking a robot from
    ``cell`` to ``next_cell``.

    Raises:
        ValueError: the cells are neither equal nor 4-neighbours.
    """
    delta = (int(next_cell[0]) - int(cell[0]), int(next_cell[1]) - int(cell[1]))
    try:
        return _DELTA_TO_ACTION[delta]
    except KeyError:
        raise ValueError(
            f"cells {[int(cell[0]), int(cell[1])]} -> {[int(next_cell[0]), int(next_cell[1])]} are not "
            "equal or 4-neighbours; one step moves by at most one row or one column"
        ) from None


def actions_from_path(path) -> list[int]:
    """Actions that walk a cell-by-cell path ``[[r, c], ...]`` (``len(path) - 1`` actions)."""
    cells = [tuple(int(v) for v in c) for c in path]
    return [action_between(a, b) for a, b in zip(cells, cells[1:])]


class MRMTCore:
    """One episode of the multi-robot multi-target grid world.

    Args:
        target_reward: reward per newly visited target; ``None`` gives
            ``2 * H * W`` for each world (see :meth:`default_target_reward`).

    Reward of a step: ``target_reward`` per target first visited in that
    step, minus 1 per robot that attempted a move (action ``1..4``), whether
    the move was made or blocked.  Staying costs nothing.
    """

    def __init__(self, target_reward: float | None = None) -> None:
        if target_reward is not None and not (np.isfinite(target_reward) and target_reward > 0):
            raise ValueError(f"target_reward must be a finite number > 0 or None, got {target_reward!r}")
        self.target_reward_arg = target_reward
        self.world: World | None = None
        self._grid_key: bytes | None = None

    @staticmethod
    def default_target_reward(height: int, width: int) -> float:
        """``2 * H * W``: more than the fewest total moves that visit every target.

        Each robot can reach every cell of its free component along a
        depth-first walk of a spanning tree (fewer than 2 x component size
        moves), so the robots together can visit all targets in
        ``C* < 2 * H * W`` moves.  Hence a complete visit in ``C*`` moves
        returns ``target_reward * N - C* > target_reward * (N - 1)``, more than
        any incomplete episode, and among complete episodes fewer moves give
        a higher return (provided the step limit leaves time to finish).
        """
        return float(2 * height * width)

    # ------------------------------------------------------------------ reset
    def reset(self, world: World) -> None:
        """Start an episode on ``world`` (robots at their start cells)."""
        h, w = world.shape
        key = world.grid.tobytes() + bytes(f"{h}x{w}", "ascii")
        if key != self._grid_key:
            self._nxt = successor_table(world.grid)
            self._grid_key = key
        self.world = world
        self.height, self.width, self.hw = h, w, h * w
        self.n_robots = world.n_robots
        self.n_targets = world.n_targets
        self.target_reward = (
            self.default_target_reward(h, w) if self.target_reward_arg is None else float(self.target_reward_arg)
        )
        self.pos = [int(r) * w + int(c) for r, c in world.robots.tolist()]
        tgt_at = [-1] * self.hw
        for i, (r, c) in enumerate(world.targets.tolist()):
            tgt_at[r * w + c] = i
        self._tgt_at = tgt_at
        self.visited = [False] * self.n_targets
        self.n_visited = 0
        for p in self.pos:
            t = tgt_at[p]
            if t >= 0 and not self.visited[t]:
                self.visited[t] = True
                self.n_visited += 1
        self.obs = encode_observation(world, visited=self.visited)
        self._obs_flat = self.obs.reshape(-1)  # a view: writes go to self.obs
        self.steps = 0
        self.route_cost = 0
        self.robot_moves = [0] * self.n_robots
        self.invalid_moves = 0
        self.vertex_conflicts = 0
        self.swap_conflicts = 0
        self.last_new_targets = 0

    # ------------------------------------------------------------------- step
    def step(self, actions: list[int]) -> float:
        """Apply one joint action (a list of ``R`` ints in ``0..4``, already
        validated by the caller) and return the step's reward."""
        pos = self.pos
        nxt = self._nxt
        obs = self._obs_flat
        tgt_at = self._tgt_at
        visited = self.visited
        hw = self.hw
        attempted = 0
        made = 0
        new = 0
        moved = None
        for k, a in enumerate(actions):
            if a:
                attempted += 1
                p = pos[k]
                q = nxt[p][a]
                if q == p:
                    continue
                pos[k] = q
                made += 1
                self.robot_moves[k] += 1
                base = (ROBOT_CHANNEL0 + k) * hw
                obs[base + p] = 0
                obs[base + q] = 1
                if moved is None:
                    moved = [(p, q)]
                else:
                    moved.append((p, q))
                t = tgt_at[q]
                if t >= 0 and not visited[t]:
                    visited[t] = True
                    new += 1
                    obs[TARGET_CHANNEL * hw + q] = 0
        self.steps += 1
        self.route_cost += made
        self.invalid_moves += attempted - made
        if new:
            self.n_visited += new
        self.last_new_targets = new
        n = self.n_robots
        if n > 1:
            if len(set(pos)) < n:
                counts: dict[int, int] = {}
                for p in pos:
                    counts[p] = counts.get(p, 0) + 1
                self.vertex_conflicts += sum(c * (c - 1) // 2 for c in counts.values() if c > 1)
            if made > 1:
                edges: dict[tuple[int, int], int] = {}
                for e in moved:
                    edges[e] = edges.get(e, 0) + 1
                self.swap_conflicts += sum(c * edges.get((q, p), 0) for (p, q), c in edges.items() if p < q)
        return new * self.target_reward - attempted

    # ------------------------------------------------------------- pickling
    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state.pop("_obs_flat", None)  # a view of self.obs: rebuilt on load
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        if "obs" in state:
            self._obs_flat = self.obs.reshape(-1)

    # ---------------------------------------------------------------- queries
    @property
    def all_visited(self) -> bool:
        return self.n_visited == self.n_targets

    def move_masks(self) -> np.ndarray:
        """``(R, 5)`` bool: action ``a`` of robot ``k`` is not blocked (stay is always allowed)."""
        nxt = self._nxt
        return np.array([[a == 0 or nxt[p][a] != p for a in range(N_ACTIONS)] for p in self.pos], dtype=bool)

    def nearest_target_field(self) -> np.ndarray:
        """``(H*W,)`` int32 BFS moves from each cell to the nearest unvisited target (-1: none reachable)."""
        todo = self.world.targets[[i for i, v in enumerate(self.visited) if not v]]
        if len(todo) == 0:
            return np.full(self.hw, -1, dtype=np.int32)
        fields = bfs_distance_fields(self.world.grid, todo).reshape(len(todo), -1)
        fields = np.where(fields < 0, np.iinfo(np.int32).max, fields).min(axis=0)
        return np.where(fields == np.iinfo(np.int32).max, -1, fields).astype(np.int32)

    def potential(self, field: np.ndarray) -> float:
        """Minus the summed BFS moves from each robot to its nearest unvisited target (0 when none is left)."""
        return -float(sum(max(int(field[p]), 0) for p in self.pos))

    def observation(self) -> np.ndarray:
        """A copy of the global observation ``(2 + R, H, W)`` uint8."""
        return self.obs.copy()

    def positions(self) -> np.ndarray:
        """``(R, 2)`` int64 current robot cells ``[row, col]``."""
        w = self.width
        return np.array([divmod(p, w) for p in self.pos], dtype=np.int64).reshape(-1, 2)

    def info(self) -> dict:
        """Flat, deterministic episode metrics so far (no wall-clock values)."""
        return {
            "route_cost": self.route_cost,
            "makespan": max(self.robot_moves),
            "steps": self.steps,
            "targets_visited": self.n_visited,
            "n_targets": self.n_targets,
            "is_success": self.n_visited == self.n_targets,
            "invalid_moves": self.invalid_moves,
            "conflicts": self.vertex_conflicts + self.swap_conflicts,
            "vertex_conflicts": self.vertex_conflicts,
            "swap_conflicts": self.swap_conflicts,
        }

    def render(self, mode: str, makespan: bool = False):
        """Render the current state: an ``(H*16, W*16, 3)`` image for ``"rgb_array"``,
        else the ansi text under a header (steps, targets, route cost and, when
        ``makespan``, the makespan); ``"human"`` prints the text and returns ``None``."""
        if self.world is None:
            raise RuntimeError("call reset() before render()")
        if mode == "rgb_array":
            return render_rgb(self.world.grid, self.world.targets, self.visited, self.positions())
        info = self.info()
        header = f"step {info['steps']}  targets {info['targets_visited']}/{info['n_targets']}  route_cost {info['route_cost']}"
        if makespan:
            header += f"  makespan {info['makespan']}"
        text = render_ansi(self.world.grid, self.world.targets, self.visited, self.positions(), header)
        if mode == "human":
            print(text, end="")
            return None
        return text

    def current_world(self) -> World:
        """The world as it is now: current robot cells, unvisited targets
        in their original order."""
        keep = [i for i, v in enumerate(self.visited) if not v]
        return self.world.replace(robots=self.positions(), targets=self.world.targets[keep])


class WorldSource:
    """Where an env's worlds come from: one fixed world, or a fresh
    :func:`~mrmt_env.generation.generate_world` draw per reset.

    Args:
        world: a :class:`World`, a path to a world file (JSON, or JSON Lines
            holding exactly one world), or ``None`` to generate worlds.
        grid_env: refuse grids beyond :data:`MAX_GRID_ENV_CELLS` (the step-level envs).
        height, width, obstacle_density, n_robots, n_targets, placement, layout, layout_options:
            generator arguments (defaults 10, 10, 0.2 for the ``uniform``
            layout, 3, 10, ``"uniform"``, ``"uniform"``, the layout's
            defaults).  With a fixed world, sizes given here must agree with it.
    """

    DEFAULTS = {"height": 10, "width": 10, "obstacle_density": None, "n_robots": 3, "n_targets": 10,
                "placement": "uniform", "layout": "uniform", "layout_options": None}

    def __init__(self, world=None, *, grid_env: bool = False, **params) -> None:
        given = {k: v for k, v in params.items() if v is not None}
        unknown = sorted(set(given) - set(self.DEFAULTS))
        if unknown:
            raise ValueError(f"unknown world argument(s) {unknown}; allowed: {sorted(self.DEFAULTS)}")
        if world is not None:
            if not isinstance(world, World):
                worlds = read_worlds(world)
                if len(worlds) != 1:
                    raise ValueError(f"world file {world} holds {len(worlds)} worlds; an env takes exactly one")
                world = worlds[0]
            actual = {"height": world.height, "width": world.width, "n_robots": world.n_robots,
                      "n_targets": world.n_targets}
            for key, value in given.items():
                if key in actual and value != actual[key]:
                    raise ValueError(f"{key}={value!r} contradicts the given world, which has {key}={actual[key]}")
                if key not in actual:
                    raise ValueError(f"{key}={value!r} only applies to generated worlds, not a fixed world")
            if grid_env:
                check_grid_env_cells(world.height, world.width)
            self.fixed: World | None = world
            self.params = dict(actual)
        else:
            self.fixed = None
            params = {**self.DEFAULTS, **given}
            if params["layout"] == "uniform" and params["obstacle_density"] is None:
                params["obstacle_density"] = DEFAULT_DENSITY
            if params["layout_options"] is not None:
                params["layout_options"] = check_layout(params["layout"], params["layout_options"])
            self.params = params
            h, w = params["height"], params["width"]
            if grid_env and all(isinstance(v, (int, np.integer)) for v in (h, w)):
                check_grid_env_cells(int(h), int(w))  # before a world is drawn
            generate_world(0, **self.params)  # validates the arguments now, with clear errors
        self.height = int(self.params["height"])
        self.width = int(self.params["width"])
        self.n_robots = int(self.params["n_robots"])

    def draw(self, rng: np.random.Generator) -> World:
        """The fixed world, or a new world drawn from ``rng`` (advanced in place)."""
        if self.fixed is not None:
            return self.fixed
        return generate_world(rng, **self.params)

    def check(self, world, n_targets: int | None = None) -> World:
        """Validate a world passed through ``reset(options={"world": ...})`` (``n_targets``: the
        target count the env's spaces need, if they depend on it)."""
        if not isinstance(world, World):
            raise TypeError(f"options['world'] must be a World, got {type(world).__name__}")
        if world.shape != (self.height, self.width) or world.n_robots != self.n_robots:
            raise ValueError(
                f"options['world'] is {world.height}x{world.width} with {world.n_robots} robots; this env's "
                f"spaces need {self.height}x{self.width} with {self.n_robots} robots"
            )
        if n_targets is not None and world.n_targets != n_targets:
            raise ValueError(f"options['world'] has {world.n_targets} targets; this env's spaces need {n_targets}")
        return world

    def reset_world(self, options, rng: np.random.Generator, n_targets: int | None = None) -> World:
        """The world of a ``reset(options=...)``: ``options["world"]`` (checked) or a draw from ``rng``.

        Other keys are ignored, as PettingZoo's API test expects of an env.

        Raises:
            TypeError: ``options`` is not a dict (or ``None``), or its world is not a ``World``.
            ValueError: a world that does not fit the env's spaces.
        """
        if options is None:
            return self.draw(rng)
        if not isinstance(options, dict):
            raise TypeError(f"options must be a dict or None, got {type(options).__name__}")
        if "world" in options:
            return self.check(options["world"], n_targets)
        return self.draw(rng)
