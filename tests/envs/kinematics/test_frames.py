"""Pose from four points (eq. 3) and the Frenet frame of a point path (eq. 7)."""

from __future__ import annotations

import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import frenet_pose, frenet_rotation, pose_from_points
from ikbranch_gym.envs.kinematics.rotations import rot_x, rot_y, rot_z


def body_points(rotation, origin, a, b, c):
    return np.stack([origin, origin + a * rotation[:, 0], origin + b * rotation[:, 1],
                     origin + c * rotation[:, 2]])


def test_pose_from_points_recovers_the_frame():
    rotation = rot_z(0.3) @ rot_x(-1.1) @ rot_y(2.0)
    origin = np.array([0.4, -0.2, 1.3])
    pose = pose_from_points(body_points(rotation, origin, 0.05, 0.35, 0.05), 0.05, 0.35, 0.05)
    np.testing.assert_allclose(pose[:3, :3], rotation, atol=1e-12)
    np.testing.assert_allclose(pose[:3, 3], origin, atol=1e-15)
    np.testing.assert_array_equal(pose[3], [0, 0, 0, 1])


def test_pose_from_points_rejects_inconsistent_points():
    points = body_points(np.eye(3), np.zeros(3), 0.05, 0.35, 0.05)
    with pytest.raises(ValueError, match="orthonormal triad"):
        pose_from_points(points, 0.05, 0.30, 0.05)  # wrong b
    with pytest.raises(ValueError, match="orthonormal triad"):
        pose_from_points(points[[0, 2, 1, 3]], 0.05, 0.35, 0.05)  # swapped points
    with pytest.raises(ValueError, match="left-handed"):
        pose_from_points(body_points(np.diag([1.0, 1.0, -1.0]), np.zeros(3), 1, 1, 1), 1, 1, 1)
    with pytest.raises(ValueError, match="shape"):
        pose_from_points(points[:3], 0.05, 0.35, 0.05)
    with pytest.raises(ValueError, match="NaN"):
        pose_from_points(np.full((4, 3), np.nan), 1, 1, 1)
    with pytest.raises(ValueError, match="positive"):
        pose_from_points(points, 0.05, -0.35, 0.05)


def helix(t, radius=0.5, pitch=0.2):
    w = 2.0
    point = np.stack([radius * np.cos(w * t), radius * np.sin(w * t), pitch * t], -1)
    velocity = np.stack([-radius * w * np.sin(w * t), radius * w * np.cos(w * t),
                         np.full_like(t, pitch)], -1)
    acceleration = np.stack([-radius * w**2 * np.cos(w * t), -radius * w**2 * np.sin(w * t),
                             np.zeros_like(t)], -1)
    return point, velocity, acceleration


def test_frenet_frame_of_a_helix():
    t = np.linspace(0.0, 3.0, 7)
    point, velocity, acceleration = helix(t)
    rotation = frenet_rotation(velocity, acceleration)
    # Proper rotations; tangent along the velocity; the principal normal of a helix points
    # horizontally at its axis; the binormal has a constant positive vertical component.
    np.testing.assert_allclose(rotation @ np.swapaxes(rotation, -1, -2),
                               np.broadcast_to(np.eye(3), (7, 3, 3)), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(rotation), 1.0, atol=1e-12)
    np.testing.assert_allclose(rotation[..., 0],
                               velocity / np.linalg.norm(velocity, axis=-1, keepdims=True))
    inward = -point[:, :2] / np.linalg.norm(point[:, :2], axis=-1, keepdims=True)
    np.testing.assert_allclose(rotation[:, :2, 1], inward, atol=1e-12)
    np.testing.assert_allclose(rotation[:, 2, 1], 0.0, atol=1e-12)
    assert np.all(rotation[:, 2, 2] > 0) and np.ptp(rotation[:, 2, 2]) < 1e-12


def test_frenet_pose_offsets_the_wrist_centre_along_the_normal():
    point, velocity, acceleration = helix(np.array([0.7]))
    pose = frenet_pose(point, velocity, acceleration, b=0.35)
    np.testing.assert_allclose(pose[:, :3, 3] + 0.35 * pose[:, :3, 1], point, atol=1e-15)


def test_frenet_frame_is_undefined_on_straight_lines_and_at_rest():
    with pytest.raises(ValueError, match="curvature vanishes"):
        frenet_rotation([1.0, 2.0, 0.0], [2.0, 4.0, 0.0])
    with pytest.raises(ValueError, match="speed vanishes"):
        frenet_rotation([0.0, 0.0, 0.0], [1.0, 0.0, 0.0])
