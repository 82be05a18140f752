"""envs.kinematics.rotations: quaternions, roll-pitch-yaw, axis turns and pose inverses
against independent definitions (scipy's ``Rotation``, numpy's inverse), their properties
(orthonormal, det 1, round trips), and one definition of each in the product."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import ikbranch_gym.envs as envs
from ikbranch_gym.envs.kinematics.rotations import (
    axis_quaternion,
    homogeneous,
    invert_pose,
    quaternion_matrix,
    rot_x,
    rot_y,
    rot_z,
    rotation_to_quaternion,
    rotation_vector,
    rpy_matrix,
    zyx_angles,
)

N = 300


def _unit_quaternions(rng: np.random.Generator, n: int = N) -> np.ndarray:
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _scipy(q_wxyz: np.ndarray) -> Rotation:
    """scipy's Rotation of (w, x, y, z) quaternions (scipy orders them x, y, z, w)."""
    return Rotation.from_quat(np.asarray(q_wxyz)[..., [1, 2, 3, 0]])


def _special_rotations() -> list[np.ndarray]:
    """Half turns (the trace −1 cases of Shepperd's method), the identity, tiny turns."""
    out = [np.eye(3), np.diag([1.0, -1, -1]), np.diag([-1.0, 1, -1]), np.diag([-1.0, -1, 1])]
    for rot in (rot_x, rot_y, rot_z):
        out += [rot(a) for a in (np.pi, -np.pi, np.pi / 2, 1e-12, np.pi - 1e-9)]
    return out


def _assert_rotation(r: np.ndarray) -> None:
    eye = np.broadcast_to(np.eye(3), r.shape)
    np.testing.assert_allclose(np.swapaxes(r, -1, -2) @ r, eye, atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-14)


def test_quaternion_matrix_is_scipys_rotation_and_batches_bit_for_bit():
    q = _unit_quaternions(np.random.default_rng(0))
    r = quaternion_matrix(q)
    assert r.shape == (N, 3, 3)
    np.testing.assert_allclose(r, _scipy(q).as_matrix(), atol=1e-15)
    _assert_rotation(r)
    # Batched over any leading axes, each element exactly the one-quaternion value.
    assert np.array_equal(np.stack([quaternion_matrix(v) for v in q]), r)
    assert np.array_equal(quaternion_matrix(q.reshape(10, 30, 4)), r.reshape(10, 30, 3, 3))
    # q and −q are one rotation; a norm off 1 by rounding gives the rotation to rounding.
    assert np.array_equal(quaternion_matrix(-q), r)
    np.testing.assert_allclose(quaternion_matrix(q * (1 + 1e-7)), r, atol=1e-14)


def test_rotation_to_quaternion_is_scipys_with_w_nonnegative():
    rng = np.random.default_rng(1)
    rotations = [*Rotation.random(N, random_state=rng).as_matrix(), *_special_rotations()]
    for r in rotations:
        q = rotation_to_quaternion(r)
        assert q[0] >= 0.0 and np.linalg.norm(q) == pytest.approx(1.0, abs=1e-15)
        expected = Rotation.from_matrix(r).as_quat()[[3, 0, 1, 2]]
        expected = expected if expected[0] >= 0 else -expected
        if q[0] < 1e-12:  # a half turn: q and −q both have w = 0
            expected = expected * np.sign(expected @ q)
        np.testing.assert_allclose(q, expected, atol=1e-14)
        # Round trip: matrix -> quaternion -> matrix.
        np.testing.assert_allclose(quaternion_matrix(q), r, atol=1e-14)


def test_quaternion_round_trip_up_to_sign():
    q = _unit_quaternions(np.random.default_rng(2))
    back = np.stack([rotation_to_quaternion(r) for r in quaternion_matrix(q)])
    np.testing.assert_allclose(back, q * np.sign(q[:, :1]), atol=1e-14)


def test_rpy_matrix_is_fixed_axes_xyz_and_euler_zyx():
    rng = np.random.default_rng(3)
    angles = rng.uniform(-4.0, 4.0, size=(N, 3))
    angles[:10, 1] = np.pi / 2  # gimbal lock
    for roll, pitch, yaw in angles:
        r = rpy_matrix(roll, pitch, yaw)
        _assert_rotation(r)
        np.testing.assert_allclose(
            r, Rotation.from_euler("xyz", [roll, pitch, yaw]).as_matrix(), atol=1e-15)
        np.testing.assert_allclose(
            r, Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_matrix(), atol=1e-15)
        np.testing.assert_allclose(r, rot_z(yaw) @ rot_y(pitch) @ rot_x(roll), atol=1e-15)


@pytest.mark.parametrize("axis", ["x", "y", "z"])
def test_axis_quaternion_is_the_turn_about_the_axis(axis):
    unit = np.eye(3)["xyz".index(axis)]
    elementary = {"x": rot_x, "y": rot_y, "z": rot_z}[axis]
    for angle in np.random.default_rng(4).uniform(-7.0, 7.0, size=N // 3):
        q = axis_quaternion(axis, angle)
        assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-15)
        np.testing.assert_allclose(q, [np.cos(angle / 2), *(np.sin(angle / 2) * unit)],
                                   atol=0)
        np.testing.assert_allclose(quaternion_matrix(q),
                                   Rotation.from_rotvec(angle * unit).as_matrix(), atol=1e-15)
        np.testing.assert_allclose(quaternion_matrix(q), elementary(angle), atol=1e-15)


def test_homogeneous_places_rotations_and_translations_broadcast():
    rng = np.random.default_rng(6)
    rotations = Rotation.random(N, random_state=rng).as_matrix()
    translations = rng.normal(size=(N, 3))
    cases = [(rotations, translations), (rotations[0], translations),
             (rotations, translations[0]), (rotations[:, None], translations[None])]
    for rotation, translation in cases:
        shape = np.broadcast_shapes(rotation.shape[:-2], translation.shape[:-1])
        every_r = np.broadcast_to(rotation, (*shape, 3, 3))
        every_t = np.broadcast_to(translation, (*shape, 3))
        expected = np.zeros((*shape, 4, 4))
        for index in np.ndindex(shape):
            expected[index] = np.block([[every_r[index], every_t[index][:, None]],
                                        [np.zeros((1, 3)), np.ones((1, 1))]])
        assert np.array_equal(homogeneous(rotation, translation), expected)


def test_invert_pose_is_the_inverse_transform():
    rng = np.random.default_rng(5)
    rotations = Rotation.random(N, random_state=rng).as_matrix()
    poses = homogeneous(rotations, rng.normal(size=(N, 3)))
    for pose in poses:
        inverse = invert_pose(pose)
        np.testing.assert_allclose(inverse, np.linalg.inv(pose), atol=1e-14)
        np.testing.assert_allclose(inverse @ pose, np.eye(4), atol=1e-14)
        assert np.array_equal(inverse[3], [0.0, 0.0, 0.0, 1.0])
        assert np.array_equal(inverse[:3, :3], pose[:3, :3].T)


#: Modules that once held their own copies of these helpers.
USERS = ("tasks/waypoint_file.py", "models/scene_file.py", "models/builders.py",
         "models/builders_industrial.py", "models/builders_dual.py", "models/builders_rod.py")
HELPERS = {"quaternion_matrix", "rotation_to_quaternion", "rpy_matrix", "invert_pose",
           "axis_quaternion", "_axis_quat", "_quaternion_matrix", "_rpy_matrix"}


def test_the_rotation_helpers_are_defined_once():
    package = Path(envs.__file__).parent
    for name in USERS:
        tree = ast.parse((package / name).read_text())
        defined = {node.name for node in ast.walk(tree) if isinstance(node, ast.FunctionDef)}
        assert not defined & HELPERS, f"{name} defines {sorted(defined & HELPERS)}"


def test_zyx_angles_rebuild_the_rotation_and_are_scipys():
    rng = np.random.default_rng(5)
    rotations = [*quaternion_matrix(_unit_quaternions(rng)), *_special_rotations(),
                 rot_y(np.pi / 2) @ rot_x(0.3), rot_z(0.4) @ rot_y(-np.pi / 2)]
    for r in rotations:
        a, b, c = zyx_angles(r)
        assert -np.pi / 2 <= b <= np.pi / 2
        np.testing.assert_allclose(rot_z(a) @ rot_y(b) @ rot_x(c), r, atol=1e-12)
    # Away from B = ±90° the angles are unique: scipy's intrinsic Z-Y-X ones.
    r = quaternion_matrix(_unit_quaternions(rng, 50))
    ours = np.array([zyx_angles(m) for m in r])
    np.testing.assert_allclose(ours, Rotation.from_matrix(r).as_euler("ZYX"), atol=1e-12)


def test_rotation_vector_is_scipys():
    rng = np.random.default_rng(6)
    rotations = [*quaternion_matrix(_unit_quaternions(rng)), np.eye(3), rot_x(1e-12)]
    for r in rotations:
        vector = rotation_vector(r)
        assert np.linalg.norm(vector) <= np.pi + 1e-12
        np.testing.assert_allclose(Rotation.from_rotvec(vector).as_matrix(), r, atol=1e-12)
