"""Typed options (planners/options.py): every option of every planner refuses a bad value in one line naming the
option, the value and what it takes; an option a planner does not take is named with those it takes."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
import pytest

from agents.lorr.schedulers import SCHEDULERS, make_scheduler, scheduler_options
from planners.mapf import TURNING_EXECUTORS
from planners.options import Bound, Options, option

GRID = np.zeros((5, 5), dtype=bool)


def bad_values(b: Bound) -> list:
    """Values the bound refuses, each for a different reason."""
    out = [[1, 2]]
    if b.kind is bool:
        return out + [1, "yes", None] if not b.none else out + [1, "yes"]
    if b.kind is str:
        return out + ["nonsense", 3] + ([] if b.none else [None])
    if b.kind is int:
        out += [1.5, True, "many"]
    else:
        out += [float("nan"), "hot", False]
    if b.lo is not None:
        out.append(b.lo - 1)
    if b.hi is not None:
        out.append(b.hi + 1)
    if not b.none:
        out.append(None)
    return out


def cases():
    for name, cls in TURNING_EXECUTORS.items():
        for f in fields(cls.Options):
            for bad in bad_values(f.metadata["bound"]):
                yield pytest.param(name, f.name, bad, id=f"{name}-{f.name}-{bad!r}")


@pytest.mark.parametrize("planner, key, bad", list(cases()))
def test_every_bad_option_value_names_the_option_the_value_and_the_limit(planner, key, bad):
    cls = TURNING_EXECUTORS[planner]
    allowed = next(f.metadata["bound"] for f in fields(cls.Options) if f.name == key).allowed()
    with pytest.raises(ValueError) as err:
        cls(GRID, **{key: bad})
    assert str(err.value) == f"{key} = {bad!r} must be {allowed}"


@pytest.mark.parametrize("planner", list(TURNING_EXECUTORS))
def test_defaults_are_valid_and_the_record_is_the_planners(planner):
    cls = TURNING_EXECUTORS[planner]
    ex = cls(GRID, seed=3)
    assert ex.options == cls.Options() and isinstance(ex.options, Options)
    with pytest.raises(ValueError) as err:
        cls(GRID, speed=2)
    names = ", ".join(f.name for f in fields(cls.Options))
    assert str(err.value) == f"{planner} takes no option 'speed'; its options: {names}"


def test_bounds_read_values_to_their_plain_type_and_say_what_they_allow():
    @dataclass(frozen=True)
    class Demo(Options):
        n: int = option(3, int, 1, 5, words=("auto",))
        x: float = option(0.5, float, 0.0, 1.0)
        k: int | None = option(None, int, 0, None, none=True)
        w: str = option("a", str, words=("a", "b"))
        b: bool = option(False, bool)

    d = Demo(n=np.int64(4), x=np.float32(0.25), k=7, w="b", b=np.bool_(True))
    assert (d.n, d.x, d.k, d.w, d.b) == (4, 0.25, 7, "b", True)
    assert type(d.n) is int and type(d.x) is float and type(d.b) is bool
    assert Demo(n="auto").n == "auto" and Demo(x=1).x == 1.0
    assert [row[2] for row in Demo.describe()] == ["an integer in [1, 5] or 'auto'", "a number in [0, 1]",
                                                   "an integer >= 0 or null", "one of a, b", "true or false"]
    assert Demo.from_dict({"k": 2}, "demo").k == 2
    with pytest.raises(ValueError, match=r"^demo takes no option 'm'; its options: n, x, k, w, b$"):
        Demo.from_dict({"m": 2}, "demo")


def test_the_options_command_lists_every_planners_options(capsys):
    from agents.cli import main

    assert main(["lorr", "options", "epibt-ising"]) == 0
    lines = capsys.readouterr().out.splitlines()
    described = TURNING_EXECUTORS["epibt-ising"].Options.describe()
    assert lines[0] == "epibt-ising:" and len(lines) == 1 + len(described)
    assert lines[-2].startswith("  rounds = 1  (an integer in [1, 4096]) rounds of decisions per call")
    assert lines[-1].startswith("  grow = false  (true or false) groups grow through")
    assert main(["lorr", "options"]) == 0
    out = capsys.readouterr().out
    heads = [line[:-1] for line in out.splitlines() if not line.startswith(" ")]
    assert heads == list(TURNING_EXECUTORS) + [f"{n} (scheduler)" for n in SCHEDULERS]
    assert main(["lorr", "options", "cbs"]) == 2
    assert capsys.readouterr().err.strip() == ("mrmt lorr: error: unknown planner 'cbs'; known: "
                                               + ", ".join(TURNING_EXECUTORS) + "; schedulers: " + ", ".join(SCHEDULERS))


def test_the_options_command_lists_a_schedulers_options_and_each_is_taken(capsys):
    from agents.cli import main
    from agents.lorr.weighted import WeightedOptions

    assert main(["lorr", "options", "lorr-weighted"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == "lorr-weighted (scheduler):" and len(lines) == 1 + len(WeightedOptions.describe()) + 1
    assert "  optimal = false  (true or false) the matching of least total cost" in "\n".join(lines)
    assert lines[-1].startswith("  busy = 1.0  (a number in (0, 1])")
    for name in SCHEDULERS:  # every option listed is one the scheduler takes, at its listed default
        keys = {key: default for key, default, _, _ in scheduler_options(name)}
        make_scheduler(name, **keys)
        with pytest.raises(ValueError, match="nonsense"):
            make_scheduler(name, nonsense=1)
