"""The 2024 record holder's own code beside the package's entry, on this machine, fairly configured (issue 80, item 6).

The 2024 winner (team No Man's Sky) published its code with its history: github.com/Straple/LORR24, the submission
of the main round's random maps at commit ``960d359`` ("submit P+S for random", start kit v2.1.0 inside).  Nothing of
it is in this repository: ``build`` exports that commit from the user's clone into ``--build-dir``, sets its thread
count (``THREADS`` in ``Solution/settings.hpp``, 32 as submitted) to this machine's cores, and builds it with its
own CMake (``cmake``, a C++17 compiler, Boost and spdlog: ``apt-get install cmake g++ libboost-all-dev
libspdlog-dev``).  ``run`` plays each instance in full (or ``--steps``) under the start kit's own clock (``-t 1000``
ms a step, 30 min of preprocessing), its output re-simulated by ``mrmt_env.lorr.output.check_output`` (the tasks
counted there, not read from the output's claim), beside the package's entry (``mrmt lorr run --entry default
--step-limit rules``) over ``--seeds`` seeds; rows go to ``--out``/rows.jsonl (``--resume`` keeps those there) and the
table to stdout (``--write``: RESULTS.md).  Run nothing else beside it.

    git clone https://github.com/Straple/LORR24 ../LORR24
    python benchmarks/record_holder.py build --checkout ../LORR24
    python benchmarks/record_holder.py run RANDOM-01 RANDOM-02 RANDOM-03 RANDOM-04 RANDOM-05 --seeds 3 --resume
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import cpu_name, finish, lorr_run_json  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
MAIN_2024 = ROOT.parent / "shared" / "lorr" / "2024-main"
SECTION = "## The record holder's code beside the entry, on this machine (issue 80)"
COMMIT = "960d359"
THREADS = re.compile(r"(static constexpr uint32_t THREADS = )(\d+);")


def build(checkout: Path, build_dir: Path, commit: str = COMMIT, threads: int | None = None) -> Path:
    """The record holder's ``lifelong`` binary built from ``commit`` of ``checkout`` with ``threads`` threads
    (default: this machine's cores) under ``build_dir``; its recipe in ``build_dir/build.json``."""
    threads = threads or os.cpu_count() or 1
    src = build_dir / "src"
    src.mkdir(parents=True, exist_ok=True)
    archive = subprocess.run(["git", "-C", str(checkout), "archive", commit], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(src)], input=archive, check=True)
    settings = src / "Solution" / "settings.hpp"
    text = settings.read_text()
    if not THREADS.search(text):
        raise SystemExit(f"{settings}: no 'static constexpr uint32_t THREADS = N;' to set (commit {commit})")
    settings.write_text(THREADS.sub(rf"\g<1>{threads};", text))
    subprocess.run(["cmake", "-B", "build", "./", "-DPYTHON=false", "-DCMAKE_BUILD_TYPE=Release"], cwd=src, check=True)
    subprocess.run(["make", "-C", "build", f"-j{threads}", "lifelong"], cwd=src, check=True)
    binary = src / "build" / "lifelong"
    (build_dir / "build.json").write_text(json.dumps({"commit": commit, "threads": threads, "binary": str(binary),
                                                      "cpu": cpu_name(), "cores": os.cpu_count()}))
    return binary


def play(binary: Path, instance: Path, steps: int) -> dict:
    """The binary's run of ``instance`` for ``steps`` steps under the start kit's clock: its tasks as the package
    re-simulates its output, the tasks it claims, and its timeouts."""
    from mrmt_env.lorr.instance import read_instance
    from mrmt_env.lorr.output import check_output, read_output

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "output.json"
        subprocess.run([str(binary), "-i", str(instance.resolve()), "-o", str(out), "-s", str(steps), "-t", "1000",
                        "-p", "1800000", "-l", str(Path(tmp) / "log")], check=True, capture_output=True,
                       cwd=binary.parent.parent)
        data = read_output(out)
    checked = check_output(read_instance(instance), data, str(out))
    return {"tasks": checked.tasks_finished, "claimed": data.get("numTaskFinished"), "timeouts": checked.timeouts,
            "errors": checked.errors}


def instance_path(name: str) -> Path:
    """``name`` as a path: a file given, or a 2024 main-round instance by name (``RANDOM-04``)."""
    p = Path(name)
    if p.suffix == ".json" and p.exists():
        return p
    found = sorted(MAIN_2024.glob(f"*/{name}.json"))
    if not found:
        raise SystemExit(f"no instance {name!r}: give a path or a name of {MAIN_2024}")
    return found[0]


def run(names: list[str], build_dir: Path, out: Path, seeds: int, steps: int | None, resume: bool) -> list[dict]:
    from mrmt_env.lorr.instance import read_instance

    recipe = json.loads((build_dir / "build.json").read_text())
    out.mkdir(parents=True, exist_ok=True)
    log = out / "rows.jsonl"
    rows = [json.loads(x) for x in log.read_text().splitlines()] if resume and log.exists() else []
    if not resume:
        log.write_text("")
    done = {(r["instance"], r["who"], r["seed"], r["steps"]) for r in rows}
    for name in names:
        path = instance_path(name)
        n = steps or read_instance(path).steps
        todo = [("record holder", 0)] + [("entry", s) for s in range(seeds)]
        for who, seed in todo:
            if (path.stem, who, seed, n) in done:
                continue
            if who == "record holder":
                r = play(Path(recipe["binary"]), path, n)
                row = {"threads": recipe["threads"], "commit": recipe["commit"], **r}
            else:
                rec = lorr_run_json(path, "--entry", "default", "--step-limit", "rules", "--steps", str(n),
                                    "--seed", str(seed))
                row = {"tasks": rec["tasks_finished"], "timeouts": rec["timeouts"], "errors": rec["errors"],
                       "threads": os.cpu_count()}
            row = {"instance": path.stem, "who": who, "seed": seed, "steps": n, "cpu": cpu_name(), **row}
            rows.append(row)
            with log.open("a") as f:
                f.write(json.dumps(row) + "\n")
            print(json.dumps(row), flush=True)
    return rows


def table(rows: list[dict]) -> list[str]:
    """One line per instance and steps: the record holder's tasks, the entry's per seed and mean, their ratio."""
    from agents.lorr.scores import best_known
    from mrmt_env.lorr.instance import read_instance

    lines = ["| instance | steps | record holder (threads) | entry, per seed | entry mean | entry / record holder "
             "| best-known |", "|---|---:|---:|---|---:|---:|---:|"]
    for inst, n in sorted({(r["instance"], r["steps"]) for r in rows}):
        rh = [r for r in rows if (r["instance"], r["steps"], r["who"]) == (inst, n, "record holder")]
        en = sorted((r for r in rows if (r["instance"], r["steps"], r["who"]) == (inst, n, "entry")),
                    key=lambda r: r["seed"])
        mean = sum(r["tasks"] for r in en) / len(en) if en else None
        ratio = f"{mean / rh[0]['tasks']:.3f}" if rh and en and rh[0]["tasks"] else ""
        best = best_known(read_instance(instance_path(inst)))
        holder = f"{rh[0]['tasks']:,} ({rh[0]['threads']})" if rh else ""
        seeds = " / ".join(f"{r['tasks']:,}" for r in en)
        mean_s = "" if mean is None else f"{mean:,.1f}"
        lines.append(f"| {inst} | {n:,} | {holder} | {seeds} | {mean_s} | {ratio} | {best or ''} |")
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="what", required=True)
    b = sub.add_parser("build", help="build the record holder's code from a clone")
    b.add_argument("--checkout", type=Path, required=True, help="a clone of github.com/Straple/LORR24")
    b.add_argument("--commit", default=COMMIT)
    b.add_argument("--threads", type=int, default=None, help="default: this machine's cores")
    r = sub.add_parser("run", help="play instances: the record holder's code and the entry")
    r.add_argument("instances", nargs="+", help="paths, or 2024 main-round names (RANDOM-04)")
    r.add_argument("--seeds", type=int, default=3, help="the entry's seeds (the record holder's code has its own)")
    r.add_argument("--steps", type=int, default=None, help="default: each instance's simulation time (in full)")
    r.add_argument("--out", type=Path, default=Path("runs/record-holder"))
    r.add_argument("--resume", action="store_true")
    r.add_argument("--write", action="store_true", help="put the table into RESULTS.md")
    for p in (b, r):
        p.add_argument("--build-dir", type=Path, default=Path("runs/record-holder-build"))
    args = ap.parse_args(argv)
    if args.what == "build":
        print(build(args.checkout, args.build_dir, args.commit, args.threads))
        return 0
    rows = run(args.instances, args.build_dir, args.out, args.seeds, args.steps, args.resume)
    recipe = json.loads((args.build_dir / "build.json").read_text())
    head = [SECTION, "", f"`python benchmarks/record_holder.py run {' '.join(args.instances)} --seeds {args.seeds}"
            f"{f' --steps {args.steps}' if args.steps else ''}` on {cpu_name()} ({os.cpu_count()} cores): the record "
            f"holder's code at {recipe['commit']} with {recipe['threads']} threads, the entry (`--entry default`) with "
            f"its own (one plan a core), both under the start kit's 1 s clock; tasks as re-simulated from each output.",
            ""]
    finish(SECTION, head + table(rows), args.write)
    return 0


if __name__ == "__main__":
    sys.exit(main())
