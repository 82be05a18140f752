"""Rectangular (Cartesian) six-DOF arm (Klyuiko 1986, fig. 1, eqs. 1–2).

Three slides s1, s2, s3 along X0, Y0, Z0 carry the wrist centre O; the wrist turns
φ1 about y, φ2 about x, φ3 about y (matrices M3·M2·M1 of eq. 1):

    O = (s1, s2, s3),   R = Ry(φ1)·Rx(φ2)·Ry(φ3)

Branches (2): wrist + / − (sign of φ2, the paper's φ2 = ±arccos n22).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from .arm import PRISMATIC, REVOLUTE, Arm, array_default
from .rotations import homogeneous
from .wrist import put_wrist_rows, wrist_rotation

_DEG = np.pi / 180.0


@dataclass(frozen=True, eq=False)
class CartesianArm(Arm):
    """Gantry with a Y–X–Y wrist. The paper gives no dimensions: the strokes are those of a
    mid-size industrial gantry (2 m × 2 m floor, 1.3 m vertical), the wrist ranges those of
    a typical industrial wrist (roll joints full circle, bend ±135°)."""

    name: ClassVar[str] = "cartesian"
    joint_names: ClassVar[tuple[str, ...]] = ("s1", "s2", "s3", "phi1", "phi2", "phi3")
    joint_types: ClassVar[tuple[str, ...]] = (PRISMATIC,) * 3 + (REVOLUTE,) * 3
    closed_form_labels: ClassVar[tuple[str, ...]] = ("wrist+", "wrist-")

    joint_limits: np.ndarray = field(default_factory=array_default((
        (-1.0, 1.0),
        (-1.0, 1.0),
        (0.2, 1.5),
        (-np.pi, np.pi),
        (-135 * _DEG, 135 * _DEG),
        (-np.pi, np.pi),
    )))
    home: np.ndarray = field(default_factory=array_default((0.0, 0.0, 1.0, 0.0, 45 * _DEG, 0.0)))

    def _fk(self, q: np.ndarray) -> np.ndarray:
        return homogeneous(wrist_rotation(q[..., 3], q[..., 4], q[..., 5]), self._position(q))

    def _position(self, q: np.ndarray) -> np.ndarray:
        return q[..., :3].copy()

def cartesian_kernel(m: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """The arm's closed form for one pose (``Arm._kernel``)."""
    put_wrist_rows(out, 0, m[0, 3], m[1, 3], m[2, 3],
                   m[0, 0], m[0, 1], m[0, 2], m[1, 1], m[2, 0], m[2, 1], m[2, 2])


CartesianArm._kernel = staticmethod(cartesian_kernel)
