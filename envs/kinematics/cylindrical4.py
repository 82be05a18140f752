"""Four-DOF cylindrical industrial robot (Klyuiko 1986: RF-202M, PR-10I, SM40C401).

The cylindrical arm of fig. 2 without the wrist joints B3, B4: a column slide s1, a turn
φ1 about Z0, a radial slide s2 and one rotation φ2 about the arm axis y:

    O = (−s2 sin φ1, s2 cos φ1, s1),   R = Rz(φ1)·Ry(φ2)

Only poses whose tool axis y3 is horizontal and radial can be reached (the paper's
constraints z01 = z03, n13/n11 = n23/n21 = −n31/n33, tan φ1 = −x01/y01 = −n12/n22 = n21/n11).
A pose that breaks them by more than ``CONSTRAINT_TOL`` is unreachable: its single branch
is invalid. Branches (1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from .arm import PRISMATIC, REVOLUTE, Arm, array_default
from .rotations import homogeneous, rot_y, rot_z

_DEG = np.pi / 180.0

#: Largest rotation-matrix entry error accepted for a pose this arm can realise.
CONSTRAINT_TOL = 1e-9


@dataclass(frozen=True, eq=False)
class Cylindrical4Arm(Arm):
    """Strokes of the PR-10I class of cylindrical pick-and-place robots (the paper names
    the models but no dimensions): 0.3–1.0 m column, 0.3–1.0 m radial arm, ±170° turn,
    gripper rotation full circle."""

    name: ClassVar[str] = "cylindrical4"
    joint_names: ClassVar[tuple[str, ...]] = ("s1", "phi1", "s2", "phi2")
    joint_types: ClassVar[tuple[str, ...]] = (PRISMATIC, REVOLUTE, PRISMATIC, REVOLUTE)
    closed_form_labels: ClassVar[tuple[str, ...]] = ("unique",)

    joint_limits: np.ndarray = field(default_factory=array_default((
        (0.3, 1.0),
        (-170 * _DEG, 170 * _DEG),
        (0.3, 1.0),
        (-np.pi, np.pi),
    )))
    home: np.ndarray = field(default_factory=array_default((0.6, 0.0, 0.5, 0.0)))

    def _fk(self, q: np.ndarray) -> np.ndarray:
        return homogeneous(rot_z(q[..., 1]) @ rot_y(q[..., 3]), self._position(q))

    def _position(self, q: np.ndarray) -> np.ndarray:
        phi1, radial = q[..., 1], q[..., 2]
        return np.stack([-radial * np.sin(phi1), radial * np.cos(phi1), q[..., 0]], -1)

def cylindrical4_kernel(m: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """The arm's closed form for one pose (``Arm._kernel``)."""
    x, y, z = m[0, 3], m[1, 3], m[2, 3]
    phi1 = math.atan2(-x, y)
    c, s = math.cos(phi1), math.sin(phi1)
    # local = Rz(φ1)ᵀ·R must be Ry(φ2).
    l00, l01, l02 = c * m[0, 0] + s * m[1, 0], c * m[0, 1] + s * m[1, 1], c * m[0, 2] + s * m[1, 2]
    l10, l11, l12 = c * m[1, 0] - s * m[0, 0], c * m[1, 1] - s * m[0, 1], c * m[1, 2] - s * m[0, 2]
    l20, l21, l22 = m[2, 0], m[2, 1], m[2, 2]
    phi2 = math.atan2(l02, l00)
    c2, s2 = math.cos(phi2), math.sin(phi2)
    residual = max(
        abs(l00 - c2), abs(l01), abs(l02 - s2),
        abs(l10), abs(l11 - 1.0), abs(l12),
        abs(l20 + s2), abs(l21), abs(l22 - c2),
    )
    if residual <= CONSTRAINT_TOL:
        out[0, 0], out[0, 1], out[0, 2], out[0, 3] = z, phi1, math.sqrt(x * x + y * y), phi2


Cylindrical4Arm._kernel = staticmethod(cylindrical4_kernel)
