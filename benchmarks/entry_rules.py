"""The LoRR entry's rules on generated instances: shape table, instances, and entry-vs-start-kit runs.

    python benchmarks/entry_rules.py shapes                       # the corridor share of the 2024 maps and families
    python benchmarks/entry_rules.py generate --out DIR           # 4 families x 4 densities, 64x64, seed 0
    python benchmarks/entry_rules.py generate --out DIR --families maze,maze32 --densities 20,45,75
    python benchmarks/entry_rules.py run --out DIR [--entry E] [--steps 200] [--only NAME,...] [--config C,...]
                                         [--clock rules]
    python benchmarks/entry_rules.py table --out DIR [--entry E] [--png FILE]

``--only`` runs the instances named, in that order.  ``run`` appends one JSON line per (instance, configuration) to ``DIR/runs.jsonl`` and skips those already there.
Configurations: ``entry`` (``--entry``, default: the package's ``default``), ``default`` (the start kit's default
entry: ``lorr-greedy`` + ``pibt-flow``, no options), ``rule:FILE.toml#N`` (rule N's choice of an entry file, forced), ``cand:NAME`` (a choice of :data:`CANDIDATES`,
given by options: the maze's candidates).
Every run is work-bounded (no clock: deterministic) unless ``--clock rules`` (the start kit's clock, 1 s a step: a
late decision costs timeouts; how results are judged, but it depends on the machine's load, recorded as ``load``),
seed 0, one process; a portfolio's plans run on one thread (``threads = 1``: plans do not depend on it).
``maze32`` and the like are the family at 32x32 (names ``G-maze32-<pct>``).  Generated maps are named ``G-<family>-<pct>`` so that no glob on a
map's name (``warehouse*``) matches them.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mrmt_env.lorr.generate import family_grid, generate_instance  # noqa: E402
from mrmt_env.lorr.instance import read_instance  # noqa: E402
from mrmt_env.lorr.shape import corridor_share, narrow_share  # noqa: E402

MAIN_2024 = ROOT.parent / "shared" / "lorr" / "2024-main"  # ../shared beside the checkout
FAMILIES = {"uniform": "family:uniform:64x64", "warehouse": "family:warehouse:64x64:aisle_width=1",
            "rooms": "family:rooms:64x64", "maze": "family:maze:64x64"}
FAMILIES.update({f"{k}32": v.replace("64x64", "32x32") for k, v in list(FAMILIES.items())})
DENSITIES = (5, 20, 45, 75)  # robots, per cent of the free cells

#: Choices given by options (``cand:NAME``): (scheduler, planner, run_lorr options).  The dense maze's candidates.
CANDIDATES = {
    # the corridors rule's choice (default.toml's min_corridors = 0.4)
    "B": ("lorr-weighted", "epibt", {"guidance": 0, "scheduler_options": {"jam": 4},
                                      "executor_options": {"flow": False, "corridors": 8}}),
    # the city's rule
    "C": ("lorr-weighted", "epibt", {"executor_options": {"flow": False, "congestion": 2}}),
    # B with 30 % of the team at work, those of least task still to go
    "B-active": ("lorr-weighted", "epibt", {"guidance": 0, "scheduler_options": {"jam": 4},
                                             "executor_options": {"flow": False, "corridors": 8, "active": 0.3,
                                                                  "active_by": "task"}}),
    # the GAME rule (the last, unconditioned)
    "game": ("lorr-greedy", "epibt", {"guidance": 8, "scheduler_options": {"way": 5},
                                       "executor_options": {"flow": False, "congestion": 2, "active": 0.3,
                                                            "active_by": "task", "weight_power": 2}}),
    # PIBT on goal fields keeping its claims (the start kit's commits) without the flow guide paths
    "pibt-commits": ("lorr-greedy", "pibt", {"guidance": 0, "executor_options": {"commits": True}}),
    # (the start kit's default with a share of the team holding tasks, option busy: measured at c199dab on the dense
    # mazes, 13 / 8 tasks with busy=0.5 against the default's 13 / 2; the option left the library at a346b00)
    # the winner's push chains on plain distances, every robot at work (no lanes: a maze has no room for them)
    "chain": ("lorr-weighted", "epibt-chain", {"guidance": 0, "executor_options": {"portfolio": 2}}),
}


def shapes() -> None:
    rows = []
    for m in sorted(MAIN_2024.glob("*/*.json")):
        inst = read_instance(m)
        t = time.perf_counter()
        c = corridor_share(inst.grid)
        dt = time.perf_counter() - t
        free = int((~inst.grid).sum())
        rows.append((inst.name, inst.map_name, inst.grid.shape, inst.grid.size, free, inst.team_size,
                     inst.team_size / free, c, dt))
    for fam in ("uniform", "warehouse", "warehouse:aisle_width=1", "rooms", "maze"):
        name, _, opts = fam.partition(":")
        for size in (32, 64, 128):
            g = family_grid(f"family:{name}:{size}x{size}" + (f":{opts}" if opts else ""), np.random.default_rng(0))
            rows.append((f"{fam} {size}x{size}", "-", g.shape, g.size, int((~g).sum()), None, None,
                         corridor_share(g), None))
    print(f"{'map':34s} {'file':22s} {'cells':>7s} {'free':>6s} {'team':>6s} {'fill':>6s} {'corridors':>9s} {'ms':>6s}")
    for name, mp, shape, cells, free, team, fill, c, dt in rows:
        print(f"{name:34s} {mp:22s} {cells:7d} {free:6d} {'-' if team is None else team:>6} "
              f"{'-' if fill is None else f'{fill:.3f}':>6s} {c:9.3f} {'-' if dt is None else f'{dt * 1e3:.1f}':>6s}")


def generate(out: Path, families=None, densities=DENSITIES) -> None:
    out.mkdir(parents=True, exist_ok=True)
    for fam in families or [f for f in FAMILIES if not f.endswith("32")]:
        spec = FAMILIES[fam]
        g = family_grid(spec, np.random.default_rng(0))  # generate_instance draws the same map from the seed first
        free = int((~g).sum())
        for pct in densities:
            n = round(free * pct / 100)
            path = out / f"G-{fam}-{pct:02d}.json"
            if not path.exists():
                generate_instance(spec, n, path, seed=0)
            print(path, n, "robots")


def _config(name: str, entry, inst):
    """``(scheduler spec, planner spec, rule)`` of configuration ``name`` on ``inst``."""
    from agents.lorr.spec import specs_from_options

    if name == "entry":
        c = entry.choose(inst)
        return c.scheduler, c.planner, c.rule
    if name == "default":
        return (*specs_from_options("lorr-greedy", "pibt-flow", None), None)
    if name.startswith("rule:"):
        from agents.lorr.entry import load_entry
        path, _, n = name[5:].partition("#")
        c = load_entry(path).rules[int(n) - 1].choice
        return c.scheduler, c.planner, int(n)
    if name.startswith("cand:"):
        scheduler, planner, options = CANDIDATES[name[5:]]
        return (*specs_from_options(scheduler, planner, json.loads(json.dumps(options))), None)
    raise SystemExit(f"unknown configuration {name!r}")


def run(out: Path, entry_spec: str, steps: int, only, configs, clock: str = "") -> None:
    import os

    from agents.lorr.entry import load_entry
    from agents.lorr.run import run_lorr
    from agents.lorr.spec import PlannerSpec
    from mrmt_env.lorr.clock import step_limit

    limit = step_limit(clock) if clock else None
    label = limit.label() if limit else "work-bounded"

    entry = load_entry(entry_spec)
    log = out / "runs.jsonl"
    done = set()
    if log.exists():
        for line in log.read_text().splitlines():
            r = json.loads(line)
            done.add((r["instance"], r["config"], r["steps"], r.get("clock", "work-bounded")))
    paths = [out / f"{name}.json" for name in only] if only else sorted(out.glob("G-*.json"))
    for path in paths:
        inst = read_instance(path)
        for cfg in configs:
            if (inst.name, cfg, steps, label) in done:
                continue
            scheduler, planner, rule = _config(cfg, entry, inst)
            if planner.name.startswith("epibt"):
                planner = PlannerSpec.of(planner.name, {**planner.given, "threads": 1})
            load = os.getloadavg()[0]
            t = time.perf_counter()
            rec, _, _ = run_lorr(inst, scheduler, planner, steps=steps, seed=0, limit=limit)
            row = {"instance": inst.name, "config": cfg, "entry": entry_spec if cfg == "entry" else None,
                   "rule": rule, "scheduler": scheduler.name, "planner": planner.name,
                   "options": {"scheduler": scheduler.options, "planner": planner.given}, "steps": steps, "robots": inst.team_size,
                   "fill": inst.team_size / int((~inst.grid).sum()), "corridors": corridor_share(inst.grid),
                   "narrow": narrow_share(inst.grid), "tasks": rec["tasks_finished"], "errors": rec["errors"],
                   "clock": rec["clock"], "timeouts": rec["timeouts"], "load": load,
                   "seconds": time.perf_counter() - t}
            with log.open("a") as f:
                f.write(json.dumps(row) + "\n")
            print(json.dumps(row), flush=True)


def table(out: Path, config: str, png: Path | None = None) -> None:
    """The entry's (``config``'s) tasks beside the default's per instance, the ratios at the two densest densities
    and, with ``png``, the figure (tasks per instance, both configurations, log scale)."""
    rows = [json.loads(x) for x in (out / "runs.jsonl").read_text().splitlines()]
    by = {(r["instance"], r["config"]): r for r in rows}
    print(f"| instance | family | robots | fill | corridors | rule ({config}) | {config} tasks | default tasks | ratio | clock |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---|")
    pairs = []
    for name in sorted({r["instance"] for r in rows}, key=lambda n: (n.split("-")[1], n)):
        e, d = by.get((name, config)), by.get((name, "default"))
        if not e or not d:
            continue
        pairs.append((name, e, d))
        ratio = e["tasks"] / d["tasks"] if d["tasks"] else float("inf")
        print(f"| {name} | {name.split('-')[1]} | {e['robots']:,} | {e['fill']:.2f} | {e['corridors']:.3f} | "
              f"{e['rule']} | {e['tasks']:,} | {d['tasks']:,} | {ratio:.2f} | {e['clock']}, {e['timeouts']} / "
              f"{d['timeouts']} timeouts |")
    pct = sorted({int(n.rsplit("-", 1)[1]) for n, _, _ in pairs})
    dense = [(e, d) for n, e, d in pairs if int(n.rsplit("-", 1)[1]) in pct[-2:]]
    if dense:
        ratios = [e["tasks"] / d["tasks"] for e, d in dense if d["tasks"]]
        print(f"\nDensest two densities ({', '.join(f'{p} %' for p in pct[-2:])}): {config} "
              f"{sum(e['tasks'] for e, _ in dense):,} tasks against the default's {sum(d['tasks'] for _, d in dense):,} "
              f"({sum(e['tasks'] for e, _ in dense) / max(sum(d['tasks'] for _, d in dense), 1):.2f}x; mean of the "
              f"ratios {sum(ratios) / max(len(ratios), 1):.2f}x over {len(ratios)} with a default task); below the "
              f"default: {', '.join(n for n, e, d in pairs if e['tasks'] < d['tasks']) or 'none'}")
    if png and pairs:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        x = np.arange(len(pairs))
        fig, ax = plt.subplots(figsize=(max(6, 0.55 * len(pairs)), 4))
        ax.bar(x - 0.2, [e["tasks"] + 1 for _, e, _ in pairs], 0.4, label=f"{config} (the package's rules)")
        ax.bar(x + 0.2, [d["tasks"] + 1 for _, _, d in pairs], 0.4, label="the start kit's default")
        ax.set_yscale("log")
        ax.set_xticks(x, [n[2:] for n, _, _ in pairs], rotation=60, ha="right", fontsize=8)
        ax.set_ylabel("tasks finished + 1")
        ax.set_title(f"Generated instances: {pairs[0][1]['steps']} steps, {pairs[0][1]['clock']}", fontsize=9)
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(png, dpi=110)
        print(f"wrote {png}")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("what", choices=("shapes", "generate", "run", "table"))
    ap.add_argument("--out", type=Path, default=Path("entry-rules"))
    ap.add_argument("--entry", default="default")
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--only", default="")
    ap.add_argument("--config", default="entry,default")
    ap.add_argument("--clock", default="", help="'rules' (the start kit's 1 s a step); default: work-bounded")
    ap.add_argument("--families", default="", help="generate: families of FAMILIES (default: the four at 64x64)")
    ap.add_argument("--densities", default="", help="generate: per cent of the free cells (default: 5,20,45,75)")
    ap.add_argument("--png", type=Path, default=None, help="table: the figure")
    a = ap.parse_args(argv)
    if a.what == "shapes":
        shapes()
    elif a.what == "generate":
        generate(a.out, list(filter(None, a.families.split(","))),
                 tuple(int(x) for x in a.densities.split(",")) if a.densities else DENSITIES)
    elif a.what == "run":
        run(a.out, a.entry, a.steps, list(filter(None, a.only.split(","))), a.config.split(","), a.clock)
    else:
        table(a.out, a.config.split(",")[0], a.png)


if __name__ == "__main__":
    main()
