"""Gripper frames from the papers' inputs: four body points (eq. 3) or a point path (eq. 7)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .rotations import as_float_array, homogeneous

#: Largest deviation (relative, dimensionless) of the four points from an orthonormal,
#: right-handed triad with the stated a, b, c. Drawing or measuring tolerances of real
#: fixtures are far above float rounding; 1e-6 rejects every wrong point set in practice.
TRIAD_TOL = 1e-6
#: Speed / curvature below which a path's Frenet frame is undefined (SI units).
FRENET_TOL = 1e-12


def pose_from_points(points: ArrayLike, a: float, b: float, c: float) -> np.ndarray:
    """The paper's eq. (3): the gripper pose from four points rigidly attached to it.

    ``points`` (…, 4, 3) are the world coordinates of O (the wrist centre) and of the points
    (a, 0, 0), (0, b, 0), (0, 0, c) of the gripper frame x3y3z3. The direction cosines are
    n_i1 = (P2 − P1)_i / a, n_i2 = (P3 − P1)_i / b, n_i3 = (P4 − P1)_i / c.
    Returns the (…, 4, 4) pose. ``ValueError`` if the points do not form that triad.
    """
    points = as_float_array(points, "points")
    if points.ndim < 2 or points.shape[-2:] != (4, 3):
        raise ValueError(f"points must have shape (..., 4, 3), got {points.shape}")
    scales = np.array([a, b, c], dtype=np.float64)
    if not np.all(np.isfinite(scales)) or np.any(scales <= 0.0):
        raise ValueError(f"a, b, c must be positive and finite, got {a}, {b}, {c}")
    origin = points[..., 0, :]
    rotation = np.swapaxes((points[..., 1:, :] - origin[..., None, :]) / scales[:, None], -1, -2)
    gram = np.swapaxes(rotation, -1, -2) @ rotation
    if np.any(np.abs(gram - np.eye(3)) > TRIAD_TOL):
        raise ValueError(
            "points do not form an orthonormal triad with the stated a, b, c "
            f"(tolerance {TRIAD_TOL:g}): check the point order and the distances a, b, c"
        )
    if np.any(np.linalg.det(rotation) < 0.0):
        raise ValueError("points form a left-handed triad: x3, y3, z3 must be right-handed")
    return homogeneous(rotation, origin)


def frenet_rotation(velocity: ArrayLike, acceleration: ArrayLike) -> np.ndarray:
    """Gripper axes x, y, z along a path's tangent, principal normal and binormal (eq. 7).

    ``velocity`` ṙ and ``acceleration`` r̈ are (…, 3). The binormal is ṙ × r̈ / |ṙ × r̈|
    (the printed formulas lost their dots) and the normal completes the triad, y = z × x.
    ``ValueError`` where the speed or the curvature vanishes (the normal is undefined).
    """
    velocity = as_float_array(velocity, "velocity")
    acceleration = as_float_array(acceleration, "acceleration")
    if velocity.shape[-1:] != (3,) or acceleration.shape[-1:] != (3,):
        raise ValueError("velocity and acceleration must have shape (..., 3)")
    speed = np.linalg.norm(velocity, axis=-1, keepdims=True)
    cross = np.cross(velocity, acceleration)
    cross_norm = np.linalg.norm(cross, axis=-1, keepdims=True)
    if np.any(speed < FRENET_TOL):
        raise ValueError("the path's speed vanishes: its tangent is undefined")
    if np.any(cross_norm < FRENET_TOL * speed**3):
        raise ValueError("the path's curvature vanishes (straight segment): normal undefined")
    tangent = velocity / speed
    binormal = cross / cross_norm
    normal = np.cross(binormal, tangent)
    return np.stack([tangent, normal, binormal], axis=-1)


def frenet_pose(
    point: ArrayLike, velocity: ArrayLike, acceleration: ArrayLike, b: float
) -> np.ndarray:
    """Pose of the wrist centre when a path point r(t) of the object is prescribed (eq. 7).

    The object point lies b along the gripper's y axis (the principal normal) from the wrist
    centre, so O = r − b·n_·2. Returns (…, 4, 4).
    """
    point = as_float_array(point, "point")
    if point.shape[-1:] != (3,):
        raise ValueError(f"point must have shape (..., 3), got {point.shape}")
    if not np.isfinite(b):
        raise ValueError("b must be finite")
    rotation = frenet_rotation(velocity, acceleration)
    return homogeneous(rotation, point - b * rotation[..., :, 1])
