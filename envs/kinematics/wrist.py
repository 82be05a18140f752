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
from collections.abc import Sequence

import numpy as np

from .rotations import rot_x, rot_y

#: Below this |sin b| the wrist is treated as singular and the free angle split evenly.
#: Above it a is ill-conditioned but harmless: c is solved from a, so FK stays exact.
WRIST_SINGULAR_TOL = 1e-12


def wrist_rotation(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Ry(a)·Rx(b)·Ry(c), batched."""
    return rot_y(a) @ rot_x(b) @ rot_y(c)


def solve_yxy_wrist(r_wrist: np.ndarray) -> np.ndarray:
    """All solutions of Ry(a)Rx(b)Ry(c) = ``r_wrist`` (…, 3, 3).

    Returns (…, 2, 3): row 0 has b ≥ 0 ("wrist +"), row 1 b ≤ 0 ("wrist −"); angles in
    [−π, π] (the arm wraps them to [−π, π)). Always finite for a finite rotation.
    """
    return np.stack(wrist_branches(*_wrist_entries(r_wrist)), axis=-1)


def wrist_branches(
    r00: np.ndarray, r01: np.ndarray, r02: np.ndarray, r11: np.ndarray, r20: np.ndarray,
    r21: np.ndarray, r22: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``solve_yxy_wrist`` from the seven entries of R_w it reads, each a (…,) array.

    Returns the columns (a, b, c), each (…, 2) with the + branch first. Entries in and
    columns out let callers keep every array contiguous: on big batches strided slices of
    (…, 3, 3) stacks cost more than the arithmetic.
    """
    sin_b = np.sqrt(r01 * r01 + r21 * r21)  # entries are bounded by 1: no need for hypot
    b = np.arctan2(sin_b, r11)
    a = np.arctan2(r01, r21)
    singular = sin_b < WRIST_SINGULAR_TOL
    shift: float | np.ndarray = np.pi
    # (cos a, sin a) is column 1's (R21, R01) normalised: no trigonometry needed. Singular
    # rows (sin b ≈ 0) are replaced below, each row on its own, so a pose's branches do not
    # depend on the rest of its batch.
    with np.errstate(divide="ignore", invalid="ignore"):
        ca, sa = r21 / sin_b, r01 / sin_b
    if np.any(singular):
        # cos b = ±1 here: a ± c = atan2(±R02, R00); split the free angle evenly.
        folded = r11 < 0.0
        a = np.where(singular, 0.5 * np.arctan2(np.where(folded, -r02, r02), r00), a)
        b = np.where(singular, np.where(folded, np.pi, 0.0), b)
        ca, sa = np.where(singular, np.cos(a), ca), np.where(singular, np.sin(a), sa)
        shift = np.where(singular, 0.0, np.pi)  # the flipped branch is the same configuration
    c = np.arctan2(ca * r02 - sa * r22, ca * r00 - sa * r20)
    # The flipped branch is (a + π, −b, c + π), kept inside [−π, π].
    flipped_a = np.where(a > 0.0, a - shift, a + shift)
    flipped_c = np.where(c > 0.0, c - shift, c + shift)
    return (
        np.stack([a, flipped_a], axis=-1),
        np.stack([b, -b], axis=-1),
        np.stack([c, flipped_c], axis=-1),
    )


def solve_with_wrist(positioning: np.ndarray, r_wrist: np.ndarray) -> list[np.ndarray]:
    """Complete positioning solutions with both wrist branches.

    ``positioning`` (…, P, 3) joint values of the positioning part and ``r_wrist``
    (…, P, 3, 3) the rotation the wrist must realise for each, R_posᵀ·R. Returns the six
    joint columns, each (…, 2P): for each positioning solution, wrist + then wrist −.
    """
    return with_positioning(
        [positioning[..., j] for j in range(3)], wrist_branches(*_wrist_entries(r_wrist))
    )


def with_positioning(
    positioning: Sequence[np.ndarray], wrist: Sequence[np.ndarray]
) -> list[np.ndarray]:
    """Columns of (…, P) positioning joints and (…, P, 2) wrist joints -> six (…, 2P) columns."""
    columns = [np.repeat(column, 2, axis=-1) for column in positioning]
    columns += [column.reshape((*column.shape[:-2], -1)) for column in wrist]
    return columns


def _wrist_entries(r_wrist: np.ndarray) -> tuple[np.ndarray, ...]:
    return tuple(
        r_wrist[..., i, j] for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (2, 0), (2, 1), (2, 2))
    )


def wrist_branches_scalar(
    r00: float, r01: float, r02: float, r11: float, r20: float, r21: float, r22: float,
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """``wrist_branches`` for one rotation given as floats: ((a, b, c), (a', b', c')).

    The same formulas, on floats with ``math``: the kernels of the compiled single-pose
    path call it (``envs/kinematics/compiled.py``). Tests hold the two to the same results.
    """
    sin_b = math.sqrt(r01 * r01 + r21 * r21)
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
    into ``out[row]`` and ``out[row + 1]`` (a kernel of the single-pose path)."""
    plus, minus = wrist_branches_scalar(r00, r01, r02, r11, r20, r21, r22)
    out[row, 0], out[row, 1], out[row, 2] = q1, q2, q3
    out[row, 3], out[row, 4], out[row, 5] = plus[0], plus[1], plus[2]
    out[row + 1, 0], out[row + 1, 1], out[row + 1, 2] = q1, q2, q3
    out[row + 1, 3], out[row + 1, 4], out[row + 1, 5] = minus[0], minus[1], minus[2]
