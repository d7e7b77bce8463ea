"""A lifelong episode people can watch: one frame per step, each robot's way to its current task drawn.

:func:`lifelong_frames` runs a lifelong controller (:mod:`agents.lifelong.controllers`) on a
lifelong id and draws every step on the env's ``rgb_array`` image: open tasks
as gold rings, robots as coloured squares, and a faint line in the robot's
colour along a BFS shortest path to the task at the head of its queue.
``mrmt watch --env-id mrmt_env/MRMT-Lifelong-v0 --controller greedy`` writes it
as a GIF (:func:`agents.animation.write_gif`).
"""

from __future__ import annotations

import numpy as np

from agents.animation import CELL, draw_route
from mrmt_env.render import PALETTE, render_rgb

__all__ = ["lifelong_frames"]


def _path(field: np.ndarray, start: int, width: int, succ: np.ndarray) -> list[list[int]]:
    """Cells ``[r, c]`` of a BFS shortest path from ``start`` down ``field`` (flat) to its 0."""
    cells, p = [list(divmod(start, width))], start
    while field[p] > 0:
        p = min((int(q) for q in succ[p, 1:] if field[q] >= 0), key=lambda q: field[q])
        cells.append(list(divmod(p, width)))
    return cells


def lifelong_frames(spec: str, env_id: str, seed: int = 0, steps: int = 100, cell: int = CELL,
                    env_kwargs: dict | None = None, executor: str = "pibt"):
    """Frames ``(H * cell, W * cell, 3)`` uint8 of ``steps`` steps and the final ``info``."""
    import gymnasium as gym

    from agents.lifelong.controllers import make_lifelong_controller

    if isinstance(cell, bool) or int(cell) != cell or cell < 8:
        raise ValueError(f"cell must be an integer >= 8 pixels, got {cell!r}")
    if isinstance(steps, bool) or int(steps) != steps or steps < 1:
        raise ValueError(f"steps must be an integer >= 1, got {steps!r}")
    env = gym.make(env_id, max_episode_steps=int(steps), **dict(env_kwargs or {}))
    obs, info = env.reset(seed=seed)
    ctrl = make_lifelong_controller(spec, seed=seed, executor=executor)
    u = env.unwrapped
    frames = []
    for _ in range(int(steps)):
        action = ctrl.act(obs)
        grid, width = u.world.grid, u.world.width
        tasks, pos = u.open_tasks(), u.positions()
        img = render_rgb(grid, np.zeros((0, 2), dtype=np.int64), [], np.zeros((0, 2), dtype=np.int64), cell=int(cell))
        flat = pos[:, 0] * width + pos[:, 1]
        for k, q in enumerate(ctrl.queues):
            if q:
                field = ctrl.fields.fields[ctrl.fields.rows(np.array([q[0]]))[0]]
                draw_route(img, _path(field, int(flat[k]), width, ctrl.executor.succ), PALETTE[k % len(PALETTE)],
                           int(cell), width=max(1, int(cell) // 8), faint=True)
        top = render_rgb(grid, tasks, [False] * len(tasks), pos, cell=int(cell))
        plain = render_rgb(grid, np.zeros((0, 2), dtype=np.int64), [], np.zeros((0, 2), dtype=np.int64),
                           cell=int(cell))
        mask = np.any(top != plain, axis=2)
        img[mask] = top[mask]
        frames.append(img)
        obs, _, _, truncated, info = env.step(action)
        if truncated:
            break
    return frames, info
