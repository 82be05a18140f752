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

Singularity (sin b < ``WRIST_SINGULAR_TOL``): only a ± c is defined. b is snapped to 0 or
±π (an error below the tolerance) and the free angle is split evenly, a = θ/2 (θ = a + c at
b = 0, θ = a − c at b = π), which keeps both joints within ±π/2 of zero; the two flip
branches then describe the same configuration and both are returned as valid.
"""

from __future__ import annotations

import math

import numpy as np

from .rotations import rot_x, rot_y

#: Below this |sin b| the wrist is treated as singular and the free angle split evenly.
#: Above it a is ill-conditioned but harmless: c is solved from a, so FK stays exact.
WRIST_SINGULAR_TOL = 1e-12


def wrist_rotation(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Ry(a)·Rx(b)·Ry(c), batched."""
    return rot_y(a) @ rot_x(b) @ rot_y(c)


def solve_yxy_wrist(r_wrist: np.ndarray) -> np.ndarray:
    """All solutions of Ry(a)Rx(b)Ry(c) = ``r_wrist`` (3, 3), as a (2, 3) array: row 0 has
    b ≥ 0 ("wrist +"), row 1 b ≤ 0 ("wrist −"); angles in [−π, π] (the arm wraps them to
    [−π, π)). Always finite for a finite rotation. ``wrist_branches`` on its entries."""
    r = np.asarray(r_wrist, dtype=np.float64)
    if r.shape != (3, 3):
        raise ValueError(f"r_wrist must have shape (3, 3), got {r.shape}")
    plus, minus = wrist_branches(
        float(r[0, 0]), float(r[0, 1]), float(r[0, 2]), float(r[1, 1]), float(r[2, 0]),
        float(r[2, 1]), float(r[2, 2]),
    )
    return np.array([plus, minus])


def wrist_branches(
    r00: float, r01: float, r02: float, r11: float, r20: float, r21: float, r22: float,
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """Both wrist branches ((a, b, c), (a', b', c')) from the seven entries of R_w they read,
    as floats: the one statement of the wrist's closed form, called by the IK kernels
    (``envs/kinematics/compiled.py``; plain Python on floats and ``math``).

    (cos a, sin a) is column 1's (R21, R01) normalised by sin b: no trigonometry needed.
    Below ``WRIST_SINGULAR_TOL`` (cos b = ±1) only a ± c = atan2(±R02, R00) is defined: the
    free angle is split evenly and both rows are the same configuration. Otherwise the
    flipped branch is (a + π, −b, c + π), kept inside [−π, π].
    """
    sin_b = math.sqrt(r01 * r01 + r21 * r21)  # entries are bounded by 1: no need for hypot
    if sin_b < WRIST_SINGULAR_TOL:
        folded = r11 < 0.0
        a = 0.5 * math.atan2(-r02 if folded else r02, r00)
        b = math.pi if folded else 0.0
        ca, sa = math.cos(a), math.sin(a)
        c = math.atan2(ca * r02 - sa * r22, ca * r00 - sa * r20)
        return (a, b, c), (a, -b, c)
    b = math.atan2(sin_b, r11)
    a = math.atan2(r01, r21)
    ca, sa = r21 / sin_b, r01 / sin_b
    c = math.atan2(ca * r02 - sa * r22, ca * r00 - sa * r20)
    flipped_a = a - math.pi if a > 0.0 else a + math.pi
    flipped_c = c - math.pi if c > 0.0 else c + math.pi
    return (a, b, c), (flipped_a, -b, flipped_c)


def put_wrist_rows(
    out: np.ndarray, row: int, q1: float, q2: float, q3: float, r00: float, r01: float,
    r02: float, r11: float, r20: float, r21: float, r22: float,
) -> None:
    """Write the rows (q1, q2, q3, wrist +) and (q1, q2, q3, wrist −) of a six-joint arm
    into ``out[row]`` and ``out[row + 1]`` (for the IK kernels)."""
    plus, minus = wrist_branches(r00, r01, r02, r11, r20, r21, r22)
    out[row, 0], out[row, 1], out[row, 2] = q1, q2, q3
    out[row, 3], out[row, 4], out[row, 5] = plus[0], plus[1], plus[2]
    out[row + 1, 0], out[row + 1, 1], out[row + 1, 2] = q1, q2, q3
    out[row + 1, 3], out[row + 1, 4], out[row + 1, 5] = minus[0], minus[1], minus[2]
