"""Episodes people can watch: frames of robots, targets and routes, written as a GIF.

:func:`episode_frames` runs one episode of a controller and draws a frame per step with each robot's route (solid
where driven, faint where still to go); :func:`write_gif` needs ``imageio`` (the ``viz`` extra).
Design notes: docs/design/evaluation.md#episodes-as-gifs.
"""

from __future__ import annotations

import numpy as np

from mrmt_env.render import PALETTE, render_rgb

__all__ = ["episode_frames", "write_gif", "draw_route"]

CELL = 24


def draw_route(img: np.ndarray, path, colour, cell: int = CELL, width: int = 3, faint: bool = False) -> None:
    """Draw a cell-by-cell path (``[[r, c], ...]``) as a line through cell centres, in place."""
    col = np.asarray(colour, dtype=np.float64)
    if faint:
        col = 0.35 * col + 0.65 * 255
    col = col.astype(np.uint8)
    half = width // 2
    cells = np.asarray(path, dtype=np.int64).reshape(-1, 2)
    for (r0, c0), (r1, c1) in zip(cells[:-1], cells[1:]):
        y0, x0 = r0 * cell + cell // 2, c0 * cell + cell // 2
        y1, x1 = r1 * cell + cell // 2, c1 * cell + cell // 2
        ya, yb = sorted((y0, y1))
        xa, xb = sorted((x0, x1))
        img[ya - half: yb + half + 1, xa - half: xb + half + 1] = col


def _frame(world, visited, positions, driven, to_go, cell):
    empty = np.zeros((0, 2), dtype=np.int64)
    base = render_rgb(world.grid, world.targets, visited, empty, cell=cell)
    top = render_rgb(world.grid, world.targets, visited, positions, cell=cell)
    img = base.copy()
    for k in range(len(positions)):
        colour = PALETTE[k % len(PALETTE)]
        if to_go[k] is not None and len(to_go[k]) > 1:
            draw_route(img, to_go[k], colour, cell, faint=True)
        if len(driven[k]) > 1:
            draw_route(img, driven[k], colour, cell)
    robots = np.any(top != base, axis=2)  # robots on top of the routes
    img[robots] = top[robots]
    return img


def _grid_frames(env, controller, seed, cell, max_frames):
    obs, info = env.reset(seed=seed)
    begin = getattr(controller, "begin_episode", None)
    if begin is not None:
        begin(env.unwrapped, 0)
    core = env.unwrapped.core
    world = env.unwrapped.world
    masked = getattr(controller, "uses_action_masks", False)
    trails = [[tuple(p)] for p in core.positions().tolist()]
    frames, start, done = [], True, False
    while True:
        action = None
        if not done:
            kwargs = {"action_masks": env.unwrapped.action_masks()} if masked else {}
            action, _ = controller.predict(obs, episode_start=start, deterministic=True, **kwargs)
            start = False
        plan = controller.current_plan(0) if hasattr(controller, "current_plan") else None
        to_go = [None] * world.n_robots
        if plan is not None:
            t = max(controller.plan_step(0) - (0 if done else 1), 0)  # the move just chosen is still to go
            to_go = [r.path[min(t, len(r.path) - 1):] for r in plan.routes][: world.n_robots]
        frames.append(_frame(world, list(core.visited), core.positions(), trails, to_go, cell))
        if done or len(frames) >= max_frames:
            break
        obs, _, term, trunc, info = env.step(action)
        for k, p in enumerate(core.positions().tolist()):
            if tuple(p) != trails[k][-1]:
                trails[k].append(tuple(p))
        done = term or trunc
    return frames, info


def _assign_frames(env, controller, seed, cell, max_frames):
    from mrmt_env.assign.env import shortest_path

    obs, info = env.reset(seed=seed)
    begin = getattr(controller, "begin_episode", None)
    if begin is not None:
        begin(env.unwrapped, 0)
    u = env.unwrapped
    world = u.world
    # segments[k]: (decision time, target, path) in order
    segments = [[] for _ in range(world.n_robots)]
    start, done = True, False
    while not done:
        k = int(info["robot"])
        at = int(u.state.free_at[0, k])
        here = u.state.positions(0)[k]
        kwargs = {"action_masks": info["action_mask"]} if getattr(controller, "uses_action_masks", False) else {}
        action, _ = controller.predict(obs, episode_start=start, deterministic=True, **kwargs)
        start = False
        before = int(u.state.counters[0, 2])
        obs, _, term, trunc, info = env.step(action)
        if int(u.state.counters[0, 2]) > before:
            segments[k].append((at, int(action), shortest_path(world, here, world.targets[int(action)])))
        done = term or trunc
    horizon = int(info["makespan"])
    full = []
    for k in range(world.n_robots):
        path = [world.robots[k]]
        for _, _, seg in segments[k]:
            path.extend(seg[1:])
        full.append(np.asarray(path, dtype=np.int64).reshape(-1, 2))
    frames = []
    for t in range(horizon + 1):
        pos = np.array([p[min(t, len(p) - 1)] for p in full])
        visited = np.zeros(world.n_targets, dtype=bool)
        to_go = []
        for k in range(world.n_robots):
            committed_end = 0
            for at, j, seg in segments[k]:
                arrive = at + len(seg) - 1
                if arrive <= t:
                    visited[j] = True
                if at <= t:
                    committed_end = arrive
            to_go.append(full[k][min(t, len(full[k]) - 1): committed_end + 1])
        for r in world.robots.tolist():  # targets under a robot at reset
            visited |= (world.targets == r).all(axis=1)
        driven = [full[k][: t + 1] for k in range(world.n_robots)]
        frames.append(_frame(world, visited, pos, driven, to_go, cell))
        if len(frames) >= max_frames:
            break
    return frames, info


def episode_frames(controller="strong", env_id: str = "mrmt_env/MRMT-v0", seed: int = 0,
                   env_kwargs: dict | None = None, cell: int = CELL, max_frames: int = 400):
    """Frames (``(H * cell, W * cell, 3)`` uint8) of one episode and its final ``info``.

    Args:
        controller: a spec (``"strong"``, ``"ising"``, ``"ppo:model.zip"``, ...) or a controller object.
        env_id, env_kwargs, seed: the env and the world's reset seed.
        cell: pixels per grid cell; max_frames: stop drawing after this many frames.
    """
    import gymnasium as gym

    from agents.env_ids import check_env_id, is_assign_env
    from agents.evaluation import make_controller

    check_env_id(env_id)
    if isinstance(cell, bool) or int(cell) != cell or cell < 8:
        raise ValueError(f"cell must be an integer >= 8 pixels, got {cell!r}")
    if isinstance(max_frames, bool) or int(max_frames) != max_frames or max_frames < 1:
        raise ValueError(f"max_frames must be an integer >= 1, got {max_frames!r}")
    ctrl = make_controller(controller, env_id=env_id) if isinstance(controller, str) else controller
    env = gym.make(env_id, **dict(env_kwargs or {}))
    if is_assign_env(env_id):
        return _assign_frames(env, ctrl, seed, int(cell), int(max_frames))
    return _grid_frames(env, ctrl, seed, int(cell), int(max_frames))


def write_gif(frames, path, fps: float = 4.0) -> None:
    """Write frames as a looping GIF (needs ``imageio``: ``pip install 'mrmt-ising[viz]'``)."""
    try:
        import imageio.v3 as iio
    except ImportError as exc:
        raise ImportError("writing a GIF needs imageio: pip install 'mrmt-ising[viz]'") from exc
    if not str(path).lower().endswith(".gif"):
        raise ValueError(f"GIF path {str(path)!r} must end in .gif")
    if not frames:
        raise ValueError("no frames to write")
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be > 0, got {fps!r}")
    iio.imwrite(path, np.stack(frames), extension=".gif", duration=1000.0 / fps, loop=0)
