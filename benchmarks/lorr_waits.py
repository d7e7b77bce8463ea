"""Where a League run's robots stand still and where its step's time goes (issue 80, item 1).

One run of an instance under the entry's choice (or a scheduler and a planner given), its executed actions replayed
from the start states: per cell, the robot-steps spent waiting there (action W, or every robot in a timeout) and
turning; the step's seconds (the scheduler's and the planner's p99 apart).  Writes a heat map of the waits (log scale,
blocked cells dark) and prints the shares: of robot-steps waiting, turning, moving; of the waits on narrow cells
(at most two free neighbours) and in the busiest 1 % / 10 % of the free cells; per window of steps, the robots
waiting and the errands reached.

    python benchmarks/lorr_waits.py ../shared/lorr/2024-main/game.domain/GAME.json --steps 200 \\
        --png docs/lorr_waits_game.png [--clock rules] [--scheduler S --planner P]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def replay(sim) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per cell, the robot-steps waiting, turning and moving forward in ``sim``'s executed actions (its record), and
    per step the robots waiting."""
    from mrmt_env.lorr.rules import CLOCKWISE, COUNTER, FORWARD, TIMEOUT, WAIT, next_states

    n = sim.blocked.size
    wait, turn, move = (np.zeros(n, np.int64) for _ in range(3))
    pos, ori = sim.start_pos.copy(), sim.start_orient.copy()
    per_step = np.zeros(len(sim.actual), np.int64)
    for t, a in enumerate(sim.actual):
        a = a.astype(np.int64)
        still = (a == WAIT) | (a == TIMEOUT)
        per_step[t] = still.sum()
        np.add.at(wait, pos[still], 1)
        np.add.at(turn, pos[(a == CLOCKWISE) | (a == COUNTER)], 1)
        np.add.at(move, pos[a == FORWARD], 1)
        a = np.where(a == TIMEOUT, WAIT, a)
        pos, ori = next_states(pos, ori, a, sim.width)
    if not np.array_equal(pos, sim.pos):  # the replay is checked against the simulator's own end state
        raise RuntimeError("replayed positions differ from the simulator's")
    return wait, turn, move, per_step


def narrow_cells(blocked: np.ndarray, width: int) -> np.ndarray:
    """Free cells with at most two free 4-neighbours (the shape measure ``narrow``)."""
    g = blocked.reshape(-1, width)
    free = ~g
    pad = np.pad(free, 1)
    nb = pad[:-2, 1:-1].astype(int) + pad[2:, 1:-1] + pad[1:-1, :-2] + pad[1:-1, 2:]
    return (free & (nb <= 2)).reshape(-1)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("instance", type=Path)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--entry", default="default")
    ap.add_argument("--scheduler", default="", help="with --planner: this pair instead of the entry's choice")
    ap.add_argument("--planner", default="")
    ap.add_argument("--clock", default="", help="'rules' (1 s a step); default work-bounded")
    ap.add_argument("--windows", type=int, default=5, help="the run cut into this many windows of steps")
    ap.add_argument("--png", type=Path, default=None)
    ap.add_argument("--out", type=Path, default=None, help="write the run's output file here (benchmarks/lorr_detours.py reads it)")
    args = ap.parse_args(argv)

    from agents.lorr.entry import load_entry
    from agents.lorr.run import run_lorr
    from mrmt_env.lorr.clock import step_limit
    from mrmt_env.lorr.instance import read_instance

    inst = read_instance(args.instance)
    if args.scheduler:
        sched, planner, label = args.scheduler, args.planner or "pibt", f"{args.scheduler} + {args.planner}"
    else:
        c = load_entry(args.entry).choose(inst)
        sched, planner, label = c.scheduler, c.planner, f"entry {args.entry}, rule {c.rule}"
    limit = step_limit(args.clock) if args.clock else None
    rec, sim, seconds = run_lorr(inst, sched, planner, steps=args.steps, limit=limit)
    wait, turn, move, per_step = replay(sim)
    total = wait.sum() + turn.sum() + move.sum()
    if total != sim.n_robots * sim.t:  # every robot-step counted once
        raise RuntimeError(f"{total} robot-steps counted, {sim.n_robots * sim.t} run")
    narrow = narrow_cells(sim.blocked, sim.width)
    free = np.flatnonzero(~sim.blocked)
    ranked = np.sort(wait[free])[::-1]
    top = {p: ranked[:max(1, len(free) * p // 100)].sum() / max(wait.sum(), 1) for p in (1, 10)}
    print(f"{inst.name} ({label}), {sim.t} steps, {sim.n_robots} robots, {rec['clock']}: {rec['tasks_finished']} tasks")
    print(f"robot-steps waiting {wait.sum() / total:.1%}, turning {turn.sum() / total:.1%}, moving "
          f"{move.sum() / total:.1%}; waits on narrow cells {wait[narrow].sum() / max(wait.sum(), 1):.1%} "
          f"(narrow cells {narrow.sum() / len(free):.1%} of the free); in the busiest 1 % of the free cells "
          f"{top[1]:.1%}, 10 % {top[10]:.1%}")
    print(f"step s: p50 {rec['step_p50_s']:.3f}, p99 {rec['step_p99_s']:.3f} (scheduler p99 {rec['scheduler_p99_s']:.3f}, "
          f"planner p99 {rec['executor_p99_s']:.3f}); timeouts {rec['timeouts']}")
    done = np.array([e[0] for e in sim.tasks.events], dtype=np.int64)  # the step of each errand reached
    for w in np.array_split(np.arange(sim.t), max(args.windows, 1)):
        if len(w):
            errands = int(((done > w[0]) & (done <= w[-1] + 1)).sum())
            print(f"steps {w[0] + 1}-{w[-1] + 1}: robots waiting {per_step[w].mean() / sim.n_robots:.1%}, "
                  f"errands reached {errands:,}")
    if args.out:
        from mrmt_env.lorr.output import write_output

        print(f"wrote {write_output(sim, args.out)}")
    if args.png:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib.colors import LogNorm

        img = np.ma.masked_where(sim.blocked, wait.astype(float) + 1).reshape(-1, sim.width)
        fig, ax = plt.subplots(figsize=(9, 9 * img.shape[0] / img.shape[1] + 0.8))
        ax.set_facecolor("#222222")
        im = ax.imshow(img, norm=LogNorm(vmin=1, vmax=max(float(img.max()), 2)), cmap="magma", interpolation="nearest")
        fig.colorbar(im, ax=ax, shrink=0.7, label="robot-steps waiting + 1")
        ax.set_title(f"{inst.name}: waits over {sim.t} steps ({label}; {rec['tasks_finished']} tasks)", fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
        fig.tight_layout()
        fig.savefig(args.png, dpi=110, bbox_inches="tight")
        print(f"wrote {args.png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
