"""The ``mrmt`` dispatcher: version, and errors reported by the subcommand they belong to."""

import pytest

from agents.cli import main


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    out = capsys.readouterr().out.strip()
    assert out.startswith("mrmt ") and len(out.split()) >= 2


@pytest.mark.parametrize("command, args, bad", [
    ("compare", [], "--wrolds"),
    ("plan", ["x.jsonl"], "--frob"),
    ("sweep", ["--chip", "n_spins=32", "--out", "x"], "--wrolds"),
])
def test_unknown_option_shows_the_subcommand_usage(command, args, bad, capsys):
    with pytest.raises(SystemExit) as exc:
        main([command, *args, bad, "2"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith(f"usage: mrmt {command} ")
    assert err.strip().splitlines()[-1] == f"mrmt {command}: error: unrecognized arguments: {bad} 2"


def test_command_examples_write_to_relative_paths():
    from pathlib import Path

    import agents.commands

    for path in Path(agents.commands.__file__).parent.glob("*.py"):
        assert "--out /" not in path.read_text(), f"{path.name}: an example writes to an absolute path"
