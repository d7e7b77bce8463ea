"""One task runner for ``mrmt compare``, ``reproduce`` and ``sweep``.

:func:`run_tasks` calls ``fn(*args)`` for every ``args`` in ``tasks`` and returns the results **in task order**,
on the backend ``inline``, ``process`` (a local process pool) or ``ray`` (a local instance on 127.0.0.1, or a
cluster at ``address``); ``fn`` must be a module-level function and the arguments picklable. Results do not depend
on the backend, the workers or the chunking. Design notes: docs/design/runner.md#the-backends-and-the-contract.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from typing import Callable, Sequence

__all__ = ["BACKENDS", "RunConfig", "RunnerError", "run_tasks"]

BACKENDS = ("inline", "process", "ray")

#: Install hint for the Ray backend.
RAY_HINT = "pip install 'mrmt-ising[distributed]' (or: pip install 'ray>=2.9')"


class RunnerError(ValueError):
    """A bad runner setting, or a backend that is not installed."""


@dataclass(frozen=True)
class RunConfig:
    """Where and how tasks run: backend, workers, Ray address, chunking, progress bar."""

    backend: str = "process"
    jobs: int = 2
    address: str | None = None
    chunk_size: int | None = None
    progress: bool = True

    def __post_init__(self):
        if self.backend not in BACKENDS:
            raise RunnerError(f"backend {self.backend!r} is not one of {', '.join(BACKENDS)}")
        if isinstance(self.jobs, bool) or int(self.jobs) != self.jobs or self.jobs < 1:
            raise RunnerError(f"jobs = {self.jobs!r} must be an integer >= 1")
        if self.chunk_size is not None and (int(self.chunk_size) != self.chunk_size or self.chunk_size < 1):
            raise RunnerError(f"chunk_size = {self.chunk_size!r} must be an integer >= 1 or None")
        if self.address is not None and self.backend != "ray":
            raise RunnerError(f"address {self.address!r} is only for the ray backend, not {self.backend!r}")

    @classmethod
    def from_jobs(cls, jobs: int, progress: bool = True, backend: str | None = None, address: str | None = None):
        """The historical ``n_jobs`` convention: 1 runs inline, more use a process pool."""
        if backend is None:
            backend = "ray" if address else ("inline" if int(jobs) == 1 else "process")
        return cls(backend=backend, jobs=int(jobs), address=address, progress=progress)

    def chunks(self, n: int) -> int:
        """Tasks per chunk for ``n`` tasks."""
        if self.chunk_size is not None:
            return int(self.chunk_size)
        return max(1, min(64, math.ceil(n / (8 * self.jobs))))


def _run_chunk(fn: Callable, chunk: Sequence[tuple]) -> list:
    return [fn(*args) for args in chunk]


def run_tasks(fn: Callable, tasks: Sequence[tuple], config: RunConfig | None = None,
              desc: str = "tasks", unit: str = "task") -> list:
    """``[fn(*t) for t in tasks]`` on the configured backend (see the module docstring)."""
    from tqdm.auto import tqdm

    config = config or RunConfig()
    tasks = [tuple(t) for t in tasks]
    if not tasks:
        return []
    size = config.chunks(len(tasks))
    chunks = [tasks[i:i + size] for i in range(0, len(tasks), size)]
    bar = tqdm(total=len(tasks), desc=desc, unit=unit, disable=not config.progress, file=sys.stderr)
    try:
        if config.backend == "inline":
            parts = []
            for chunk in chunks:
                parts.append(_run_chunk(fn, chunk))
                bar.update(len(chunk))
        elif config.backend == "process":
            parts = _run_process(fn, chunks, config, bar)
        else:
            parts = _run_ray(fn, chunks, config, bar)
    finally:
        bar.close()
    return [r for part in parts for r in part]


def _run_process(fn, chunks, config: RunConfig, bar) -> list:
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    # Forking a process that runs Ray's (gRPC) threads can deadlock the child: once Ray has been
    # imported here, workers come from a clean forkserver instead of a fork of this process.
    context = multiprocessing.get_context("forkserver") if "ray" in sys.modules else None
    with ProcessPoolExecutor(max_workers=config.jobs, mp_context=context) as pool:
        futures = {pool.submit(_run_chunk, fn, chunk): k for k, chunk in enumerate(chunks)}
        parts: list = [None] * len(chunks)
        for fut in as_completed(futures):
            k = futures[fut]
            parts[k] = fut.result()
            bar.update(len(chunks[k]))
    return parts


#: Ray reads this when imported: "0" makes a local instance use the loopback address, so its
#: GCS, raylet and workers listen on 127.0.0.1 only (measured with ``ss -ltn``; without it they
#: listen on every interface).  A user's own setting is kept.
LOOPBACK_ENV = "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"


def _ray(local: bool = True):
    import os

    if local and "ray" not in sys.modules:
        os.environ.setdefault(LOOPBACK_ENV, "0")
    try:
        import ray
    except ImportError:
        raise RunnerError(f"the ray backend needs Ray, which is not installed: {RAY_HINT}") from None
    return ray


def _run_ray(fn, chunks, config: RunConfig, bar) -> list:
    ray = _ray(local=not config.address)
    started = False
    if not ray.is_initialized():
        import logging

        if config.address:
            ray.init(address=config.address, logging_level=logging.WARNING, log_to_driver=False)
        else:  # a private local instance: loopback only, no dashboard, a small object store
            ray.init(num_cpus=config.jobs, include_dashboard=False, object_store_memory=256 * 1024 * 1024,
                     logging_level=logging.WARNING, log_to_driver=False)
        started = True
    try:
        remote = ray.remote(num_cpus=1, max_retries=0)(_run_chunk)
        refs = [remote.remote(fn, chunk) for chunk in chunks]
        index = {ref: k for k, ref in enumerate(refs)}
        pending = list(refs)
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                bar.update(len(chunks[index[ref]]))
        return ray.get(refs)
    except ray.exceptions.RayTaskError as exc:  # re-raise the task's own exception
        cause = exc.as_instanceof_cause()
        raise cause from None
    finally:
        if started:
            ray.shutdown()
