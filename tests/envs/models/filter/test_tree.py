"""Forward kinematics inside the kernels is MuJoCo's."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.models import CollisionChecker, build_model
from ikbranch_gym.envs.models.filter import tree as kinematics
from tests.envs.models.conftest import scene_cases


@pytest.mark.parametrize(("arm_name", "scene"), scene_cases())
def test_forward_kinematics_equals_mujoco(arm_name, scene):
    arm = make_arm(arm_name)
    model = build_model(arm_name, scene, tool=True) if scene != "milling_cell" else build_model(
        arm_name, scene)
    checker = CollisionChecker(model, dof=arm.dof, backend="compiled")
    scene_arrays = checker._filter.scene
    arrays = scene_arrays.tree
    data = mujoco.MjData(model)
    xpos, xmat = arrays[-2].copy(), arrays[-1].copy()
    rng = np.random.default_rng(25)
    for q in rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(100, arm.dof)):
        qpos = model.qpos0.copy()
        qpos[: arm.dof] = q
        kinematics._forward(*arrays[:12], qpos, xpos, xmat)
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        np.testing.assert_allclose(xpos, data.xpos, atol=1e-12)
        np.testing.assert_allclose(xmat.reshape(-1, 9), data.xmat, atol=1e-12)
