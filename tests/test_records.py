"""The library reads its records by name: the house rules of issue 58, checked on the source itself.

A record (a kernel's inputs or result with more than three fields) is read by field name, not by position:
no unpacking of five or more names from one call or record, nor of four or more from an input named as a record
(a kernel's grid, robots, tables handed over as one tuple), no ``out[6]``-style reads of a result. Every
chip call from the planners goes through a machine session, and the QUBO-to-Ising conversion exists once.
"""

from __future__ import annotations

import ast
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
LIBRARY = ("mrmt_env", "ising_backend", "planners", "agents")
#: Names a record goes by in the library (a result, statistics, a program, a state, options ...).
RECORD_NAMES = {"out", "stats", "st", "program", "prog", "state", "result", "res", "record", "rec", "options",
                "machine", "loop", "pool", "tables", "book", "store", "search", "limits", "last", "groups",
                "scratch", "solver", "robot"}
#: Inputs a kernel takes as one tuple (read by name once they hold four or more fields; arrays of the same names,
#: such as a list of robots, may be indexed).
INPUT_NAMES = RECORD_NAMES | {"grid", "robots", "heuristic", "knobs", "ranks", "stamp", "step", "weights", "when"}
#: Reads of a one-row structured statistics record (``stats[0]`` is the record itself, read by field name).
ALLOWED = {("planners/ising/moves/search.py", "stats[0]"), ("planners/ising/tour/selection.py", "stats[0]")}


def _modules(packages=LIBRARY):
    for package in packages:
        for path in sorted((ROOT / package).rglob("*.py")):
            yield path.relative_to(ROOT).as_posix(), ast.parse(path.read_text())


def _gym_step(targets) -> bool:
    """Gymnasium's ``(obs, reward, terminated, truncated, info)``: the field's own five-tuple."""
    return any(t in getattr(n, "id", "") for n in targets for t in ("term", "trunc"))


def positional_reads(modules) -> list[str]:
    """Where a record is read by position: five or more names unpacked from one call or record (not a tuple
    written out, not ``range``, not Gymnasium's step), four or more from a record name, or an integer index into
    a record name."""
    sites = []
    for where, tree in modules:
        for node in ast.walk(tree):
            if isinstance(node, ast.Assign) and isinstance(node.targets[0], ast.Tuple):
                names, value = node.targets[0].elts, node.value
                least = 4 if isinstance(value, ast.Name) and value.id in INPUT_NAMES else 5
                if len(names) < least or isinstance(value, (ast.Tuple, ast.List, ast.GeneratorExp)) or _gym_step(names):
                    continue
                if isinstance(value, ast.Call) and getattr(value.func, "id", "") == "range":
                    continue
                sites.append(f"{where}:{node.lineno}: {len(names)} names from {ast.unparse(value)[:60]}")
            elif (isinstance(node, ast.Subscript) and isinstance(node.ctx, ast.Load)
                  and isinstance(node.value, ast.Name) and node.value.id in RECORD_NAMES
                  and isinstance(node.slice, ast.Constant) and type(node.slice.value) is int
                  and (where, ast.unparse(node)) not in ALLOWED):
                sites.append(f"{where}:{node.lineno}: {ast.unparse(node)}")
    return sites


def test_the_library_reads_its_records_by_name():
    sites = positional_reads(_modules())
    assert not sites, "records read by position:\n" + "\n".join(sites)


@pytest.mark.parametrize("source, count", [
    ("a, b, c, d, e = run(x)", 1),  # five names from one call
    ("a, b, c, d = run(x)", 0),  # four: a small tuple
    ("nbr, cell_of, width, cost = grid", 1),  # four from an input named as a record
    ("fields, rows, far = heuristic", 0),  # three: a small tuple
    ("a, b, c, d, e = 1, 2, 3, 4, 5", 0),  # written out
    ("A, B, C, D, E = range(5)", 0),  # named constants
    ("obs, r, terminated, truncated, info = env.step(a)", 0),  # Gymnasium's step
    ("x = out[6]", 1),
    ("out[0] = 3", 0),  # a write into an array
    ("x = stats[8] + program[2]", 2),
])
def test_the_position_rule_finds_what_it_names(source, count):
    """The rule above, on snippets: it counts reads by position and nothing else."""
    assert len(positional_reads([("snippet.py", ast.parse(source))])) == count


def test_the_planners_reach_machines_only_through_sessions():
    """No ``anneal_batch`` call and no ``last_call`` read outside ``ising_backend``: the session charges the
    ledger, records the audit and answers by the host rule under ``--host-rule``."""
    sites = []
    for where, tree in _modules(("mrmt_env", "planners", "agents")):
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and node.attr in ("anneal_batch", "last_call"):
                sites.append(f"{where}:{node.lineno}: .{node.attr}")
    assert not sites, "\n".join(sites)


def test_one_qubo_to_ising_conversion_in_compiled_code():
    """Every compiled QUBO-to-Ising conversion is ``ising_backend.mapping.numeric.ising_of_qubo`` (the group programs
    of the League planners reach it through ``ising_backend.integer_program``)."""
    converters = []
    for where, tree in _modules():
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef) and "qubo" in node.name and "ising" in node.name:
                compiled = any("njit" in ast.unparse(d) for d in node.decorator_list)
                if compiled:
                    converters.append(f"{where}:{node.name}")
    assert converters == ["ising_backend/mapping/numeric.py:ising_of_qubo"]
