"""Batched elementary rotations, homogeneous transforms and input validation.

Every function broadcasts over leading axes. Angles in radians, lengths in metres.
"""

from __future__ import annotations

import numpy as np

#: Largest |RᵀR − I| entry accepted as an orthonormal rotation. Poses built from measured
#: points or float32 pipelines carry ~1e-7 noise; anything beyond 1e-6 is a wrong matrix.
ORTHONORMAL_TOL = 1e-6


def rot_x(angle: np.ndarray) -> np.ndarray:
    """Rotation about x by ``angle`` (…,) -> (…, 3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    one, zero = np.ones_like(c), np.zeros_like(c)
    return np.stack(
        [np.stack([one, zero, zero], -1), np.stack([zero, c, -s], -1), np.stack([zero, s, c], -1)],
        -2,
    )


def rot_y(angle: np.ndarray) -> np.ndarray:
    """Rotation about y by ``angle`` (…,) -> (…, 3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    one, zero = np.ones_like(c), np.zeros_like(c)
    return np.stack(
        [np.stack([c, zero, s], -1), np.stack([zero, one, zero], -1), np.stack([-s, zero, c], -1)],
        -2,
    )


def rot_z(angle: np.ndarray) -> np.ndarray:
    """Rotation about z by ``angle`` (…,) -> (…, 3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    one, zero = np.ones_like(c), np.zeros_like(c)
    return np.stack(
        [np.stack([c, -s, zero], -1), np.stack([s, c, zero], -1), np.stack([zero, zero, one], -1)],
        -2,
    )


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
    return np.remainder(angle + np.pi, 2.0 * np.pi) - np.pi


def as_float_array(value, name: str) -> np.ndarray:
    """``value`` as a float64 array; ``ValueError`` naming ``name`` if it holds NaN or inf."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be numeric, got {type(value).__name__}") from exc
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} contains NaN or inf")
    return array


def validate_pose(pose, name: str = "pose") -> np.ndarray:
    """Check a batch of homogeneous transforms (…, 4, 4) and return it as float64.

    Raises ``ValueError`` for a wrong shape, NaN/inf, a bottom row other than (0, 0, 0, 1),
    or a rotation block that is not a proper rotation within ``ORTHONORMAL_TOL``.
    """
    pose = as_float_array(pose, name)
    if pose.ndim < 2 or pose.shape[-2:] != (4, 4):
        raise ValueError(f"{name} must have shape (..., 4, 4), got {pose.shape}")
    if np.any(np.abs(pose[..., 3, :] - (0.0, 0.0, 0.0, 1.0)) > ORTHONORMAL_TOL):
        raise ValueError(f"{name} bottom row must be (0, 0, 0, 1)")
    rotation = pose[..., :3, :3]
    gram = np.einsum("...ki,...kj->...ij", rotation, rotation)
    if np.any(np.abs(gram - np.eye(3)) > ORTHONORMAL_TOL):
        raise ValueError(
            f"{name} rotation block is not orthonormal (tolerance {ORTHONORMAL_TOL:g})"
        )
    if np.any(np.linalg.det(rotation) < 0.0):
        raise ValueError(f"{name} rotation block is a reflection (det < 0), not a rotation")
    return pose
