"""The task frame (``envs/task_frame.py``): tasks given in the cell, of the TCP, become fk
poses ``base_from_cell · pose · inv(tcp)``; every branch the env offers puts the TCP on the
task's pose, checked by forward kinematics."""

from __future__ import annotations

import numpy as np
import pytest

from ikbranch_gym.envs.ik_branch_env import IKBranchEnv
from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.models.scene_file import base_pose
from ikbranch_gym.envs.models.scenes import milling_cell_poses
from ikbranch_gym.envs.task_frame import FramedArm, TaskFrame
from ikbranch_gym.envs.tools import Tool

TOOL = {"shape": "cylinder", "size": [0.03, 0.12],
        "tcp": {"pos": [0.0, 0.04, 0.12], "rpy": [0.2, 0.0, 0.0]}}
PLACED = {"base_pos": [-0.475, 0.4, 0.0], "base_rpy": [0.0, 0.0, 0.7]}


def test_the_frame_maps_both_ways():
    frame = TaskFrame(base_pose(**PLACED), Tool.from_spec(TOOL).tcp)
    assert not frame.identity and TaskFrame().identity
    rng = np.random.default_rng(0)
    arm = make_arm("abb_irb2600")
    poses = arm.fk(rng.uniform(*arm.joint_limits.T, size=(40, 6)))
    np.testing.assert_allclose(frame.from_fk(frame.to_fk(poses)), poses, atol=1e-14)
    expected = np.linalg.inv(frame.cell_from_base) @ poses @ np.linalg.inv(frame.tcp)
    np.testing.assert_allclose(frame.to_fk(poses), expected, atol=1e-14)


@pytest.mark.parametrize("arm_name", ["abb_irb2600", "ur5e", "anthropomorphic"])
def test_every_framed_branch_reaches_the_task_pose(arm_name):
    arm = make_arm(arm_name)
    framed = FramedArm(arm, TaskFrame(base_pose(**PLACED), Tool.from_spec(TOOL).tcp))
    rng = np.random.default_rng(1)
    q = rng.uniform(*arm.joint_limits.T, size=(30, arm.dof))
    poses = framed.fk(q)  # task-frame poses of the TCP
    branches, valid = framed.ik(poses)
    assert valid.any(axis=-1).all()
    for pose, rows, ok in zip(poses, branches, valid, strict=True):
        np.testing.assert_allclose(framed.fk(rows[ok]), np.broadcast_to(pose, (ok.sum(), 4, 4)),
                                   atol=1e-9)
    assert framed.reaches(poses).all() and framed.dof == arm.dof  # the rest is the arm's
    # Positions are the TCP's in the task frame too, not the flange's in the base frame.
    assert np.array_equal(framed.positions(q), poses[:, :3, 3])
    assert not np.allclose(framed.positions(q), arm.positions(q))


def test_a_placed_arm_with_a_tool_serves_the_cells_poses():
    # The IRB 4600 of IRB4600ToolTransfer-v0: placed between rack and mill, a gripper.
    import ikbranch_gym.envs as envs

    kwargs = envs.ENV_SPECS["IKBranch/IRB4600ToolTransfer-v0"]
    assert kwargs["scene_options"]["base_pos"] != [0.0, 0.0, 0.0] and kwargs["tool"]
    env = IKBranchEnv(**kwargs)
    env.reset(seed=0)
    assert not env.task_frame.identity
    cell = env.task_frame.from_fk(env.task.poses)  # back in the cell, of the TCP
    # The fourth waypoint of a tool change puts the tool in the spindle: position 2, the
    # tool's axis (the gripper's y) along the spindle's, gripped either way round it.
    spindle = milling_cell_poses()[1]
    np.testing.assert_allclose(cell[3][:3, 1:4:2], spindle[:3, 1:4:2], atol=1e-12)
    np.testing.assert_allclose(abs(cell[3][:3, 0] @ spindle[:3, 0]), 1.0, atol=1e-12)
    moves = env.pricer.task(env.task)
    for pose, rows, ok in zip(env.task.poses, moves.candidates, moves.valid, strict=True):
        assert ok.any()
        np.testing.assert_allclose(env.arm.fk(rows[ok]),
                                   np.broadcast_to(pose, (ok.sum(), 4, 4)), atol=1e-9)
