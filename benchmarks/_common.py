"""Helpers shared by the benchmark scripts (run as ``python benchmarks/<name>.py``)."""

from __future__ import annotations

import platform
import re
from pathlib import Path

RESULTS = Path(__file__).with_name("RESULTS.md")


#: In a section, what follows this line (readings, subsections written by hand) is kept when the section
#: is rewritten.
KEEP_MARK = "<!-- kept when the tables above are rewritten -->"


def write_results_section(section: str, block: str, path: Path = RESULTS) -> None:
    """Put ``block`` (text starting with the heading line ``section``) into ``path``.

    An existing section (from its heading to the next ``## `` heading or the end)
    is replaced, except what follows a :data:`KEEP_MARK` line in it, which stays after the
    new block; otherwise the block is appended.  Other sections are kept as
    they are.  The block is written with one trailing newline plus the blank line
    before the next section.
    """
    path = Path(path)
    text = path.read_text() if path.exists() else "# Benchmark results\n\n"
    body = block.rstrip("\n")
    pattern = re.compile(r"^" + re.escape(section) + r"\n.*?(?=^## |\Z)", re.S | re.M)
    found = pattern.search(text)
    if found:
        old = found.group(0)
        if KEEP_MARK in old and KEEP_MARK not in body:
            body += "\n\n" + KEEP_MARK + old.split(KEEP_MARK, 1)[1].rstrip("\n")
        text = pattern.sub(lambda _: body + "\n\n", text)
    else:
        text = text.rstrip("\n") + "\n\n" + body + "\n"
    path.write_text(text)


def cpu_name() -> str:
    """The CPU model from ``/proc/cpuinfo`` ("model name"), else ``platform.processor()`` or the machine type."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return cpu


def finish(section: str, lines: list[str], write: bool) -> str:
    """Print the section built from ``lines`` and, with ``write``, put it into RESULTS.md."""
    text = "\n".join(lines) + "\n"
    print(text)
    if write:
        write_results_section(section, text)
    return text


def lorr_run_json(instance: Path, *args: str) -> dict:
    """The record of ``mrmt lorr run INSTANCE ARGS --json --no-progress`` (one instance, in a process of its own)."""
    import json
    import subprocess
    import sys

    cmd = [sys.executable, "-m", "agents.cli", "lorr", "run", str(instance), *args, "--json", "--no-progress"]
    return json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout.strip().splitlines()[-1])
