"""Spherical (polar) six-DOF arm (Klyuiko 1986, fig. 3, eq. 5).

A turn φ1 about Z0 (from Y0), the shoulder O1 at height l1, an elevation φ2 about the
local x axis, a radial slide s1 along the arm's y axis; the wrist turns φ3 about y (the arm
axis), φ4 about x, φ5 about y:

    O = (0, 0, l1) + Rz(φ1)·(0, s1 cos φ2, s1 sin φ2),   R = Rz(φ1)·Rx(φ2)·Ry(φ3)Rx(φ4)Ry(φ5)

With a positive stroke and |φ2| < 90° the position part is unique (the paper: φ1, φ2 and
s1 "determined uniquely"); the reach-over solution (φ1 + π, π − φ2) lies outside the
elevation range by construction. Branches (2): wrist + / − (sign of φ4).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from .arm import PRISMATIC, REVOLUTE, Arm, array_default
from .rotations import homogeneous, rot_x, rot_z
from .wrist import put_wrist_rows, wrist_rotation

_DEG = np.pi / 180.0


@dataclass(frozen=True, eq=False)
class SphericalArm(Arm):
    """Polar robot (Unimate-like). The paper gives no dimensions: shoulder height, stroke
    and elevation range are those of a mid-size polar industrial robot; the elevation must
    stay inside (−90°, 90°) for the position part to be unique."""

    name: ClassVar[str] = "spherical"
    joint_names: ClassVar[tuple[str, ...]] = ("phi1", "phi2", "s1", "phi3", "phi4", "phi5")
    joint_types: ClassVar[tuple[str, ...]] = (
        REVOLUTE, REVOLUTE, PRISMATIC, REVOLUTE, REVOLUTE, REVOLUTE,
    )
    closed_form_labels: ClassVar[tuple[str, ...]] = ("wrist+", "wrist-")

    #: Shoulder height O0O1 (m).
    l1: float = 0.9
    joint_limits: np.ndarray = field(default_factory=array_default((
        (-170 * _DEG, 170 * _DEG),
        (-45 * _DEG, 60 * _DEG),
        (0.4, 1.4),
        (-np.pi, np.pi),
        (-135 * _DEG, 135 * _DEG),
        (-np.pi, np.pi),
    )))
    home: np.ndarray = field(default_factory=array_default((0.0, 0.0, 0.8, 0.0, 45 * _DEG, 0.0)))

    def _check_parameters(self) -> None:
        if self.l1 <= 0.0:
            raise ValueError("spherical: l1 must be positive")
        elevation = self.joint_limits[1]
        if elevation[0] <= -np.pi / 2 or elevation[1] >= np.pi / 2:
            raise ValueError("spherical: the elevation phi2 must stay within (-90°, 90°)")
        if self.joint_limits[2, 0] <= 0.0:
            raise ValueError("spherical: the radial stroke s1 must be positive")

    def _fk(self, q: np.ndarray) -> np.ndarray:
        rotation = rot_z(q[..., 0]) @ rot_x(q[..., 1]) @ wrist_rotation(q[..., 3], q[..., 4],
                                                                         q[..., 5])
        return homogeneous(rotation, self._position(q))

    def _position(self, q: np.ndarray) -> np.ndarray:
        phi1, phi2, radial = q[..., 0], q[..., 1], q[..., 2]
        reach = radial * np.cos(phi2)
        return np.stack(
            [-reach * np.sin(phi1), reach * np.cos(phi1), self.l1 + radial * np.sin(phi2)], -1
        )

    def _kernel_parameters(self) -> np.ndarray:
        return np.array([self.l1])


def spherical_kernel(m: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """The arm's closed form for one pose (``Arm._kernel``)."""
    x, y, z = m[0, 3], m[1, 3], m[2, 3]
    phi1 = math.atan2(-x, y)
    reach, height = math.sqrt(x * x + y * y), z - p[0]
    phi2 = math.atan2(height, reach)
    # T = Rz(−φ1)·R, then W = Rx(−φ2)·T, row by row.
    c, s = math.cos(-phi1), math.sin(-phi1)
    t00, t01, t02 = c * m[0, 0] - s * m[1, 0], c * m[0, 1] - s * m[1, 1], c * m[0, 2] - s * m[1, 2]
    t10, t11, t12 = s * m[0, 0] + c * m[1, 0], s * m[0, 1] + c * m[1, 1], s * m[0, 2] + c * m[1, 2]
    t20, t21, t22 = m[2, 0], m[2, 1], m[2, 2]
    c, s = math.cos(-phi2), math.sin(-phi2)
    w11 = c * t11 - s * t21
    w20, w21, w22 = s * t10 + c * t20, s * t11 + c * t21, s * t12 + c * t22
    put_wrist_rows(out, 0, phi1, phi2, math.sqrt(reach * reach + height * height),
                   t00, t01, t02, w11, w20, w21, w22)


SphericalArm._kernel = staticmethod(spherical_kernel)
