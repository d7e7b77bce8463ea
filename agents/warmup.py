"""Cold start: compile the planners' numba kernels up front, in parallel, and say so once.

:func:`warm` (called by ``mrmt plan``, ``compare``, ``sweep``, ``reproduce`` and ``watch``) announces a long first
compile in one line, then compiles the parts the command needs as pipeline warm-ups on ``jobs`` worker processes,
a progress bar per part; a stamp file remembers which parts are warm. ``mrmt warmup`` compiles every preset.
Design notes: docs/design/cold_start.md#warm-up-parts-bars-notice-and-stamp.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

__all__ = ["parts_for", "cold_parts", "warm", "compile_part", "mark_warm", "PART_SECONDS", "PART_KERNELS", "LONG_S",
           "stamp_path", "probe_seconds", "PROBE_REF_S", "estimate_s", "pace_factor", "count_compiles"]

#: Cold compile seconds of each part on the reference machine, each alone in a fresh process with an empty
#: cache (2 cores, AMD EPYC, 2026-11-29, `python benchmarks/compile_parts.py`; the history: docs/design/cold_start.md).
#: Parts compiled side by side share the anneal and quantization kernels, so the sum over two workers is an
#: upper estimate.
PART_SECONDS = {"ising:sharing": 56, "ising-paper:tour+path": 48, "ising-fleet": 32, "ising:tour+path": 24,
                "lorr:epibt-chain-ising": 23, "lorr:epibt": 16, "lorr:epibt-chain": 13, "lorr:pibt-flow": 10,
                "strong": 9, "lorr:pibt": 6, "exact": 5, "fast": 4}

#: Kernels (numba dispatcher specializations) each part compiles alone with an empty cache, measured beside
#: :data:`PART_SECONDS` (`python benchmarks/compile_parts.py`): the totals of the per-part progress bars.  A part
#: compiled after another in the same worker, or after the other worker cached kernels they share, compiles fewer
#: (its bar is filled when it ends); a part missing here shows a count without a total.
PART_KERNELS = {"ising:sharing": 310, "ising-paper:tour+path": 241, "ising:tour+path": 217, "ising-fleet": 217,
                "strong": 86, "fast": 30}  # 2026-12-07, numba 0.68.1

#: The share of the parts' summed seconds a worker spends when it compiles several: the anneal,
#: quantization and tour kernels they share compile once per worker (measured: one process compiling
#: every part in turn, 263 s for a 391 s sum; a cold `make demo` on 2 workers, 130 s for 196 s).
SHARED_SHARE = 0.67

#: A cold compile shorter than this (all parts together) is not announced nor run apart.
LONG_S = 10

#: :func:`probe_seconds` on the reference machine of :data:`PART_SECONDS`, measured beside them.
PROBE_REF_S = 1.49

# The speed probe: a fresh interpreter's seconds to import numba and compile (no cache) one small kernel with a
# loop, a branch, array arithmetic and a sort -- the compile pipeline every part goes through, at its first use.
_PROBE = """
import time
t0 = time.perf_counter()
import numba
import numpy as np
def probe(a, b):
    s = 0.0
    for i in range(a.shape[0]):
        if a[i] > b:
            s += np.sqrt(a[i]) * 2.0
        else:
            s -= a[i] / (1.0 + b)
    out = np.empty(3)
    out[0] = s
    out[1] = a.sum()
    out[2] = np.argsort(a)[0]
    return out
numba.njit(cache=False)(probe)(np.arange(5.0), 1.0)
print(time.perf_counter() - t0)
"""

_ISING = ("ising", "ising-paper")
_PRESETS = {"fast": ("psa", "nn", "astar"), "strong": ("ssa", "3opt", "astar"), "ising": ("ising", "ising", "field"),
            "ising-paper": ("ising-paper",) * 3, "exact": ("exact", "brute", "bfs"),
            "ising-fleet": ("ising-fleet", "keep", "field")}


def _layers(part: str) -> list[tuple[str, str, str]]:
    """The (sharing, tour, path) registry names whose warm-ups compile ``part``: the Ising sharing part
    warms both presets' sharing (the paper's configuration runs the same kernels, so one worker
    compiles them once)."""
    name, _, side = part.partition(":")
    if side == "sharing":
        return [(preset, "nn", "bfs") for preset in _ISING]
    return [_layer_triple(name, side)]


def _layer_triple(name: str, side: str) -> tuple[str, str, str]:
    if side == "tour+path":
        return "psa", name, _PRESETS[name][2] if name in _PRESETS else name
    return _PRESETS[name] if name in _PRESETS else tuple(name.split("+"))


def parts_for(controllers, max_targets: int | None = None) -> list[str]:
    """The warm-up parts of controller specs (presets and layer triples; learned models have none),
    longest first.  An Ising preset is two parts: the Ising sharing (one part for both presets, whose
    sharing layers run the same kernels) and its tour and path layers; ``ising`` also the fleet search
    it runs above :data:`~planners.pipeline.FLEET_ABOVE` targets, unless the worlds are known to have
    at most ``max_targets`` <= that many (then the fleet search never runs)."""
    from planners.pipeline import FLEET_ABOVE

    fleet = max_targets is None or max_targets > FLEET_ABOVE
    parts: list[str] = []
    for spec in controllers:
        spec = spec.strip()
        if spec in _ISING:
            new = ["ising:sharing", f"{spec}:tour+path"] + (["ising-fleet"] if spec == "ising" and fleet else [])
        elif spec in _PRESETS:
            new = [spec]
        elif spec.startswith("lorr:"):  # a LoRR executor with the start kit's scheduler (mrmt lorr run)
            new = [spec]
        elif spec.count("+") == 2:
            s, t, p = spec.split("+")
            tp = f"{t}:tour+path" if t == p and t in _ISING else f"psa+{t}+{p}"  # a preset's part when it is one
            new = ["ising:sharing" if s in _ISING else None, tp if t in _ISING or p in _ISING else None]
            new = [x for x in new if x] or [spec]
        else:
            new = []
        parts += [x for x in new if x not in parts]
    return sorted(parts, key=lambda x: -PART_SECONDS.get(x, 5))


def _fingerprint() -> str:
    from importlib.metadata import PackageNotFoundError, version

    import numba

    try:
        ours = version("mrmt-ising")
    except PackageNotFoundError:
        ours = "source"
    root = Path(__file__).resolve().parents[1]
    newest = max((p.stat().st_mtime_ns for pkg in ("ising_backend", "planners", "mrmt_env")
                  for p in (root / pkg).rglob("*.py")), default=0)
    key = f"{ours}|{numba.__version__}|{sys.version}|{root}|{newest}|{os.environ.get('NUMBA_CACHE_DIR', '')}"
    return hashlib.sha256(key.encode()).hexdigest()[:16]


def stamp_path() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "mrmt-ising" / "warm.json"


def _stamps() -> dict:
    try:
        data = json.loads(stamp_path().read_text())
        return data if isinstance(data, dict) else {}
    except (OSError, ValueError):
        return {}


def _read_stamp() -> set[str]:
    parts = _stamps().get(_fingerprint(), [])
    return set(parts) if isinstance(parts, list) else set()


def mark_warm(parts) -> None:
    """Record ``parts`` as compiled for this install (what :func:`warm` does after compiling)."""
    _write_stamp(parts)


def _write_stamp(parts) -> None:
    try:
        path = stamp_path()
        path.parent.mkdir(parents=True, exist_ok=True)
        stamps = _stamps()  # other installs (venvs, clones) keep theirs; the newest 32 are kept
        key = _fingerprint()
        merged = sorted(_read_stamp() | set(parts))
        stamps.pop(key, None)
        stamps = dict(list(stamps.items())[-31:]) | {key: merged}
        path.write_text(json.dumps(stamps))
    except OSError:  # a read-only home: the notice shows again next time, nothing else changes
        pass


def cold_parts(controllers, max_targets: int | None = None) -> list[str]:
    """The parts of ``controllers`` (:func:`parts_for`) not yet compiled for this install (as far as the
    stamp knows)."""
    done = _read_stamp()
    return [p for p in parts_for(controllers, max_targets) if p not in done]


def compile_part(part: str, world_kwargs: dict | None = None) -> str:
    """Compile the kernels of warm-up part ``part`` in this process (a pipeline warm-up, or three steps of a LoRR
    run); returns ``part``."""
    if part.startswith("lorr:"):
        from agents.lorr.run import run_lorr
        from mrmt_env.lorr.instance import example_instance_path

        run_lorr(example_instance_path(), "lorr-greedy", part[len("lorr:"):], steps=3)
        return part
    from mrmt_env.generation import generate_world
    from planners.pipeline import make_pipeline

    world = generate_world(0, **(world_kwargs or {}))
    for sharing, tour, path in _layers(part):
        make_pipeline(sharing=sharing, tour=tour, path=path).warmup(world, seed=0)
    return part


def estimate_s(parts, jobs: int) -> float:
    """Seconds ``parts`` take to compile on ``jobs`` workers on the reference machine: their
    :data:`PART_SECONDS` summed times :data:`SHARED_SHARE` over the workers, at least the longest part."""
    secs = [PART_SECONDS.get(p, 5) for p in parts]
    return max(max(secs), SHARED_SHARE * sum(secs) / max(1, jobs))


def probe_seconds(timeout_s: float = 120.0) -> float | None:
    """This machine's pace at compiling: the seconds a fresh interpreter takes to import numba and compile one
    small kernel without a cache (about 1.5 s; :data:`PROBE_REF_S` on the reference machine), or ``None`` when
    the probe could not run (the notice then gives the reference machine's seconds and says so)."""
    try:
        out = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True, timeout=timeout_s,
                             check=True)
        seconds = float(out.stdout.strip().splitlines()[-1])
    except (OSError, subprocess.SubprocessError, ValueError, IndexError):
        return None
    return seconds if seconds > 0 else None


def busy_cores(before: tuple[int, int, int], after: tuple[int, int, int]) -> float:
    """Cores busy between two :func:`cpu_times` readings ``(busy, total, cpus)`` (Linux's ``/proc/stat``)."""
    total = after[1] - before[1]
    return (after[0] - before[0]) / total * after[2] if total > 0 else 0.0


def cpu_times() -> tuple[int, int, int] | None:
    """``(busy, total, cpus)``: the machine's busy and total CPU ticks since boot and its CPU count, from
    ``/proc/stat`` (``None`` where there is none: the notice then assumes no other load)."""
    try:
        lines = Path("/proc/stat").read_text().splitlines()
        ticks = [int(x) for x in lines[0].split()[1:]]
    except (OSError, ValueError, IndexError):
        return None
    idle = ticks[3] + (ticks[4] if len(ticks) > 4 else 0)  # idle and waiting for I/O
    return sum(ticks) - idle, sum(ticks), sum(1 for line in lines if line.startswith("cpu") and line[3:4].isdigit())


def pace_factor(probe_s: float, others: float, jobs: int, cores: int) -> float:
    """How many times the reference machine's seconds ``jobs`` workers take here: the probe's seconds as on an
    idle machine (it had ``min(1, cores / (1 + others))`` of a core beside ``others`` busy cores) against
    :data:`PROBE_REF_S`, times the workers' own share of the cores beside that load."""
    alone = probe_s * min(1.0, cores / (1.0 + others))
    return alone / PROBE_REF_S * max(1.0, (jobs + others) / cores)


def _machine_pace(jobs: int) -> tuple[float, str]:
    """The notice's factor on the reference seconds and its words (the probe, and the other load beside it)."""
    before = cpu_times()
    probe_s = probe_seconds()
    after = cpu_times()
    if probe_s is None:
        return 1.0, "the reference machine's pace"
    others = 0.0 if before is None or after is None else max(busy_cores(before, after) - 1.0, 0.0)  # less the probe
    factor = pace_factor(probe_s, others, jobs, after[2] if after else (os.cpu_count() or 1))
    return factor, f"this machine's pace: {factor:.1f}x, {others:.1f} cores busy with other work"


def warm(controllers, jobs: int = 2, progress: bool = True, world_kwargs: dict | None = None,
         stream=None, force: bool = False, minimum_s: float = LONG_S) -> list[str]:
    """Compile the cold parts of ``controllers`` (all of them with ``force``) on ``jobs`` processes,
    after one line on ``stream`` (default stderr) saying what and why, when they are expected to
    take at least ``minimum_s`` seconds; returns the parts compiled."""
    targets = (world_kwargs or {}).get("n_targets")  # worlds of known size: no part they never run
    targets = targets if isinstance(targets, int) and not isinstance(targets, bool) else None
    todo = parts_for(controllers, targets) if force else cold_parts(controllers, targets)
    if not todo or (not force and sum(PART_SECONDS.get(p, 5) for p in todo) < minimum_s):
        return []  # nothing cold, or a few seconds: compiled on first use, in the process, silently
    stream = sys.stderr if stream is None else stream
    jobs = max(1, min(jobs, len(todo)))
    guess = estimate_s(todo, jobs)
    factor, how = _machine_pace(jobs) if guess >= LONG_S else (1.0, "the reference machine's pace")  # a probe: 1.5 s
    guess *= factor
    print(f"mrmt: compiling the numba kernels of {', '.join(todo)} (first run after install; cached "
          f"afterwards, `mrmt warmup` does it up front): roughly {guess:.0f} s on {jobs} core(s) ({how})",
          file=stream, flush=True)
    kwargs = dict(world_kwargs or {})
    try:
        from ising_backend.audit.record import suspended

        with suspended():  # compiling decides nothing: an open audit records none of it
            _compile_parts(todo, kwargs, jobs, progress, stream)
    except Exception as exc:  # noqa: BLE001 -- the command itself will meet (and report) the same problem
        print(f"mrmt: warm-up stopped ({type(exc).__name__}: {exc}); compiling on first use instead",
              file=stream)
        return []
    _write_stamp(todo)
    return todo


def count_compiles(report):
    """A context manager calling ``report(qualname)`` each time numba compiles a kernel in this process (a
    dispatcher's specialization; loads from numba's on-disk cache are not compiles and are not reported)."""
    from numba.core import event

    class _Compiled(event.Listener):
        def on_start(self, ev):
            pass

        def on_end(self, ev):
            func = getattr(ev.data.get("dispatcher"), "py_func", None)
            report(getattr(func, "__qualname__", "?"))

    return event.install_listener("numba:compile", _Compiled())


def _bars(parts, progress: bool, stream) -> dict:
    """One bar per part (its kernels compiled, out of :data:`PART_KERNELS`), longest part first."""
    from tqdm.auto import tqdm

    width = max(len(p) for p in parts)
    return {p: tqdm(total=PART_KERNELS.get(p), desc=f"compiling {p:<{width}}", unit="kernel", position=k,
                    disable=not progress, file=stream, leave=True, dynamic_ncols=True)
            for k, p in enumerate(parts)}


def _advance(bar, n: int = 1) -> None:
    if bar.total is not None and bar.n + n > bar.total:  # more than alone (another order, another numba)
        bar.total = bar.n + n
    bar.update(n)


def _finish(bar) -> None:
    """A part's bar once the part is compiled: full (kernels it loaded from the other worker's cache count as done)."""
    if bar.total is None:
        bar.total = bar.n
    bar.update(bar.total - bar.n)
    bar.set_postfix_str("done", refresh=True)


_REPORTS = None  # a worker's queue to the parent's bars (set by _start_worker)


def _start_worker(queue) -> None:
    global _REPORTS
    _REPORTS = queue


def _compile_reported(part: str, world_kwargs: dict) -> str:
    """:func:`compile_part` in a worker, each kernel compiled reported to the parent as ``part``."""
    with count_compiles(lambda _name: _REPORTS.put(part)):
        return compile_part(part, world_kwargs)


def _compile_parts(todo, world_kwargs: dict, jobs: int, progress: bool, stream) -> None:
    """Compile ``todo`` on ``jobs`` processes (in this one for a single job), with :func:`_bars`."""
    bars = _bars(todo, progress, stream)
    try:
        if jobs == 1:
            for part in todo:
                with count_compiles(lambda _name, bar=bars[part]: _advance(bar)):
                    compile_part(part, world_kwargs)
                _finish(bars[part])
            return
        _compile_in_workers(todo, world_kwargs, jobs, bars)
    finally:
        for bar in reversed(list(bars.values())):
            bar.close()


def _compile_in_workers(todo, world_kwargs: dict, jobs: int, bars: dict) -> None:
    import multiprocessing
    import queue as queues
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    # as agents.runner: workers from a clean forkserver once Ray's threads run in this process
    context = multiprocessing.get_context("forkserver") if "ray" in sys.modules else multiprocessing.get_context()
    reports = context.Queue()
    finished: set[str] = set()

    def drain() -> None:
        while True:
            try:
                part = reports.get_nowait()
            except queues.Empty:
                return
            if part not in finished:  # a late report of a part already shown full
                _advance(bars[part])

    with ProcessPoolExecutor(max_workers=jobs, mp_context=context, initializer=_start_worker,
                             initargs=(reports,)) as pool:
        futures = {pool.submit(_compile_reported, p, world_kwargs): p for p in todo}
        pending = set(futures)
        try:
            while pending:
                done, pending = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
                drain()
                for future in done:
                    future.result()  # a worker's error stops the warm-up (warm reports it)
                    finished.add(futures[future])
                    _finish(bars[futures[future]])
        except BaseException:
            pool.shutdown(wait=True, cancel_futures=True)
            raise
