"""Cold start: `make demo` on a fresh clone -- install, first (cold) run, second (warm) run.

    flock /tmp/mrmt-bench.lock python benchmarks/cold_start.py [--repo .] [--ref COMMIT ...] [--keep]

Clones the repository's HEAD into a temporary directory (its own ``.venv``, an empty numba cache in
the clone's ``__pycache__`` folders), then times, one after the other: ``make .venv/.base-stamp``
(the pip install of the base package), ``make demo`` (cold: every kernel compiled) and ``make demo``
again (warm: kernels loaded from the cache).  Reports wall seconds, user + sys CPU seconds of the
child processes and their peak RSS.  The warm-up stamp goes to the clone's own ``XDG_CACHE_HOME``,
so the first run announces its compile as a new install would.  From the cold demo's progress bars (one per
compiled part, counting its kernels): the longest wait with no bar moving, and when the first moved.

To load the other core meanwhile (the "loaded" figure): ``python -c "while True: pass" &`` before, ``kill`` its
pid after.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def timed(cmd: list[str], cwd: Path, env: dict) -> dict:
    """Run ``cmd``; wall seconds, and from ``os.wait4`` its own user + sys seconds and peak RSS
    (its waited-for descendants included: make -> mrmt -> workers)."""
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=out, stderr=err, text=True)
        _, status, ru = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        stdout, stderr = out.read(), err.read()
    if proc.returncode:
        sys.exit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{stdout[-2000:]}\n{stderr[-2000:]}")
    return {"wall_s": wall, "cpu_s": ru.ru_utime + ru.ru_stime, "peak_mb": ru.ru_maxrss / 1024, "stderr": stderr}


_BAR = re.compile(r"^compiling ?(\S*?)\s*:.*?(\d+)(?:/\d+| ?kernels?| ?parts?)\s*\[(\d+):(\d\d)")


def stalls(stderr: str) -> tuple[float, float] | None:
    """From the compile bars' lines in ``stderr``: the longest stretch (s) in which no bar's count moved, and the
    seconds before the first moved (tqdm's elapsed field, whole seconds; every bar starts together); ``None`` without
    bars."""
    last: dict[str, int] = {}
    moves = [0.0]
    for line in stderr.replace("\r", "\n").splitlines():
        found = _BAR.search(line.strip())
        if not found:
            continue
        part, n, t = found.group(1), int(found.group(2)), 60 * int(found.group(3)) + int(found.group(4))
        if n != last.get(part, 0):
            moves.append(float(t))
        last[part] = n
    if len(moves) == 1:
        return None
    moves.sort()
    return max(b - a for a, b in zip(moves, moves[1:])), moves[1]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repo", default=str(Path(__file__).resolve().parents[1]), help="repository to clone")
    parser.add_argument("--ref", nargs="+", default=["HEAD"],
                        help="commits to measure one after the other (e.g. an older one and HEAD: a ratio "
                             "measured in one run)")
    parser.add_argument("--keep", action="store_true", help="keep the clones (their paths are printed)")
    args = parser.parse_args(argv)
    for ref in args.ref:
        measure(args.repo, ref, args.keep)
    return 0


def measure(repo: str, ref: str, keep: bool) -> None:
    tmp = Path(tempfile.mkdtemp(prefix="mrmt-cold-"))
    clone = tmp / "clone"
    subprocess.run(["git", "clone", "-q", repo, str(clone)], check=True)
    subprocess.run(["git", "checkout", "-q", ref], cwd=clone, check=True)
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp / "cache")}
    env.pop("NUMBA_CACHE_DIR", None)
    head = subprocess.run(["git", "log", "--oneline", "-1"], cwd=clone, capture_output=True, text=True).stdout.strip()
    print(f"clone of {head}")
    try:
        walls, said = {}, None
        for label, cmd in (("install", ["make", ".venv/.base-stamp"]), ("cold demo", ["make", "demo"]),
                           ("warm demo", ["make", "demo"])):
            r = timed(cmd, clone, env)
            walls[label] = r["wall_s"]
            print(f"{label:10s} wall {r['wall_s']:7.1f} s   user+sys {r['cpu_s']:7.1f} s   peak {r['peak_mb']:6.0f} MB")
            if label == "cold demo":
                notice = [line for line in r["stderr"].replace("\r", "\n").splitlines() if line.startswith("mrmt:")]
                print("  " + (notice[0] if notice else "(no compile notice)"))
                said = re.search(r"roughly (\d+) s", notice[0]) if notice else None
                stall = stalls(r["stderr"])
                if stall:
                    print(f"  progress: the longest wait with no compile bar moving {stall[0]:.0f} s, the first move "
                          f"at {stall[1]:.0f} s")
        if said:  # the compile's own wall: the cold demo's less the warm one's
            compile_s = walls["cold demo"] - walls["warm demo"]
            print(f"the notice said {said.group(1)} s; the compile took {compile_s:.1f} s (cold - warm demo): "
                  f"{100 * (int(said.group(1)) / compile_s - 1):+.0f} %")
    finally:
        if keep:
            print(f"kept {clone}")
        else:
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    raise SystemExit(main())
