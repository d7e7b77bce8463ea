"""One instance of each experiment (paper 6.2.1-6.2.4): every method on one seeded world.

Instance ``i`` uses world seed ``seed + i`` and planner seed ``seed + i`` for every method, so
all methods see the same world and the rows are deterministic (except measured CPU times).
"""

from __future__ import annotations

import math

import numpy as np

from agents.experiments.layers import _warm, make_layer, registry_name
from agents.experiments.records import (_compute_columns, _is_accelerated, _layer_columns, _mapping_of,
                                        _plan_valid)
from planners.compute import stopwatch

def _path_instance(i: int, seed: int, methods, placement: str, chip=None) -> list[dict]:
    from mrmt_env.generation import generate_world

    world = generate_world(seed + i, n_robots=1, n_targets=1, placement=placement)
    start, goal = world.robots[0], world.targets[0]
    bfs_len = int(world.robot_fields[0][goal[0], goal[1]])
    rows = []
    for m in methods:
        solver = make_layer("path", m, chip)
        _warm(("path", m), lambda: make_layer("path", m).find_path(world, start, goal, np.random.default_rng(0)))
        rng = np.random.default_rng(seed + i)
        with stopwatch() as t:
            res = solver.find_path(world, start, goal, rng)
        cpu = t()
        row = {"instance": i, "world_seed": seed + i, "method": m, "success": bool(res.success)}
        row["cost"] = float(res.length) if res.success else math.nan
        row["bfs_length"] = bfs_len
        row.update(_compute_columns(res.compute, cpu, _is_accelerated(res.compute) or m == "ising"))
        row["mapping"] = _mapping_of(res.stats)
        rows.append(row)
    return rows


def _tour_instance(i: int, seed: int, methods, n_targets: int, placement: str, chip=None) -> list[dict]:
    from mrmt_env.generation import generate_world

    world = generate_world(seed + i, n_robots=1, n_targets=n_targets, placement=placement)
    dist = world.distance_matrix
    out = {}
    for m in dict.fromkeys(("brute",) + tuple(methods)):
        solver = make_layer("tour", m, chip)
        _warm(("tour", m), lambda: make_layer("tour", m).solve(dist, np.random.default_rng(0)))
        rng = np.random.default_rng(seed + i)
        with stopwatch() as t:
            res = solver.solve(dist, rng)
        out[m] = (res, t())
    opt = float(out["brute"][0].cost)
    rows = []
    for m in methods:
        res, cpu = out[m]
        cost = float(res.cost)
        ok = bool(np.isfinite(cost)) and res.failure is None
        row = {"instance": i, "world_seed": seed + i, "method": m, "success": ok}
        row["tour_cost"] = cost
        row["optimal_cost"] = opt
        row["cost"] = (100.0 * (cost - opt) / opt if opt > 0 else 0.0) if ok else math.nan
        row.update(_compute_columns(res.compute, cpu, _is_accelerated(res.compute) or m == "ising"))
        row["mapping"] = _mapping_of(res.stats)
        rows.append(row)
    return rows


def _sharing_instance(i: int, seed: int, methods, n_robots: int, n_targets: int, placement: str, pricing: str,
                      chip=None) -> list[dict]:
    from mrmt_env.generation import generate_world

    world = generate_world(seed + i, n_robots=n_robots, n_targets=n_targets, placement=placement)
    dist = world.distance_matrix
    exact_tour = make_layer("tour", "brute")
    rows = []
    for m in methods:
        sharing = make_layer("sharing", m, chip)
        rng = np.random.default_rng(seed + i)
        tour = make_layer("tour", pricing, chip)
        _warm(("sharing", m, pricing), lambda: make_layer("sharing", m).assign(
            dist, n_robots, make_layer("tour", pricing), np.random.default_rng(0)))
        with stopwatch() as t:
            res = sharing.assign(dist, n_robots, tour, rng)
        cpu = t()
        lengths = []
        assigned = sorted(t_ for group in res.assignment for t_ in group)
        ok = assigned == list(range(world.n_targets)) and res.failure is None
        for k, group in enumerate(res.assignment):
            nodes = [k] + [n_robots + int(t_) for t_ in group]
            sub = dist[np.ix_(nodes, nodes)]
            lengths.append(float(exact_tour.solve(sub).cost) if len(group) else 0.0)
        row = {"instance": i, "world_seed": seed + i, "method": m, "success": bool(ok)}
        row["cost"] = float(sum(lengths)) if ok else math.nan
        row["makespan"] = float(max(lengths)) if ok else math.nan
        row["imbalance"] = float(max(lengths) - min(lengths)) if ok else math.nan
        row.update(_compute_columns(res.compute, cpu, _is_accelerated(res.compute) or m == "ising"))
        row["mapping"] = _mapping_of(res.stats)
        rows.append(row)
    best = min((r["cost"] for r in rows if r["success"]), default=math.nan)
    exact = next((r["cost"] for r in rows if r["method"] == "exact" and r["success"]), math.nan)
    for r in rows:
        r["gap_to_best"] = 100.0 * (r["cost"] - best) / best if r["success"] and best > 0 else math.nan
        r["gap_to_exact"] = 100.0 * (r["cost"] - exact) / exact if r["success"] and exact > 0 else math.nan
    return rows


def _endtoend_instance(i: int, seed: int, methods, n_robots: int, n_targets: int, placement: str,
                       chip=None) -> list[dict]:
    from mrmt_env.generation import generate_world
    from agents.evaluation import planner_pipeline
    from planners.pipeline import make_pipeline

    world = generate_world(seed + i, n_robots=n_robots, n_targets=n_targets, placement=placement)
    rows = []
    for m in methods:
        name = registry_name(m)
        if name == "pyvrp":  # the classical peer, stopped by iterations (deterministic)
            from agents.experiments.paper import PYVRP_OPTIONS

            def build():
                return make_pipeline("pyvrp", sharing_options=PYVRP_OPTIONS)
        else:
            def build():
                return make_pipeline(name)
        pipe = planner_pipeline(name, chip) if chip is not None and name != "pyvrp" else build()
        _warm(("pipeline", m), lambda: build().plan(world, seed=0))
        plan = pipe.plan(world, seed=seed + i)
        ok = _plan_valid(world, plan)
        row = {"instance": i, "world_seed": seed + i, "method": m, "success": ok}
        row["cost"] = float(plan.route_cost) if ok else math.nan
        row["makespan"] = float(plan.makespan) if ok else math.nan
        row["imbalance"] = float(plan.imbalance) if ok else math.nan
        row["failure"] = plan.failure or plan.stats.get("invalid")
        row.update(_compute_columns(plan.compute, plan.compute.cpu_s, m == "ising" or _is_accelerated(plan.compute)))
        row.update(_layer_columns(plan))
        rows.append(row)
    strong = next((r["cost"] for r in rows if r["method"] == "strong" and r["success"]), math.nan)
    for r in rows:
        r["gap_to_strong"] = 100.0 * (r["cost"] - strong) / strong if r["success"] and strong > 0 else math.nan
    return rows
