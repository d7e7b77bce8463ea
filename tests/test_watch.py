"""Episodes as GIFs: frames for planners and learned agents in both envs, and the mrmt watch command."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("imageio")

from agents.animation import draw_route, episode_frames, write_gif  # noqa: E402
from agents.cli import main  # noqa: E402


@pytest.mark.parametrize("env_id", ["mrmt_env/MRMT-v0", "mrmt_env/MRMT-Assign-v0"])
def test_planner_frames_follow_the_episode(env_id):
    frames, info = episode_frames("strong", env_id, seed=2, cell=12)
    assert info["is_success"]
    assert len(frames) == info["makespan"] + 1  # one frame per time step, start included
    assert all(f.shape == (120, 120, 3) and f.dtype == np.uint8 for f in frames)
    assert not np.array_equal(frames[0], frames[-1])


def test_draw_route_and_errors(tmp_path):
    img = np.full((48, 48, 3), 255, np.uint8)
    draw_route(img, [[0, 0], [0, 1], [1, 1]], (255, 0, 0), cell=24)
    assert (img[12, 12:36] == [255, 0, 0]).all() and (img[12:36, 36] == [255, 0, 0]).all()
    with pytest.raises(ValueError, match="cell must be an integer >= 8"):
        episode_frames("strong", cell=4)
    with pytest.raises(ValueError, match="no frames"):
        write_gif([], tmp_path / "x.gif")


def test_watch_cli(tmp_path, capsys):
    out = tmp_path / "e.gif"
    assert main(["watch", "--controller", "fast", "--env-id", "mrmt_env/MRMT-5x5-v0", "--out", str(out)]) == 0
    assert out.read_bytes()[:6] in (b"GIF89a", b"GIF87a")
    assert "route_cost" in capsys.readouterr().out
    assert main(["watch", "--controller", "nope", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "unknown controller 'nope'" in err and len(err.strip().splitlines()) == 1
    assert main(["watch", "--env-id", "mrmt_env/Nope-v0", "--out", str(out)]) == 2
    assert "unknown env id" in capsys.readouterr().err


def test_watch_refuses_an_out_path_that_is_not_a_gif(tmp_path, capsys):
    png = tmp_path / "out.png"
    assert main(["watch", "--controller", "fast", "--env-id", "mrmt_env/MRMT-5x5-v0", "--out", str(png)]) == 2
    err = capsys.readouterr().err
    assert "must end in .gif" in err and str(png) in err and len(err.strip().splitlines()) == 1
    assert not png.exists()
    frames, _ = episode_frames("fast", "mrmt_env/MRMT-5x5-v0")
    with pytest.raises(ValueError, match=r"must end in \.gif"):
        write_gif(frames, png)
    assert not png.exists()
