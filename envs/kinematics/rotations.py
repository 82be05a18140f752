"""Rotations and poses: elementary rotations, homogeneous transforms, quaternions,
roll-pitch-yaw angles, and input validation.

Angles in radians, lengths in metres; quaternions are (w, x, y, z). The elementary
rotations, ``homogeneous`` and ``quaternion_matrix`` broadcast over leading axes; the
conversions of one rotation (``rpy_matrix``, ``rotation_to_quaternion``,
``axis_quaternion``, ``invert_pose``) take one value, computed with scalar arithmetic so
that every caller (waypoint files, scene files, the models' builders) gets the same bits.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

#: Largest |RᵀR − I| entry accepted as an orthonormal rotation. Poses built from measured
#: points or float32 pipelines carry ~1e-7 noise; anything beyond 1e-6 is a wrong matrix.
ORTHONORMAL_TOL = 1e-6


def _elementary(angle: ArrayLike, axis: int) -> np.ndarray:
    angle = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    out = np.zeros((*angle.shape, 3, 3))
    out[..., axis, axis] = 1.0
    out[..., i, i] = c
    out[..., j, j] = c
    out[..., i, j] = -s
    out[..., j, i] = s
    return out


def rot_x(angle: ArrayLike) -> np.ndarray:
    """Rotation about x by ``angle`` (…,) -> (…, 3, 3)."""
    return _elementary(angle, 0)


def rot_y(angle: ArrayLike) -> np.ndarray:
    """Rotation about y by ``angle`` (…,) -> (…, 3, 3)."""
    return _elementary(angle, 1)


def rot_z(angle: ArrayLike) -> np.ndarray:
    """Rotation about z by ``angle`` (…,) -> (…, 3, 3)."""
    return _elementary(angle, 2)


def homogeneous(rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    """Assemble (…, 4, 4) transforms from (…, 3, 3) rotations and (…, 3) translations."""
    # Assignment broadcasts each into place (no broadcast copies made first).
    out = np.zeros((*np.broadcast_shapes(rotation.shape[:-2], translation.shape[:-1]), 4, 4))
    out[..., :3, :3] = rotation
    out[..., :3, 3] = translation
    out[..., 3, 3] = 1.0
    return out


def invert_pose(pose: ArrayLike) -> np.ndarray:
    """The inverse (4, 4) of a rigid transform (4, 4): (Rᵀ, −Rᵀ·t)."""
    pose = np.asarray(pose, dtype=np.float64)
    rotation, position = pose[:3, :3], pose[:3, 3]
    inverse = np.eye(4)
    inverse[:3, :3] = rotation.T
    inverse[:3, 3] = -(rotation.T @ position)
    return inverse


def quaternion_matrix(quaternion: ArrayLike) -> np.ndarray:
    """Rotations (…, 3, 3) of quaternions (…, 4) (w, x, y, z) of norm ≈ 1.

    Computed with s = 2/‖q‖² (for ‖q‖ = 1 exactly, the unit-quaternion formula), so a
    quaternion whose norm differs from 1 by rounding still gives its rotation to rounding;
    callers check the norm (nothing here normalises beyond that).
    """
    q = np.asarray(quaternion, dtype=np.float64)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    s = 2.0 / (w * w + x * x + y * y + z * z)
    out = np.empty((*q.shape[:-1], 3, 3))
    out[..., 0, 0] = 1.0 - s * (y * y + z * z)
    out[..., 0, 1] = s * (x * y - w * z)
    out[..., 0, 2] = s * (x * z + w * y)
    out[..., 1, 0] = s * (x * y + w * z)
    out[..., 1, 1] = 1.0 - s * (x * x + z * z)
    out[..., 1, 2] = s * (y * z - w * x)
    out[..., 2, 0] = s * (x * z - w * y)
    out[..., 2, 1] = s * (y * z + w * x)
    out[..., 2, 2] = 1.0 - s * (x * x + y * y)
    return out


def rotation_to_quaternion(rotation: ArrayLike) -> np.ndarray:
    """Unit quaternion (w, x, y, z), w ≥ 0, of a (3, 3) rotation (Shepperd's method)."""
    m = np.asarray(rotation, dtype=np.float64)
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    candidates = (trace, m[0, 0], m[1, 1], m[2, 2])
    k = int(np.argmax(candidates))
    if k == 0:
        s = 2.0 * math.sqrt(1.0 + trace)
        q = (0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s)
    elif k == 1:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = ((m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s)
    elif k == 2:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = ((m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s)
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = ((m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s)
    quaternion = np.array(q)
    # The rotation's own quaternion; only rounding is removed here.
    quaternion /= np.linalg.norm(quaternion)
    return -quaternion if quaternion[0] < 0 else quaternion


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Rz(yaw)·Ry(pitch)·Rx(roll) (3, 3): fixed axes x, then y, then z (URDF's ``rpy``;
    the Z-Y-X Euler angles yaw, pitch, roll of the same rotation)."""
    cr, sr, cp, sp, cy, sy = (
        f(angle) for angle in (roll, pitch, yaw) for f in (math.cos, math.sin)
    )
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def zyx_angles(rotation: ArrayLike) -> tuple[float, float, float]:
    """(A, B, C) rad with ``rotation`` = Rz(A)·Ry(B)·Rx(C) (KUKA's A, B, C; ``rpy_matrix``'s
    yaw, pitch, roll), B in [−π/2, π/2]. At B = ±π/2 only A ∓ C is defined: C is 0 there."""
    m = np.asarray(rotation, dtype=np.float64)
    cos_b = math.hypot(m[0, 0], m[1, 0])
    b = math.atan2(-m[2, 0], cos_b)
    if cos_b < 1e-12:
        return math.atan2(-m[0, 1], m[1, 1]), b, 0.0
    return math.atan2(m[1, 0], m[0, 0]), b, math.atan2(m[2, 1], m[2, 2])


def rotation_vector(rotation: ArrayLike) -> np.ndarray:
    """(3,) the axis times the angle (rad, in [0, π]) of ``rotation`` (UR's rx, ry, rz)."""
    w, x, y, z = rotation_to_quaternion(rotation)  # w >= 0: the angle is at most π
    sine = math.sqrt(x * x + y * y + z * z)
    if sine < 1e-15:
        return np.zeros(3)
    angle = 2.0 * math.atan2(sine, w)
    return np.array([x, y, z]) * (angle / sine)


def axis_quaternion(axis: str, angle: float) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a turn by ``angle`` about the axis "x", "y" or "z"."""
    quaternion = np.zeros(4)
    quaternion[0] = np.cos(angle / 2)
    quaternion["xyz".index(axis) + 1] = np.sin(angle / 2)
    return quaternion


def as_float_array(value: ArrayLike, name: str, check_finite: bool = True) -> np.ndarray:
    """``value`` as a float64 array; ``ValueError`` naming ``name`` if it is not numeric or
    (with ``check_finite``, for callers that do not check each element themselves) holds
    NaN or inf."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be numeric, got {type(value).__name__}") from exc
    if check_finite and not np.all(np.isfinite(array)):
        raise ValueError(f"{name} contains NaN or inf")
    return array
