"""MuJoCo's C functions and struct fields, as the kernels reach them."""

from __future__ import annotations

import mujoco
import numpy as np

from ikbranch_gym.envs.models import build_model, native


def test_ncon_view_follows_mujoco():
    model = build_model("anthropomorphic", "milling_cell")
    data = mujoco.MjData(model)
    view = native.ncon_view(data)
    rng = np.random.default_rng(31)
    seen = set()
    for q in rng.uniform(-2, 2, size=(50, 6)):
        data.qpos[:6] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_collision(model, data)
        assert view[0] == data.ncon
        seen.add(data.ncon)
    assert len(seen) > 3

