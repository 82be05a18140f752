"""Cylindrical six-DOF arm (Klyuiko 1986, fig. 2, eq. 4).

A column slide s1 along Z0, a turn φ1 about Z0 (measured from Y0), a radial slide s2 along
the arm's own y axis; the wrist turns φ2 about y (the arm axis), φ3 about x, φ4 about y:

    O = (−s2 sin φ1, s2 cos φ1, s1),   R = Rz(φ1)·Ry(φ2)·Rx(φ3)·Ry(φ4)

The radial stroke is positive, so φ1 = atan2(−x, y) is unique (the paper: "computed
uniquely"). Branches (2): wrist + / − (sign of φ3, the paper's φ3 = ±arccos …).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from .arm import PRISMATIC, REVOLUTE, Arm, array_default
from .rotations import homogeneous, rot_z
from .wrist import put_wrist_rows, wrist_rotation

_DEG = np.pi / 180.0


@dataclass(frozen=True, eq=False)
class CylindricalArm(Arm):
    """Column robot. The paper gives no dimensions: strokes are those of a mid-size
    cylindrical industrial robot (1 m column, 0.3–1.2 m radial reach), the turn ±170° and
    the wrist ranges of a typical industrial wrist."""

    name: ClassVar[str] = "cylindrical"
    joint_names: ClassVar[tuple[str, ...]] = ("s1", "phi1", "s2", "phi2", "phi3", "phi4")
    joint_types: ClassVar[tuple[str, ...]] = (
        PRISMATIC, REVOLUTE, PRISMATIC, REVOLUTE, REVOLUTE, REVOLUTE,
    )
    closed_form_labels: ClassVar[tuple[str, ...]] = ("wrist+", "wrist-")

    joint_limits: np.ndarray = field(default_factory=array_default((
        (0.3, 1.3),
        (-170 * _DEG, 170 * _DEG),
        (0.3, 1.2),
        (-np.pi, np.pi),
        (-135 * _DEG, 135 * _DEG),
        (-np.pi, np.pi),
    )))
    home: np.ndarray = field(default_factory=array_default((0.8, 0.0, 0.6, 0.0, 45 * _DEG, 0.0)))

    def _fk(self, q: np.ndarray) -> np.ndarray:
        rotation = rot_z(q[..., 1]) @ wrist_rotation(q[..., 3], q[..., 4], q[..., 5])
        return homogeneous(rotation, self._position(q))

    def _position(self, q: np.ndarray) -> np.ndarray:
        phi1, radial = q[..., 1], q[..., 2]
        return np.stack([-radial * np.sin(phi1), radial * np.cos(phi1), q[..., 0]], -1)

def cylindrical_kernel(m: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """The arm's closed form for one pose (``Arm._kernel``)."""
    x, y, z = m[0, 3], m[1, 3], m[2, 3]
    phi1 = math.atan2(-x, y)
    # Rz(−φ1)·R row by row.
    c, s = math.cos(-phi1), math.sin(-phi1)
    w00, w01, w02 = c * m[0, 0] - s * m[1, 0], c * m[0, 1] - s * m[1, 1], c * m[0, 2] - s * m[1, 2]
    w11 = s * m[0, 1] + c * m[1, 1]
    radial = math.sqrt(x * x + y * y)
    put_wrist_rows(out, 0, z, phi1, radial, w00, w01, w02, w11, m[2, 0], m[2, 1], m[2, 2])


CylindricalArm._kernel = staticmethod(cylindrical_kernel)
