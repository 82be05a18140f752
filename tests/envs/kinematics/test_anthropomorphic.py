"""Anthropomorphic arm: branch meaning and degenerate poses."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.kinematics.rotations import homogeneous, rot_x, rot_z

ARM = make_arm("anthropomorphic")


def elbow_height_above_line(q):
    """Signed height of the elbow above the straight shoulder-wrist line, in the arm plane."""
    phi2, phi3 = q[..., 1], q[..., 2]
    elbow = np.stack([ARM.l2 * np.cos(phi2), ARM.l2 * np.sin(phi2)], -1)
    wrist = elbow + ARM.l3 * np.stack([np.cos(phi2 + phi3), np.sin(phi2 + phi3)], -1)
    t = elbow[..., 0] / wrist[..., 0]
    return elbow[..., 1] - t * wrist[..., 1]


def test_branch_labels_mean_what_they_say():
    rng = np.random.default_rng(11)
    q = rng.uniform(ARM.joint_limits[:, 0], ARM.joint_limits[:, 1], (500, 6))
    solutions, valid = ARM.ik(ARM.fk(q))
    for k, label in enumerate(ARM.branch_labels):
        shoulder, elbow, wrist = label.split("/")
        rows = solutions[valid[:, k], k]
        wrist_x = ARM.fk(rows)[:, :3, 3]
        # The wrist centre lies in front (along the arm's own +y) or behind the base axis.
        arm_y = np.stack([-np.sin(rows[:, 0]), np.cos(rows[:, 0])], -1)
        reach = np.einsum("ij,ij->i", wrist_x[:, :2], arm_y)
        assert np.all(reach > 0) if shoulder == "front" else np.all(reach < 0)
        height = elbow_height_above_line(rows)
        assert np.all(height > 0) if elbow == "elbow-up" else np.all(height < 0)
        assert np.all(rows[:, 4] > 0) if wrist == "wrist+" else np.all(rows[:, 4] < 0)


def test_wrist_centre_on_base_axis_is_finite_and_valid():
    rotation = rot_z(0.3) @ rot_x(-0.4)
    pose = homogeneous(rotation, np.array([0.0, 0.0, ARM.l1 + 1.2]))
    solutions, valid = ARM.ik(pose)
    assert valid.sum() >= 4
    assert np.all(np.isfinite(solutions[valid]))
    # The free base angle is 0 in front and -pi behind (wrapped half turn).
    assert np.all(solutions[valid & (np.arange(8) < 4), 0] == 0.0)
    assert np.all(solutions[valid & (np.arange(8) >= 4), 0] == -np.pi)
    assert np.abs(ARM.fk(solutions[valid]) - pose).max() < 1e-9
    np.testing.assert_array_equal(solutions, ARM.ik(pose)[0])


def test_workspace_boundary_keeps_coinciding_elbows_valid():
    # Fully stretched: wrist centre exactly l2 + l3 from the shoulder.
    q = np.array([0.4, 0.3, 0.0, 0.2, 0.9, -0.1])
    solutions, valid = ARM.ik(ARM.fk(q))
    up, down = solutions[0], solutions[2]
    assert valid[0] and valid[2]
    np.testing.assert_allclose(up[:3], down[:3], atol=1e-6)
    assert np.abs(ARM.fk(solutions[valid]) - ARM.fk(q)).max() < 1e-9


def test_just_beyond_reach_is_unreachable():
    q = np.array([0.4, 0.3, 0.0, 0.2, 0.9, -0.1])
    pose = ARM.fk(q)
    outward = pose[:3, 3] - [0, 0, ARM.l1]
    pose[:3, 3] += 1e-6 * outward / np.linalg.norm(outward)
    _, valid = ARM.ik(pose)
    assert not valid[:4].any()


@settings(max_examples=200, deadline=None)
@given(
    base=st.floats(-3.0, 3.0),
    shoulder=st.floats(-3.0, 3.0),
    elbow=st.floats(-2.9, 2.9),
    roll=st.floats(-3.1, 3.1),
    bend=st.one_of(st.floats(-1e-6, 1e-6), st.floats(-2.35, 2.35)),
    tool=st.floats(-3.1, 3.1),
)
def test_round_trip_near_wrist_singularity(base, shoulder, elbow, roll, bend, tool):
    q = np.array([base, shoulder, elbow, roll, bend, tool])
    pose = ARM.fk(q)
    solutions, valid = ARM.ik(pose)
    assert valid.any()
    assert np.abs(ARM.fk(solutions[valid]) - pose).max() < 1e-9


@pytest.mark.parametrize("joint", range(6))
@pytest.mark.parametrize("side", [0, 1])
def test_configuration_on_a_joint_limit_stays_valid(joint, side):
    q = ARM.home.copy()
    q[joint] = ARM.joint_limits[joint, side]
    solutions, valid = ARM.ik(ARM.fk(q))
    gap = np.abs(np.remainder(solutions - q + np.pi, 2 * np.pi) - np.pi).max(axis=-1)
    assert np.nanmin(np.where(valid, gap, np.nan)) < 1e-7


def degenerate_and_random_poses():
    rng = np.random.default_rng(21)
    q = rng.uniform(ARM.joint_limits[:, 0], ARM.joint_limits[:, 1], (300, 6))
    q[:20, 4] = 0.0  # wrist singular
    q[20:40, 2] = 0.0  # stretched elbow: workspace boundary
    poses = ARM.fk(q)
    on_axis = homogeneous(rot_z(0.3) @ rot_x(-0.4), np.array([0.0, 0.0, ARM.l1 + 1.2]))
    far = ARM.fk(ARM.home)
    far[:3, 3] = (5.0, 0.0, 0.0)
    return np.concatenate([poses, on_axis[None], far[None]])


def test_one_pose_alone_is_its_batch_row():
    poses = degenerate_and_random_poses()
    batch_q, batch_ok = ARM.ik(poses)
    for pose, expected_q, expected_ok in zip(poses, batch_q, batch_ok, strict=True):
        q, ok = ARM.ik(pose)
        np.testing.assert_array_equal(ok, expected_ok)
        np.testing.assert_array_equal(q, expected_q)


def test_a_bad_pose_matrix_is_rejected():
    pose = ARM.fk(ARM.home)
    for bad, message in (
        (np.where(np.eye(4, dtype=bool), np.inf, pose), "NaN or inf"),
        (pose * np.array([1, 1, 1.01, 1])[:, None], "not orthonormal"),
        (pose @ np.diag([-1.0, 1.0, 1.0, 1.0]), "reflection"),
        (pose + np.array([[0, 0, 0, 0]] * 3 + [[0, 0, 0.5, 0]]), "bottom row"),
    ):
        with pytest.raises(ValueError, match=message):
            ARM.ik(bad)
