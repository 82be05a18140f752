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


def homogeneous(rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    """Assemble (…, 4, 4) transforms from (…, 3, 3) rotations and (…, 3) translations."""
    rotation, translation = np.broadcast_arrays(rotation, translation[..., None])
    out = np.zeros((*rotation.shape[:-2], 4, 4))
    out[..., :3, :3] = rotation
    out[..., :3, 3] = translation[..., 0]
    out[..., 3, 3] = 1.0
    return out


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
