"""Batched elementary rotations, homogeneous transforms and input validation.

Every function broadcasts over leading axes. Angles in radians, lengths in metres.
"""

from __future__ import annotations

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


def premultiply_rotation(angle: ArrayLike, rotation: np.ndarray, axis: int) -> np.ndarray:
    """R_axis(angle)·rotation for (…,) angles and (…, 3, 3) rotations, broadcast.

    Works on rows instead of building the elementary matrix and calling matmul, which is
    several times faster for large batches of 3 × 3 products.
    """
    angle = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(angle)[..., None], np.sin(angle)[..., None]
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    shape = np.broadcast_shapes((*angle.shape, 3, 3), rotation.shape)
    out = np.empty(shape)
    out[..., axis, :] = rotation[..., axis, :]
    out[..., i, :] = c * rotation[..., i, :] - s * rotation[..., j, :]
    out[..., j, :] = s * rotation[..., i, :] + c * rotation[..., j, :]
    return out


def homogeneous(rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    """Assemble (…, 4, 4) transforms from (…, 3, 3) rotations and (…, 3) translations."""
    rotation, translation = np.broadcast_arrays(rotation, translation[..., None])
    out = np.zeros((*rotation.shape[:-2], 4, 4))
    out[..., :3, :3] = rotation
    out[..., :3, 3] = translation[..., 0]
    out[..., 3, 3] = 1.0
    return out


def wrap_angle(angle: np.ndarray) -> np.ndarray:
    """Wrap to [−π, π) (the paper's table writes a half turn as −180°)."""
    # floor instead of np.remainder: the same result, several times faster on big batches.
    return angle - (2.0 * np.pi) * np.floor((angle + np.pi) / (2.0 * np.pi))


def as_float_array(value: ArrayLike, name: str) -> np.ndarray:
    """``value`` as a float64 array; ``ValueError`` naming ``name`` if it holds NaN or inf."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be numeric, got {type(value).__name__}") from exc
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} contains NaN or inf")
    return array


def validate_rotation(rotation: np.ndarray, name: str = "rotation") -> None:
    """``ValueError`` unless every (…, 3, 3) block is a proper rotation (``ORTHONORMAL_TOL``).

    The bottom row of a pose is not read: the kinematics never use it.
    """
    x, y, z = rotation[..., 0], rotation[..., 1], rotation[..., 2]
    if not all(
        np.all(np.abs(_dot(u, v) - expected) <= ORTHONORMAL_TOL)
        for u, v, expected in ((x, x, 1), (y, y, 1), (z, z, 1), (x, y, 0), (y, z, 0), (z, x, 0))
    ):
        raise ValueError(
            f"{name} rotation block is not orthonormal (tolerance {ORTHONORMAL_TOL:g})"
        )
    if np.any(_dot(np.cross(x, y), z) < 0.0):
        raise ValueError(f"{name} rotation block is a reflection (det < 0), not a rotation")


def _dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    # Spelled out: a reduction over a length-3 axis is slow in numpy for big batches.
    return u[..., 0] * v[..., 0] + u[..., 1] * v[..., 1] + u[..., 2] * v[..., 2]
