"""The library's size, counted as a reader meets it: code lines, docstring lines, comment lines and blank lines apart,
modules and compiled functions, per top-level package (issue 58, item 7).

A docstring line is a line of a module's, class's or function's docstring; a comment line holds only a comment; a
code line is any other line that is not blank.  Compiled functions are those decorated by ``numba.njit`` / ``njit``
/ ``numba.jit``.  ``--ref REV`` counts a git revision the same way beside the work tree (``git show``, nothing is
checked out), so a change's own lines can be read as the difference::

    python benchmarks/lines.py --ref HEAD~5
"""

from __future__ import annotations

import argparse
import ast
import io
import subprocess
import tokenize
from collections import Counter
from pathlib import Path

PACKAGES = ("mrmt_env", "ising_backend", "planners", "agents")
ROOT = Path(__file__).resolve().parents[1]


def count(source: str) -> Counter:
    """``code``, ``docstring``, ``comment``, ``blank`` lines and ``compiled`` functions of one module's ``source``."""
    lines = source.splitlines()
    doc: set[int] = set()
    compiled = 0
    tree = ast.parse(source)
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
                    and isinstance(body[0].value.value, str):
                doc.update(range(body[0].lineno, body[0].end_lineno + 1))
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for d in node.decorator_list:
                name = ast.unparse(d.func if isinstance(d, ast.Call) else d)
                if name.split(".")[-1] in ("njit", "jit"):
                    compiled += 1
                    break
    comment: set[int] = set()
    code: set[int] = set()
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.COMMENT:
            comment.add(tok.start[0])
        elif tok.type not in (tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT, tokenize.ENDMARKER):
            code.update(range(tok.start[0], tok.end[0] + 1))
    c = Counter(modules=1, compiled=compiled)
    for i, text in enumerate(lines, start=1):
        if not text.strip():
            c["blank"] += 1
        elif i in doc:
            c["docstring"] += 1
        elif i in code:
            c["code"] += 1
        elif i in comment:
            c["comment"] += 1
        else:
            c["code"] += 1  # a string continuation line
    return c


def tree_sources(ref: str | None):
    """``(package, source)`` of every library module in the work tree (``ref`` None) or at git revision ``ref``."""
    if ref is None:
        for pkg in PACKAGES:
            for path in sorted((ROOT / pkg).rglob("*.py")):
                yield pkg, path.read_text()
        return
    names = subprocess.run(["git", "ls-tree", "-r", "--name-only", ref, "--", *PACKAGES], cwd=ROOT, check=True,
                           capture_output=True, text=True).stdout.split()
    for name in names:
        if name.endswith(".py"):
            yield name.split("/")[0], subprocess.run(["git", "show", f"{ref}:{name}"], cwd=ROOT, check=True,
                                                     capture_output=True, text=True).stdout


def table(ref: str | None) -> dict[str, Counter]:
    out: dict[str, Counter] = {pkg: Counter() for pkg in PACKAGES}
    for pkg, source in tree_sources(ref):
        out[pkg] += count(source)
    out["library"] = sum(out.values(), Counter())
    return out


KEYS = ("modules", "code", "docstring", "comment", "blank", "compiled")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ref", help="also count this git revision, and the difference")
    args = ap.parse_args()
    now = table(None)
    rows = [("work tree", now)]
    if args.ref:
        rows.insert(0, (args.ref, table(args.ref)))
    print("| tree | package | " + " | ".join(KEYS) + " |")
    print("|---|---|" + "---:|" * len(KEYS))
    for label, t in rows:
        for pkg, c in t.items():
            print(f"| {label} | {pkg} | " + " | ".join(f"{c[k]:,}" for k in KEYS) + " |")
    if args.ref:
        before = rows[0][1]["library"]
        print("| difference | library | " + " | ".join(f"{now['library'][k] - before[k]:+,}" for k in KEYS) + " |")


if __name__ == "__main__":
    main()
