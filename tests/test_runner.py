"""The task runner (agents.runner): order, chunking, errors, and every backend giving the same rows."""

from __future__ import annotations

import os

import pytest

from agents.runner import LOOPBACK_ENV, RunConfig, RunnerError, run_tasks


def _square_plus(x: int, y: int) -> int:
    return x * x + y


def _fails(x: int) -> int:
    if x == 3:
        raise ValueError(f"task {x} refuses")
    return x


TASKS = [(i, 10 * i) for i in range(23)]
EXPECTED = [i * i + 10 * i for i in range(23)]


@pytest.mark.parametrize("chunk", [None, 1, 5, 64])
def test_inline_and_process_keep_task_order(chunk):
    for backend in ("inline", "process"):
        cfg = RunConfig(backend=backend, jobs=2, chunk_size=chunk, progress=False)
        assert run_tasks(_square_plus, TASKS, cfg) == EXPECTED


def test_empty_task_list():
    assert run_tasks(_square_plus, [], RunConfig(progress=False)) == []


def test_a_task_error_reaches_the_caller_with_its_type():
    for backend in ("inline", "process"):
        with pytest.raises(ValueError, match="task 3 refuses"):
            run_tasks(_fails, [(i,) for i in range(6)], RunConfig(backend=backend, jobs=2, progress=False))


@pytest.mark.parametrize("kwargs, match", [
    (dict(backend="threads"), "backend 'threads' is not one of inline, process, ray"),
    (dict(jobs=0), "jobs = 0 must be an integer >= 1"),
    (dict(jobs=1.5), "jobs = 1.5"),
    (dict(chunk_size=0), "chunk_size = 0"),
    (dict(backend="process", address="1.2.3.4:6379"), "only for the ray backend"),
])
def test_bad_settings_are_refused_by_name(kwargs, match):
    with pytest.raises(RunnerError, match=match):
        RunConfig(**kwargs)


def test_from_jobs_keeps_the_n_jobs_convention():
    assert RunConfig.from_jobs(1).backend == "inline"
    assert RunConfig.from_jobs(3).backend == "process"
    assert RunConfig.from_jobs(2, address="127.0.0.1:6379").backend == "ray"
    assert RunConfig.from_jobs(1, backend="process").backend == "process"


def test_default_chunks_are_about_eight_per_worker_and_at_most_64():
    assert RunConfig(jobs=2).chunks(160) == 10
    assert RunConfig(jobs=2).chunks(10_000) == 64
    assert RunConfig(jobs=2).chunks(3) == 1


def test_missing_ray_names_the_install_command(monkeypatch):
    import builtins

    real = builtins.__import__

    def no_ray(name, *args, **kwargs):
        if name == "ray" or name.startswith("ray."):
            raise ImportError("no ray here")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_ray)
    with pytest.raises(RunnerError, match=r"pip install 'mrmt-ising\[distributed\]'"):
        run_tasks(_square_plus, TASKS, RunConfig(backend="ray", progress=False))


def test_ray_backend_matches_the_process_backend():
    """One local Ray instance (loopback only) for every Ray check: task order and errors,
    the evaluation runner and the sweep give the rows the process pool gives."""
    import sys

    from agents.runner import _ray
    from agents.evaluation import evaluate
    from agents.sweep import SweepConfig, run_sweep

    import importlib.util

    if importlib.util.find_spec("ray") is None:
        pytest.skip("Ray is not installed (pip install 'mrmt-ising[distributed]')")
    if "ray" in sys.modules and os.environ.get(LOOPBACK_ENV) != "0":
        # Ray was imported here before the runner could ask for a loopback-only instance: the same test in a
        # fresh interpreter, so it runs whatever the test order
        import subprocess

        proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                               f"{__file__}::test_ray_backend_matches_the_process_backend"],
                              capture_output=True, text=True, env={**os.environ, LOOPBACK_ENV: "0"})
        assert proc.returncode == 0 and " passed" in proc.stdout, proc.stdout[-2000:] + proc.stderr[-2000:]
        return
    # the process-backend references first, before Ray's threads exist in this process
    keys = ("controller", "seed", "world_seed", "route_cost", "makespan", "is_success", "chip_calls",
            "logical_calls", "accelerator_energy_j")
    kw = dict(n_worlds=3, seeds=(0, 1))
    b = evaluate("strong,ising", run=RunConfig.from_jobs(2, progress=False, backend="process"), **kw)
    cfg = SweepConfig(axes={"j_range": ["7", "15"]}, controllers=("ising", "strong"), n_worlds=2)
    sb = run_sweep(cfg, RunConfig(backend="process", jobs=2, progress=False))
    on_ray = RunConfig(backend="ray", jobs=2, chunk_size=4, progress=False)
    ray = _ray()
    # Ray workers import task functions by name: builtins here, package functions below
    assert run_tasks(pow, [(i, 2) for i in range(23)], on_ray) == [i * i for i in range(23)]  # own instance
    assert not ray.is_initialized()
    ray.init(num_cpus=2, include_dashboard=False, object_store_memory=128 * 1024 * 1024, log_to_driver=False)
    try:
        assert ray.get_runtime_context().gcs_address.startswith("127.0.0.1:")  # this machine only
        assert run_tasks(pow, [(i, 3) for i in range(9)], on_ray) == [i ** 3 for i in range(9)]
        with pytest.raises(ValueError, match="invalid literal"):  # the task's own exception type
            run_tasks(int, [("1",), ("2",), ("3x",)], on_ray)

        a = evaluate("strong,ising", run=RunConfig.from_jobs(2, progress=False, backend="ray"), **kw)
        assert [[r[k] for k in keys] for r in a.rows] == [[r[k] for k in keys] for r in b.rows]

        sa = run_sweep(cfg, on_ray)
        # a process pool started while Ray runs here uses a forkserver (no fork of Ray's threads)
        assert run_tasks(pow, [(i, 2) for i in range(6)], RunConfig(backend="process", jobs=2, progress=False)) \
            == [i * i for i in range(6)]
        keys = ("spec_id", "j_range", "controller", "world_seed", "route_cost", "chip_calls", "error")
        assert [[r.get(k) for k in keys] for r in sa.rows] == [[r.get(k) for k in keys] for r in sb.rows]
    finally:
        ray.shutdown()


@pytest.mark.parametrize("argv, match", [
    (["compare", "--seed", "-1"], "--seed must be in [0, 2**63)"),
    (["compare", "--max-steps", "0"], "--max-steps must be >= 1, got 0"),
    (["compare", "--jobs", "0"], "--jobs must be >= 1, got 0"),
    (["compare", "--backend", "process", "--address", "1.2.3.4:6379"], "--address is for --backend ray"),
    (["reproduce", "--quick", "--seed", "-1", "--out", "unused"], "--seed must be in [0, 2**63)"),
    (["reproduce", "--quick", "--jobs", "0", "--out", "unused"], "--jobs must be >= 1, got 0"),
])
def test_runner_options_bad_input_is_one_line_and_exit_2(argv, match, capsys):
    from agents.cli import main

    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and match in err


def test_compare_max_steps_truncates_episodes(tmp_path, capsys):
    import json

    from agents.cli import main

    out = tmp_path / "c"
    assert main(["compare", "--worlds", "1", "--controllers", "strong", "--max-steps", "2", "--jobs", "1",
                 "--no-progress", "--out", str(out)]) == 0
    rows = json.loads((out / "episodes.json").read_text())["rows"]
    assert rows[0]["steps"] == 2 and rows[0]["truncated"] is True


def test_compare_layout_option_plans_on_that_map_family(tmp_path):
    import json

    from agents.cli import main

    out = tmp_path / "c"
    assert main(["compare", "--worlds", "2", "--controllers", "strong", "--layout", "maze", "--height", "15",
                 "--width", "15", "--jobs", "1", "--no-progress", "--out", str(out)]) == 0
    data = json.loads((out / "episodes.json").read_text())
    assert data["config"]["env_kwargs"]["layout"] == "maze"
    assert all(r["is_success"] for r in data["rows"])
