"""Model files are untrusted: loading one through the package never unpickles code from it.

Each crafted file is first shown to run its payload through stable-baselines3's own loader (so the
test can fail), then loaded through :func:`agents.learned.training.load_policy`, which must not run it.
"""

from __future__ import annotations

import base64
import io
import json
import pickle
import shutil
import zipfile

import numpy as np
import pytest

pytest.importorskip("sb3_contrib")

import gymnasium as gym  # noqa: E402
import torch  # noqa: E402
from sb3_contrib import MaskablePPO  # noqa: E402
from stable_baselines3 import PPO  # noqa: E402

from agents.cli import main  # noqa: E402
from agents.errors import ControllerError  # noqa: E402
from agents.learned.training import (ASSIGN_ENV_ID, SMALL_ENV_ID, TrainOptions, load_policy, sidecar_path,  # noqa: E402
                                     train)


class Payload:
    """Unpickling this runs ``exec(code)``: here, writing a marker file."""

    def __init__(self, marker):
        self.code = f"open({str(marker)!r}, 'w').write('ran')"

    def __reduce__(self):
        return exec, (self.code,)


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    d = tmp_path_factory.mktemp("models")
    grid, assign = d / "grid.zip", d / "assign.zip"
    train(SMALL_ENV_ID, 64, out=grid, options=TrainOptions(seed=0, n_envs=1))
    train(ASSIGN_ENV_ID, 256, out=assign, options=TrainOptions(seed=0, n_envs=4))
    return {"grid": (grid, PPO, SMALL_ENV_ID), "assign": (assign, MaskablePPO, ASSIGN_ENV_ID)}


def _rewrite(src, dst, data=None, entries=None):
    """Copy a model zip (and its sidecar), changing its ``data`` JSON and/or replacing entries."""
    with zipfile.ZipFile(src) as z:
        files = {name: z.read(name) for name in z.namelist()}
    if data is not None:
        d = json.loads(files["data"])
        data(d)
        files["data"] = json.dumps(d).encode()
    files.update(entries or {})
    with zipfile.ZipFile(dst, "w") as z:
        for name, blob in files.items():
            z.writestr(name, blob)
    shutil.copy(sidecar_path(src), sidecar_path(dst))
    return dst


def _pickled(obj) -> dict:
    return {":type:": "<class 'x'>", ":serialized:": base64.b64encode(pickle.dumps(obj)).decode()}


def _sb3_runs_it(algo, path, marker) -> bool:
    try:
        algo.load(path, device="cpu")
    except Exception:  # the payload returns None where SB3 wanted a space or class
        pass
    return marker.exists()


@pytest.mark.parametrize("which", ["grid", "assign"])
@pytest.mark.parametrize("entry", ["observation_space", "policy_class", "lr_schedule", "_last_obs"])
def test_a_pickled_entry_is_never_unpickled(models, tmp_path, which, entry):
    src, algo, _ = models[which]
    marker = tmp_path / "ran"
    crafted = _rewrite(src, tmp_path / "crafted.zip", data=lambda d: d.__setitem__(entry, _pickled(Payload(marker))))
    assert _sb3_runs_it(algo, crafted, marker)  # SB3's own loader runs the file's code
    marker.unlink()
    policy = load_policy(crafted)  # the safe loader rebuilds the entry instead: the model still loads
    assert not marker.exists()
    assert type(policy.model) is algo


def test_an_unknown_pickled_entry_is_refused(models, tmp_path):
    src, algo, _ = models["grid"]
    marker = tmp_path / "ran"
    crafted = _rewrite(src, tmp_path / "crafted.zip", data=lambda d: d.__setitem__("extra", _pickled(Payload(marker))))
    assert _sb3_runs_it(algo, crafted, marker)
    marker.unlink()
    with pytest.raises(ControllerError, match=r"refusing to load model .*data entry 'extra' is a pickle"):
        load_policy(crafted)
    assert not marker.exists()


def test_pickled_code_in_the_weights_is_refused(models, tmp_path):
    src, algo, _ = models["grid"]
    marker = tmp_path / "ran"
    blob = io.BytesIO()
    torch.save({"policy": Payload(marker)}, blob)
    crafted = _rewrite(src, tmp_path / "crafted.zip", entries={"policy.pth": blob.getvalue()})
    torch.load(io.BytesIO(blob.getvalue()), weights_only=False)  # an unrestricted torch.load runs it
    assert marker.exists()
    marker.unlink()
    with pytest.raises(ControllerError, match=r"entry 'policy.pth' holds more than tensors"):
        load_policy(crafted)
    assert not marker.exists()


@pytest.mark.parametrize("key, value, match", [
    ("env", "os:system", r"data entry 'env' would replace the model's own 'env'"),
    ("predict", 1, r"data entry 'predict' would replace"),
    ("policy_kwargs", {"net_arch": [10**9]}, r"policy_kwargs hold the number 1000000000"),
])
def test_data_entries_that_would_steer_the_model_are_refused(models, tmp_path, key, value, match):
    src, _, _ = models["grid"]
    crafted = _rewrite(src, tmp_path / "crafted.zip", data=lambda d: d.__setitem__(key, value))
    with pytest.raises(ControllerError, match=match):
        load_policy(crafted)


def test_sidecar_and_policy_class_come_from_fixed_lists(models, tmp_path):
    src, _, _ = models["grid"]
    crafted = _rewrite(src, tmp_path / "crafted.zip")
    side = sidecar_path(crafted)
    meta = json.loads(side.read_text())
    side.write_text(json.dumps({**meta, "policy": "EvilPolicy"}))
    with pytest.raises(ControllerError, match=r"policy 'EvilPolicy' \(sidecar\) is not one of"):
        load_policy(crafted)
    side.write_text(json.dumps({**meta, "env_id": "CartPole-v1"}))
    with pytest.raises(ControllerError, match=r"only this package's mrmt_env/ ids"):
        load_policy(crafted)
    side.write_text(json.dumps({**meta, "env_kwargs": {"n_robots": 3}}))
    with pytest.raises(ControllerError, match=r"observation_space has shape .* but its env gives"):
        load_policy(crafted)


def test_size_limits(models, tmp_path, monkeypatch):
    import agents.learned.policy as learned

    src, _, _ = models["grid"]
    monkeypatch.setattr(learned, "MAX_MODEL_BYTES", 1000)
    with pytest.raises(ControllerError, match=r"the file has \d+ bytes; at most 1000 are read"):
        load_policy(src)


@pytest.mark.parametrize("which", ["grid", "assign"])
def test_a_trained_model_loads_and_acts_identically(models, which):
    src, algo, env_id = models[which]
    safe = load_policy(src).model
    ref = algo.load(src, device="cpu")  # our own file: trusted here
    a, b = safe.policy.state_dict(), ref.policy.state_dict()
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    env = gym.make(env_id)
    obs, info = env.reset(seed=0)
    masked = algo is MaskablePPO
    for t in range(60):
        kw = {"action_masks": env.unwrapped.action_masks()} if masked else {}
        x, _ = safe.predict(obs, deterministic=True, **kw)
        y, _ = ref.predict(obs, deterministic=True, **kw)
        assert np.array_equal(x, y)
        obs, _, term, trunc, _ = env.step(x)
        if term or trunc:
            obs, info = env.reset(seed=t + 1)


def test_compare_refuses_a_crafted_model_without_running_it(models, tmp_path, capsys):
    src, _, _ = models["grid"]
    marker = tmp_path / "ran"
    crafted = _rewrite(src, tmp_path / "crafted.zip", data=lambda d: d.__setitem__("extra", _pickled(Payload(marker))))
    rc = main(["compare", "--worlds", "1", "--env-id", SMALL_ENV_ID, "--controllers", f"strong,ppo:{crafted}",
               "--jobs", "1", "--no-progress"])
    assert rc == 2 and not marker.exists()
    assert "data entry 'extra' is a pickle" in capsys.readouterr().err
