"""Typed options (planners/options.py): every option of every planner refuses a bad value in one line naming the
option, the value and what it takes; an option a planner does not take is named with those it takes."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
import pytest

from agents.lorr.schedulers import SCHEDULERS, make_scheduler, scheduler_options
from planners.mapf import TURNING_PLANNERS, make_turning_planner
from planners.options import Bound, Options, option, record

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
    for name, kind in TURNING_PLANNERS.items():
        for f in fields(kind.Options):
            for bad in bad_values(f.metadata["bound"]):
                yield pytest.param(name, f.name, bad, id=f"{name}-{f.name}-{bad!r}")


@pytest.mark.parametrize("planner, key, bad", list(cases()))
def test_every_bad_option_value_names_the_option_the_value_and_the_limit(planner, key, bad):
    kind = TURNING_PLANNERS[planner]
    allowed = next(f.metadata["bound"] for f in fields(kind.Options) if f.name == key).allowed()
    with pytest.raises(ValueError) as err:
        make_turning_planner(planner, GRID, **{key: bad})
    assert str(err.value) == f"{key} = {bad!r} must be {allowed}"


@pytest.mark.parametrize("planner", list(TURNING_PLANNERS))
def test_defaults_are_valid_and_the_record_is_the_planners(planner):
    kind = TURNING_PLANNERS[planner]
    ex = make_turning_planner(planner, GRID, seed=3)
    assert ex.options == kind.Options() and isinstance(ex.options, Options)
    with pytest.raises(ValueError) as err:
        make_turning_planner(planner, GRID, speed=2)
    names = ", ".join(f.name for f in fields(kind.Options))
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


def test_tuples_mappings_open_bounds_replace_and_resolve():
    @dataclass(frozen=True)
    class Kinds(Options):
        rules: tuple = option(("a",), tuple, words=("a", "b"), none=True)
        shifts: tuple = option((0.5,), tuple)
        table: dict | None = option(None, dict, none=True)
        thing: object = option("x", object)
        gain: float = option(1.0, float, 0, lo_open=True)

    k = Kinds(rules=["a", "b"], shifts=[1, np.float32(0.5)], table={"q": 1}, thing=print, gain=1e-9)
    assert (k.rules, k.shifts, k.table, k.thing) == (("a", "b"), (1.0, 0.5), {"q": 1}, print)
    assert Kinds(rules="b").rules == ("b",) and Kinds(rules=None).rules is None  # one word: a tuple of one
    assert [row[2] for row in Kinds.describe()] == ["a non-empty tuple of a, b or null",
                                                    "a non-empty tuple of finite numbers", "a mapping or null",
                                                    "any value", "a number > 0"]
    for key, bad in (("rules", ("a", "c")), ("rules", ()), ("shifts", (0.5, float("nan"))), ("shifts", (True,)),
                     ("table", [("q", 1)]), ("gain", 0)):
        allowed = next(row[2] for row in Kinds.describe() if row[0] == key)
        with pytest.raises(ValueError) as err:
            Kinds(**{key: bad})
        assert str(err.value) == f"{key} = {bad!r} must be {allowed}"
    assert k.replace(gain=2).gain == 2.0 and k.replace(gain=2).rules == ("a", "b")
    with pytest.raises(ValueError, match=r"^Kinds takes no option 'gian'; its options: rules, shifts, table, thing, "
                                         r"gain$"):
        k.replace(gian=2)
    assert Kinds.resolve() == Kinds() and Kinds.resolve(k, {"gain": 3}) == k.replace(gain=3)
    assert Kinds.resolve(None, None, k) is k
    with pytest.raises(ValueError, match="^config must be a Kinds, got dict$"):
        Kinds.resolve({"gain": 3})


def test_the_options_command_lists_every_planners_options(capsys):
    from agents.cli import main

    assert main(["lorr", "options", "epibt-ising"]) == 0
    lines = capsys.readouterr().out.splitlines()
    described = TURNING_PLANNERS["epibt-ising"].Options.describe()
    assert lines[0] == "epibt-ising:" and len(lines) == 1 + len(described)
    assert lines[-2].startswith("  rounds = 1  (an integer in [1, 4096]) rounds of decisions per call")
    assert lines[-1].startswith("  grow = false  (true or false) groups grow through")
    assert main(["lorr", "options"]) == 0
    out = capsys.readouterr().out
    heads = [line[:-1] for line in out.splitlines() if not line.startswith(" ")]
    assert heads == list(TURNING_PLANNERS) + [f"{n} (scheduler)" for n in SCHEDULERS]
    assert main(["lorr", "options", "cbs"]) == 2
    assert capsys.readouterr().err.strip() == ("mrmt lorr: error: unknown planner 'cbs'; known: "
                                               + ", ".join(TURNING_PLANNERS) + "; schedulers: " + ", ".join(SCHEDULERS))


def test_the_options_command_lists_a_schedulers_options_and_each_is_taken(capsys):
    from agents.cli import main
    from agents.lorr.weighted import WeightedOptions

    assert main(["lorr", "options", "lorr-weighted"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == "lorr-weighted (scheduler):" and len(lines) == 1 + len(WeightedOptions.describe())
    assert "  optimal = false  (true or false) the matching of least total cost" in "\n".join(lines)
    for name in SCHEDULERS:  # every option listed is one the scheduler takes, at its listed default
        keys = {key: default for key, default, _, _ in scheduler_options(name)}
        make_scheduler(name, **keys)
        with pytest.raises(ValueError, match="nonsense"):
            make_scheduler(name, nonsense=1)


@dataclass(frozen=True)
class _Speed(Options):
    speed: int = option(3, int, 1, 9, meaning="how fast")
    mode: str = option("a", str, words=("a", "b"))


@dataclass(frozen=True)
class _Care(Options):
    care: float = option(0.5, float, 0.0, 1.0)
    log: bool = option(False, bool)


def test_a_record_is_the_union_of_its_parts_fields_with_defaults_replaced():
    Both = record("Both", "speed and care.", _Speed, _Care, defaults={"speed": 7, "log": True})
    assert [f.name for f in fields(Both)] == ["speed", "mode", "care", "log"]  # the parts' fields, in order
    assert issubclass(Both, Options) and Both.__name__ == "Both" and Both.__doc__ == "speed and care."
    assert [(name, default, allowed) for name, default, allowed, _ in Both.describe()] == [
        ("speed", 7, "an integer in [1, 9]"), ("mode", "a", "one of a, b"), ("care", 0.5, "a number in [0, 1]"),
        ("log", True, "true or false")]
    assert Both.describe()[0][3] == "how fast"  # a part's meaning kept
    b = Both()
    assert (b.speed, b.mode, b.care, b.log) == (7, "a", 0.5, True)
    assert record("Plain", "", _Speed, _Care)().speed == 3  # without defaults=, the parts' own
    with pytest.raises(ValueError, match=r"^speed = 10 must be an integer in \[1, 9\]$"):
        Both(speed=10)  # a part's bound holds in the record
    with pytest.raises(ValueError, match=r"^both takes no option 'x'; its options: speed, mode, care, log$"):
        Both.from_dict({"x": 1}, "both")
    # .part(cls): the part's own record, of the composed values (a replaced default included)
    c = Both.from_dict({"mode": "b", "care": 0.25}, "both")
    assert c.part(_Speed) == _Speed(speed=7, mode="b") and type(c.part(_Speed)) is _Speed
    assert c.part(_Care) == _Care(care=0.25, log=True) and type(c.part(_Care)) is _Care


def test_a_record_refuses_a_field_declared_twice_and_a_default_of_no_field():
    @dataclass(frozen=True)
    class _Fast(Options):
        speed: int = option(1, int, 0, 5)

    with pytest.raises(ValueError, match=r"^Twice: option 'speed' declared by both _Speed and _Fast$"):
        record("Twice", "", _Speed, _Fast)
    with pytest.raises(ValueError, match=r"^Stray: a default for 'colour', which none of its parts declares$"):
        record("Stray", "", _Speed, _Care, defaults={"speed": 2, "colour": 1})


def test_a_composed_record_bound_in_its_module_pickles():
    import pickle

    import planners.mapf as mapf
    from planners.mapf.epibt.chain_planner import ChainOptions
    from planners.mapf.guides.fields import FieldOptions
    from planners.mapf.guides.focus import FocusOptions

    assert TURNING_PLANNERS["epibt-chain"].Options is mapf.ChainRecord
    assert mapf.ChainRecord.__module__ == "planners.mapf"
    rec = mapf.ChainRecord.from_dict({"lns": 5, "active": 0.5, "corridors": 2}, "epibt-chain")
    back = pickle.loads(pickle.dumps(rec))
    assert back == rec and type(back) is mapf.ChainRecord
    assert rec.part(FocusOptions) == FocusOptions(active=0.5)
    assert rec.part(ChainOptions).lns == 5
    assert rec.part(FieldOptions) == FieldOptions(guidance=0, corridors=2)  # the planner's default guidance, 0
    for name, kind in TURNING_PLANNERS.items():  # every planner's record: bound where it is made, pickles
        rec = kind.Options()
        assert pickle.loads(pickle.dumps(rec)) == rec, name
