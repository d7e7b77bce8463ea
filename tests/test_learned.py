"""PPO training, loading and evaluation through the same runner."""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from agents.cli import main  # noqa: E402
from agents.evaluation import ControllerError, evaluate  # noqa: E402
from agents.runner import RunConfig  # noqa: E402
from agents.learned.training import SMALL_ENV_ID, load_policy, sidecar_path, train_ppo  # noqa: E402


@pytest.fixture(scope="module")
def model_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("ppo") / "model.zip"
    train_ppo(256, out=path, env_id=SMALL_ENV_ID, seed=0)
    return path


def test_train_writes_model_and_sidecar(model_path):
    assert zipfile.is_zipfile(model_path)
    meta = json.loads(sidecar_path(model_path).read_text())
    assert meta["env_id"] == SMALL_ENV_ID and meta["timesteps"] == 256


def test_training_leaves_no_log_folder_and_prints_its_table_when_verbose(tmp_path, monkeypatch, capsys):
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # where SB3's default logger makes its folder
    train_ppo(64, out=None, env_id=SMALL_ENV_ID, seed=0, verbose=1)
    assert list(tmp_path.glob("SB3-*")) == []
    assert "total_timesteps" in capsys.readouterr().out


def test_ppo_evaluated_by_the_same_runner(model_path):
    res = evaluate([f"ppo:{model_path}", "strong"], n_worlds=2, env_id=SMALL_ENV_ID,
                   run=RunConfig.from_jobs(1, progress=False))
    ppo = res.by_controller(f"ppo:{model_path}")
    strong = res.by_controller("strong")
    assert len(ppo) == len(strong) == 2
    for r in ppo:
        assert r["steps"] >= 1 and r["n_plans"] == 0
        assert r["cpu_s"] > 0 and r["chip_calls"] == 0 and r["accelerator_energy_j"] == 0.0
        assert r["host_energy_j"] == pytest.approx(15.0 * r["cpu_s"])
    assert all(r["is_success"] for r in strong)
    assert [r["world_seed"] for r in ppo] == [r["world_seed"] for r in strong]


def test_loaded_policy_checks_observation_shape(model_path):
    pol = load_policy(model_path)
    with pytest.raises(ValueError, match="trained on observations of shape"):
        pol.predict(np.zeros((5, 10, 10), np.uint8))
    action, _ = pol.predict(np.zeros(pol.observation_shape, np.uint8), episode_start=True)
    assert action.shape == (pol.observation_shape[0] - 2,)
    assert pol.episode_compute().cpu_s > 0


def test_load_errors(tmp_path):
    with pytest.raises(ControllerError, match="does not exist"):
        load_policy(tmp_path / "nope.zip")
    bad = tmp_path / "bad.zip"
    with zipfile.ZipFile(bad, "w") as z:
        z.writestr("hello.txt", "no model here")
    with pytest.raises(ControllerError, match=r"is not a stable-baselines3 .zip model \(no 'data' entry\)"):
        load_policy(bad)


def test_train_cli(tmp_path, capsys):
    out = tmp_path / "m.zip"
    assert main(["train", "--timesteps", "64", "--out", str(out), "--env-id", SMALL_ENV_ID]) == 0
    assert zipfile.is_zipfile(out)
    assert main(["train", "--timesteps", "64", "--out", str(out), "--env-id", "mrmt_env/Nope-v0"]) == 2
    assert "unknown env id 'mrmt_env/Nope-v0'" in capsys.readouterr().err


def test_train_cli_names_the_file_it_writes(tmp_path, capsys):
    out = tmp_path / "m2"
    assert main(["train", "--timesteps", "64", "--out", str(out), "--env-id", SMALL_ENV_ID, "--no-progress"]) == 0
    line = capsys.readouterr().out.strip()
    assert line.startswith(f"wrote {out}.zip, {out}.json") and zipfile.is_zipfile(f"{out}.zip") and not out.exists()
    for seed in ("-1", str(2**32)):
        assert main(["train", "--timesteps", "64", "--out", str(out), "--seed", seed]) == 2
        assert capsys.readouterr().err.strip() == (
            "mrmt train: error: --seed must be in [0, 2**32 - 1] (stable-baselines3 seeds numpy's global generator "
            f"with it), got {seed}")
