"""The paper's spherical wrist R = Ry(a)·Rx(b)·Ry(c), shared by all four six-DOF arms.

Klyuiko (1986) ends every six-DOF arm in the same three revolute joints about the local
y, x and y axes (eq. 1, matrices M1–M3). After the positioning joints' rotation R_pos is
removed, the wrist must realise R_w = R_posᵀ·R. Writing R_w = Ry(a)Rx(b)Ry(c):

    R_w[1,1] = cos b,  R_w[0,1] = sin a sin b,  R_w[2,1] = cos a sin b,
    R_w[1,0] = sin b sin c,  R_w[1,2] = −sin b cos c,

so b = ±atan2(√(R01² + R21²), R11) (the "flip" pair) and a follows from column 1. The
second branch is (a + π, −b, c + π). c is not read from row 1 but from what is left once
Ry(a) is known, c = atan2(M02, M00) with M = Ry(−a)·R_w, which keeps FK exact even when
sin b is tiny and a is poorly conditioned.

Singularity (sin b < ``WRIST_SINGULAR_TOL``): only a ± c is defined. The free angle is split
evenly, a = θ/2 (θ = a + c at b = 0, θ = a − c at b = π), which keeps both joints within
±π/2 of zero; both flip branches then coincide and both are returned as valid.
"""

from __future__ import annotations

import numpy as np

from .rotations import rot_x, rot_y, wrap_angle

#: Below this |sin b| the wrist is treated as singular and the free angle split evenly.
WRIST_SINGULAR_TOL = 1e-10


def wrist_rotation(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Ry(a)·Rx(b)·Ry(c), batched."""
    return rot_y(a) @ rot_x(b) @ rot_y(c)


def solve_yxy_wrist(r_wrist: np.ndarray) -> np.ndarray:
    """All solutions of Ry(a)Rx(b)Ry(c) = ``r_wrist`` (…, 3, 3).

    Returns (…, 2, 3): row 0 has b ≥ 0 ("wrist +"), row 1 b ≤ 0 ("wrist −"); angles
    wrapped to [−π, π). Always finite for a finite rotation.
    """
    r00, r01, r02 = r_wrist[..., 0, 0], r_wrist[..., 0, 1], r_wrist[..., 0, 2]
    r11 = r_wrist[..., 1, 1]
    r20, r21, r22 = r_wrist[..., 2, 0], r_wrist[..., 2, 1], r_wrist[..., 2, 2]
    sin_b = np.hypot(r01, r21)
    b = np.arctan2(sin_b, r11)
    singular = sin_b < WRIST_SINGULAR_TOL
    a = np.arctan2(r01, r21)
    if np.any(singular):
        # cos b = ±1 here: a ± c = atan2(±R02, R00); split the free angle evenly.
        sign = np.where(r11 >= 0.0, 1.0, -1.0)
        a = np.where(singular, 0.5 * np.arctan2(sign * r02, r00), a)
    ca, sa = np.cos(a), np.sin(a)
    c = np.arctan2(ca * r02 - sa * r22, ca * r00 - sa * r20)
    flipped_a = np.where(singular, a, wrap_angle(a + np.pi))
    flipped_b = np.where(singular, b, -b)
    flipped_c = np.where(singular, c, wrap_angle(c + np.pi))
    return np.stack(
        [np.stack([a, b, c], -1), np.stack([flipped_a, flipped_b, flipped_c], -1)], -2
    )


def solve_with_wrist(
    positioning: np.ndarray, r_positioning: np.ndarray, rotation: np.ndarray
) -> np.ndarray:
    """Complete positioning solutions with both wrist branches.

    ``positioning`` (…, P, 3) joint values of the positioning part, ``r_positioning``
    (…, P, 3, 3) the rotation they produce, ``rotation`` (…, 3, 3) the target orientation.
    Returns (…, 2P, 6): for each positioning solution, wrist + then wrist −.
    """
    r_wrist = np.swapaxes(r_positioning, -1, -2) @ rotation[..., None, :, :]
    wrist = solve_yxy_wrist(r_wrist)  # (…, P, 2, 3)
    positioning = np.broadcast_to(positioning[..., None, :], wrist.shape)
    both = np.concatenate([positioning, wrist], axis=-1)  # (…, P, 2, 6)
    return both.reshape((*both.shape[:-3], -1, 6))
