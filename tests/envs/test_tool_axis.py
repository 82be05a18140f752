"""A free tool axis (envs/tool_axis.py): every branch × angle verified by forward
kinematics, the DP's optimum over them equal to enumeration, never worse than the fixed
axis."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ikbranch_gym.agents.evaluation import build_policy
from ikbranch_gym.envs.ik_branch_env import IKBranchEnv
from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.kinematics.rotations import rot_z
from ikbranch_gym.envs.tasks.waypoint_file import write_waypoints
from ikbranch_gym.envs.tool_axis import MAX_ANGLES, ToolAxisArm, axis_angles, tilt_directions
from tests.agents.brute_force import brute_force
from tests.envs.test_process import _spin_poses


def test_sampled_angles():
    np.testing.assert_allclose(np.degrees(axis_angles(math.radians(60), math.radians(30))),
                               [-60, -30, 0, 30, 60], atol=1e-12)
    full = np.degrees(axis_angles(math.pi, math.radians(90)))
    np.testing.assert_allclose(full, [-180, -90, 0, 90], atol=1e-12)  # ±180° once
    np.testing.assert_array_equal(axis_angles(0.0, 0.1), [0.0])
    for bad in ((-0.1, 0.1), (4.0, 0.1), (1.0, 0.0), (1.0, math.nan)):
        with pytest.raises(ValueError, match="tool_axis"):
            axis_angles(*bad)
    with pytest.raises(ValueError, match=f"at most {MAX_ANGLES}"):
        axis_angles(math.pi, math.radians(1.0))


@pytest.mark.parametrize("name", ["kuka_kr6_r700", "ur5e", "anthropomorphic"])
def test_every_branch_and_angle_reaches_its_turned_pose(name):
    arm = make_arm(name)
    tcp = np.eye(4)
    tcp[:3, 3] = (0.01, 0.02, 0.15)  # a TCP off the flange's axis
    angles = axis_angles(math.pi, math.radians(45))
    free = ToolAxisArm(arm, tcp, angles)
    rng = np.random.default_rng(0)
    q = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(4, arm.dof))
    poses = arm.fk(q)
    candidates, valid = free.ik(poses)
    assert candidates.shape == (4, arm.n_branches * 8, arm.dof) and valid.any()
    assert free.n_branches == len(free.branch_labels) == arm.n_branches * 8
    for m, b in zip(*np.nonzero(valid), strict=True):
        # The TCP stands where the waypoint's TCP stands, turned about its own z axis.
        turn = np.eye(4)
        turn[:3, :3] = rot_z(angles[b % 8])
        expected = poses[m] @ tcp @ turn @ np.linalg.inv(tcp)
        np.testing.assert_allclose(arm.fk(candidates[m, b]), expected, atol=1e-9)
        np.testing.assert_allclose(arm.fk(candidates[m, b]), free.branch_pose(poses[m], b),
                                   atol=1e-12)
    zero = np.flatnonzero(angles == 0.0)[0]  # angle 0: the arm's own branches, exactly
    base, ok = arm.ik(poses)
    np.testing.assert_array_equal(valid[:, zero::8], ok)
    np.testing.assert_array_equal(candidates[:, zero::8][ok], base[ok])
    assert list(free.branch_closed_form[::8]) == list(arm.branch_closed_form)


def _play(env, spec="dp_oracle"):
    _, policy = build_policy(spec, env, 0)
    obs, info = env.reset(seed=0)
    total, done = 0.0, False
    while not done:
        action, _ = policy.predict(obs, action_masks=info["action_mask"], deterministic=True)
        obs, reward, done, _, info = env.step(int(action))
        total += reward
    return total, info


def test_the_dp_is_the_optimum_over_branch_and_angle(tmp_path):
    path = write_waypoints(tmp_path / "short.csv", _spin_poses(3))
    env = IKBranchEnv(arm="kuka_kr6_r700", scene="empty", task="file", task_file=str(path),
                      tool_axis=[math.radians(30), math.radians(30)], time_weight=0.3)
    total, info = _play(env)
    assert env.arm.n_branches == 96 and info["is_success"]
    assert total == pytest.approx(brute_force(env), rel=1e-12, abs=1e-12)


def test_a_free_axis_is_never_worse_than_the_fixed_one(tmp_path):
    path = write_waypoints(tmp_path / "spin.csv", _spin_poses(8))
    fixed, _ = _play(IKBranchEnv(arm="kuka_kr6_r700", scene="empty", task="file",
                                 task_file=str(path)))
    free, info = _play(IKBranchEnv(arm="kuka_kr6_r700", scene="empty", task="file",
                                   task_file=str(path),
                                   tool_axis=[math.pi, math.radians(25)]))
    # The job turns the tool 25° a waypoint: a free axis turns it back instead of j6.
    assert info["is_success"] and free > fixed + 1.0


def test_the_tool_axis_is_for_a_waypoint_file():
    with pytest.raises(ValueError, match="tool_axis is for task='file' or 'deburring'"):
        IKBranchEnv(arm="kuka_kr6_r700", scene="empty", tool_axis=[1.0, 0.5])
    with pytest.raises(ValueError, match=r"tool_axis must be \[range, step\]"):
        IKBranchEnv(arm="kuka_kr6_r700", scene="empty", task="file",
                    task_file="examples/deburring_passes.csv", tool_axis=1.0)


def test_tilt_directions_cover_the_cone():
    directions = tilt_directions(math.radians(10.0), math.radians(5.0))
    tilts = np.round(np.degrees(directions[:, 0]), 9)
    assert list(np.unique(tilts, return_counts=True)[1]) == [1, 7, 13]  # 0°, 5°, 10°
    assert tuple(directions[0]) == (0.0, 0.0)
    for tilt in (5.0, 10.0):  # neighbouring tilted axes about a step apart, all around
        azimuths = directions[tilts == tilt, 1]
        np.testing.assert_allclose(np.diff(np.r_[azimuths, 2 * math.pi]),
                                   2 * math.pi / len(azimuths), atol=1e-12)
        axes = np.stack([np.sin(math.radians(tilt)) * np.sin(azimuths),
                         -np.sin(math.radians(tilt)) * np.cos(azimuths)], axis=1)
        gaps = np.linalg.norm(axes - np.roll(axes, 1, axis=0), axis=1)
        assert gaps.max() <= math.radians(5.0) + 1e-12
    assert len(tilt_directions(math.radians(4.0), math.radians(5.0))) == 1  # no tilt fits
    for bad in ((-0.1, 0.1), (2.0, 0.1), (0.2, 0.0)):
        with pytest.raises(ValueError, match="tool tilt"):
            tilt_directions(*bad)


def test_every_tilted_sample_reaches_its_turned_pose():
    """Tilt(α, φ)·Rz(θ) in the TCP frame: the TCP stays put and its z axis leans by α,
    turned about the hinge (cos φ, sin φ, 0): to (sin φ sin α, −cos φ sin α, cos α)."""
    arm = make_arm("kuka_kr6_r700")
    tcp = np.eye(4)
    tcp[:3, 3] = (0.01, 0.02, 0.15)
    tilts = tilt_directions(math.radians(10.0), math.radians(10.0))
    free = ToolAxisArm(arm, tcp, axis_angles(math.radians(90), math.radians(90)), tilts)
    samples = 3 * len(tilts)
    assert free.n_branches == arm.n_branches * samples
    pose = arm.fk(np.array([0.1, -1.3, 1.7, 0.4, 0.9, -0.2]))
    candidates, valid = free.ik(pose)
    assert valid.any()
    target = pose @ tcp
    for b in np.flatnonzero(valid):
        reached = arm.fk(candidates[b]) @ tcp
        np.testing.assert_allclose(reached[:3, 3], target[:3, 3], atol=1e-9)  # TCP put
        tilt, azimuth = free.branch_tilts[b], free.branch_azimuths[b]
        leaned = np.array([math.sin(azimuth) * math.sin(tilt),
                           -math.cos(azimuth) * math.sin(tilt), math.cos(tilt)])
        np.testing.assert_allclose(target[:3, :3].T @ reached[:3, 2], leaned, atol=1e-9)
    with pytest.raises(ValueError, match="at most 73"):
        ToolAxisArm(arm, tcp, axis_angles(math.pi, math.radians(30)), tilts)  # 12 × 8


def test_a_tilt_cone_reaches_what_a_fixed_axis_cannot(tmp_path):
    """A pose whose every branch needs A5 = 125° (5° beyond the KR 6 R700's limit):
    unreachable with a fixed tool, reached with a 10° cone, and the DP over branch × tilt
    is the optimum."""
    arm = make_arm("kuka_kr6_r700")
    inside = arm.fk(np.array([0.2, -1.4, 1.8, 0.5, math.radians(100.0), 0.3]))
    beyond = arm.fk(np.array([0.2, -1.4, 1.8, 0.5, math.radians(125.0), 0.3]))
    path = write_waypoints(tmp_path / "beyond.csv", np.array([inside, beyond]))
    with pytest.raises(ValueError, match="outside the joint limits"):
        IKBranchEnv(arm="kuka_kr6_r700", scene="empty", task="file", task_file=str(path))
    env = IKBranchEnv(arm="kuka_kr6_r700", scene="empty", task="file", task_file=str(path),
                      tool_axis=[0.0, 1.0, math.radians(10.0), math.radians(10.0)])
    total, info = _play(env)
    assert info["is_success"]
    assert total == pytest.approx(brute_force(env), rel=1e-12, abs=1e-12)
