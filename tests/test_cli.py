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


@pytest.mark.parametrize("controllers", ["greedy", "fast", "ppo:/no/such.zip"])
def test_compare_names_an_unknown_env_id_before_the_controllers(controllers, capsys):
    assert main(["compare", "--env-id", "mrmt_env/NoSuch-v0", "--controllers", controllers, "--worlds", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("mrmt compare: error: unknown env id 'mrmt_env/NoSuch-v0'; registered: ")
    assert "mrmt_env/MRMT-v0" in err[0] and "mrmt_env/MRMT-Lifelong-v0" in err[0]


def test_compare_refuses_a_world_the_env_cannot_hold_before_any_bar_or_pool(capsys):
    assert main(["compare", "--controllers", "fast", "--robots", "500", "--worlds", "2", "--jobs", "2"]) == 2
    err = capsys.readouterr().err
    assert err == ("mrmt compare: error: 500 robots + 10 targets need 510 distinct free cells, but a 10x10 grid "
                   "with 20 obstacles has only 80\n")  # no progress bar drawn first, no traceback


@pytest.mark.parametrize("env_id, needle", [
    ("mrmt_env/LoRR-v0", "use mrmt lorr run INSTANCE.json"),
    ("CartPole-v1", "'CartPole-v1' is not an mrmt_env/ id"),
])
def test_compare_refuses_ids_it_does_not_run(env_id, needle):
    from agents.cli import main

    import io
    import contextlib

    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        code = main(["compare", "--env-id", env_id, "--controllers", "fast", "--worlds", "1", "--no-progress"])
    assert code == 2 and needle in err.getvalue() and len(err.getvalue().strip().splitlines()) == 1
