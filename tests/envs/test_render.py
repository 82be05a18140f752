"""Offscreen rendering draws real frames (EGL by default; no skip)."""

from __future__ import annotations

import imageio.v3 as iio
import numpy as np

from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.models import build_model
from ikbranch_gym.envs.render import SceneRenderer, main


def test_frame_shows_the_arm():
    arm = make_arm("anthropomorphic")
    model = build_model("anthropomorphic")
    turned = arm.home.copy()
    turned[0] += np.pi / 2
    with SceneRenderer(model, width=160, height=120, frame_qs=[arm.home, turned]) as renderer:
        home = renderer.render(arm.home)
        moved = renderer.render(turned)
    assert home.shape == (120, 160, 3) and home.dtype == np.uint8
    assert home.std() > 10.0  # not blank
    # The arm's pixels move with it; the floor's stay put.
    changed = np.any(np.abs(home.astype(int) - moved.astype(int)) > 30, axis=-1)
    assert 0.01 < changed.mean() < 0.5
    # Orange links: red well above blue.
    orange = (home[..., 0].astype(int) - home[..., 2].astype(int)) > 80
    assert orange.sum() > 50


def test_cli_writes_png_and_gif(tmp_path):
    png, gif = tmp_path / "arm.png", tmp_path / "path.gif"
    assert main(["cylindrical4", "--width", "96", "--height", "72", "--out", str(png)]) == 0
    picture = iio.imread(png)
    assert picture.shape[:2] == (72, 96) and picture.std() > 10.0
    assert main(["cartesian", "--path-from", "0", "0", "1", "0", "0.5", "0",
                 "--path-to", "0.5", "0.5", "0.8", "1", "0.5", "1",
                 "--frames", "3", "--width", "64", "--height", "48", "--out", str(gif)]) == 0
    frames = iio.imread(gif, index=None)
    assert frames.shape[0] == 3
    assert not np.array_equal(frames[0], frames[-1])
