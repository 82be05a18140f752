"""The configuration a KUKA or ABB controller names a joint configuration by, for the OPW
arms (whose joint values are the controllers', ``opw.py``).

Both describe the same three choices the closed-form branches make, from the geometry of
the configuration:

- the **wrist centre's side of axis 1**: its x in the frame that turns with axis 1
  (KUKA's "A1 coordinate system"), ≥ 0 in front ("basic area"), < 0 behind ("overhead");
- its **side of the lower arm**: in the arm's plane, whether the wrist centre lies in front
  of the line through axes 2 and 3 (the direction the arm reaches) or behind it; on the
  line the arm is stretched (KUKA's angle φ of A3);
- the **sign of axis 5**.

KUKA (KSS "Status" and "Turn", ``E6POS``'s S and T): S bit 0 = 1 behind axis 1
(overhead area), bit 1 = 1 in front of the lower arm (A3 ≥ φ), bit 2 = 1 for A5 ≤ 0;
T bit i = 1 where axis i + 1 is negative. ABB (``robtarget``'s ``confdata``): cf1, cf4,
cf6 the quarter revolution of axes 1, 4, 6 (⌊angle / 90°⌋), cfx = 4·(behind axis 1) +
2·(behind the lower arm) + (axis 5 negative). A KUKA arm in its usual posture (front,
elbow up, A5 > 0) is S 2; an ABB arm in its usual posture cfx 0.

Pure numpy; no state.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from .opw import OpwArm


def _sides(arm: OpwArm, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(behind axis 1, behind the lower arm) (…,) bool of configurations ``q`` (…, 6)."""
    theta = arm.angles_from_joints(q)
    centre = arm.wrist_centre(q)
    c1, s1 = np.cos(theta[..., 0]), np.sin(theta[..., 0])
    reach = c1 * centre[..., 0] + s1 * centre[..., 1]  # x in the frame turning with axis 1
    height = centre[..., 2]
    # The lower arm from axis 2 (a1, c1) to axis 3, c2 along (sin θ2, cos θ2).
    ux, uz = np.sin(theta[..., 1]), np.cos(theta[..., 1])
    vx, vz = reach - arm.a1, height - arm.c1
    in_front = ux * vz - uz * vx < 0.0  # the wrist centre clockwise of the lower arm
    return reach < 0.0, ~in_front


def kuka_status_turn(arm: OpwArm, q: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """KUKA's Status and Turn (…,) ints of configurations ``q`` (…, 6) (module docstring)."""
    q = np.asarray(q, dtype=np.float64)
    behind_axis1, behind_arm = _sides(arm, q)
    status = (behind_axis1.astype(np.int64) + 2 * (~behind_arm).astype(np.int64)
              + 4 * (q[..., 4] <= 0.0).astype(np.int64))
    turn = sum((q[..., j] < 0.0).astype(np.int64) << j for j in range(6))
    return status, np.asarray(turn)


def abb_confdata(arm: OpwArm, q: ArrayLike) -> np.ndarray:
    """ABB's confdata (…, 4) ints [cf1, cf4, cf6, cfx] of configurations ``q`` (…, 6)."""
    q = np.asarray(q, dtype=np.float64)
    behind_axis1, behind_arm = _sides(arm, q)
    quarter = np.floor(q[..., [0, 3, 5]] / (math.pi / 2)).astype(np.int64)
    cfx = (4 * behind_axis1.astype(np.int64) + 2 * behind_arm.astype(np.int64)
           + (q[..., 4] < 0.0).astype(np.int64))
    return np.concatenate([quarter, cfx[..., None]], axis=-1)
