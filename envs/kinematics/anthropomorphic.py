"""Anthropomorphic six-DOF arm (Klyuiko 1986, fig. 4): the paper's worked example.

Joint chain (reproduces the paper's table, see ``docs/kinematics.md``): φ1 about +Z0 at the
base; shoulder O1 at height l1 on the Z0 axis; φ2 (shoulder) and φ3 (elbow) about the local
+x axis; upper arm O1O2 (l2) and forearm O2O3 (l3) along the local +y axis; wrist centre O3
at the forearm's end; wrist φ4 about +y (forearm roll), φ5 about +x, φ6 about +y (tool axis).
At all-zero joints the arm points along +Y0, horizontally, and the gripper frame is aligned
with the world frame:

    R = Rz(φ1)·Rx(φ2 + φ3)·Ry(φ4)·Rx(φ5)·Ry(φ6)
    O3 = (0, 0, l1) + Rz(φ1)·(0, l2 cos φ2 + l3 cos(φ2+φ3), l2 sin φ2 + l3 sin(φ2+φ3))

Branches (8): shoulder front (φ1 = atan2(−x, y)) / back (φ1 + π, reaching over the base)
× elbow up / down (elbow above / below the shoulder–wrist line) × wrist + / − (sign of φ5).
With the wrist centre on the Z0 axis φ1 is free: it is set to 0 (front) and π (back).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from .arm import REVOLUTE, Arm, array_default
from .rotations import homogeneous, rot_x, rot_z
from .wrist import put_wrist_rows, wrist_rotation

_DEG = np.pi / 180.0

#: Reach tolerance: |cos φ3| up to 1 + this still counts as reachable (both elbow branches
#: then coincide at the workspace boundary and stay valid).
REACH_TOL = 1e-9
#: Below this horizontal distance (m) the wrist centre is on the base axis.
ON_AXIS_TOL = 1e-12


@dataclass(frozen=True, eq=False)
class AnthropomorphicArm(Arm):
    """Revolute 6-DOF arm; defaults are the worked example's dimensions (mm → m)."""

    name: ClassVar[str] = "anthropomorphic"
    joint_names: ClassVar[tuple[str, ...]] = ("phi1", "phi2", "phi3", "phi4", "phi5", "phi6")
    joint_types: ClassVar[tuple[str, ...]] = (REVOLUTE,) * 6
    closed_form_labels: ClassVar[tuple[str, ...]] = tuple(
        f"{shoulder}/elbow-{elbow}/wrist{wrist}"
        for shoulder in ("front", "back")
        for elbow in ("up", "down")
        for wrist in ("+", "-")
    )

    #: Shoulder height O0O1 = l = 1300 mm (worked example).
    l1: float = 1.300
    #: Upper arm O1O2 = l2 = 1000 mm (worked example).
    l2: float = 1.000
    #: Forearm O2O3 = l3 = 1000 mm (worked example).
    l3: float = 1.000
    #: The paper gives no limits. Waist, elbow and the two roll joints use the full circle
    #: (as on large gantry-fed arms such as the KUKA KR 1000 titan's A1/A4/A6 at ±180°-class
    #: ranges); the shoulder may reach back over the base (the paper's φ1 + 180° family
    #: needs φ2 up to ~−200°+360°); the wrist bend φ5 is limited to ±135°, a typical
    #: industrial wrist pitch range that still admits the worked example's ±105.81°.
    joint_limits: np.ndarray = field(default_factory=array_default((
        (-np.pi, np.pi),
        (-np.pi, np.pi),
        (-170 * _DEG, 170 * _DEG),
        (-np.pi, np.pi),
        (-135 * _DEG, 135 * _DEG),
        (-np.pi, np.pi),
    )))
    #: Upper arm raised 30°, forearm level, wrist bent 45°: clear of the floor, no singularity.
    home: np.ndarray = field(
        default_factory=array_default((0.0, 30 * _DEG, -30 * _DEG, 0.0, 45 * _DEG, 0.0))
    )

    def _check_parameters(self) -> None:
        for label in ("l1", "l2", "l3"):
            if getattr(self, label) <= 0.0:
                raise ValueError(f"anthropomorphic: {label} must be positive")

    def _fk(self, q: np.ndarray) -> np.ndarray:
        rotation = rot_z(q[..., 0]) @ rot_x(q[..., 1] + q[..., 2]) @ wrist_rotation(
            q[..., 3], q[..., 4], q[..., 5])
        return homogeneous(rotation, self._position(q))

    def _position(self, q: np.ndarray) -> np.ndarray:
        phi1, phi2, phi3 = q[..., 0], q[..., 1], q[..., 2]
        phi23 = phi2 + phi3
        reach = self.l2 * np.cos(phi2) + self.l3 * np.cos(phi23)
        height = self.l1 + self.l2 * np.sin(phi2) + self.l3 * np.sin(phi23)
        return np.stack([-reach * np.sin(phi1), reach * np.cos(phi1), height], -1)

    def _kernel_parameters(self) -> np.ndarray:
        return np.array([self.l1, self.l2, self.l3])


_SHOULDER_SIGN = np.array([1.0, -1.0])  # front, back
_SHOULDER_TURN = np.array([0.0, np.pi])
#: Sign of sin φ3 for (shoulder, elbow): elbow up is φ3 < 0 in front and φ3 > 0 behind.
_ELBOW_SIGN = np.array([[-1.0, 1.0], [1.0, -1.0]])


def anthropomorphic_kernel(m: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """The arm's closed form for one pose (``Arm._kernel``): the 8 rows front/back ×
    elbow up/down × wrist +/−. cos/sin of φ1, φ3 and φ2 + φ3 come from the geometry
    (normalised vectors), not from cos/sin of the angles."""
    l1, l2, l3 = p[0], p[1], p[2]
    x, y, z = m[0, 3], m[1, 3], m[2, 3]
    horizontal = math.sqrt(x * x + y * y)
    if horizontal < ON_AXIS_TOL:
        phi1, cos1, sin1 = 0.0, 1.0, 0.0
    else:
        phi1, cos1, sin1 = math.atan2(-x, y), y / horizontal, -x / horizontal
    height = z - l1
    row = 0
    for shoulder in range(2):
        side = 1.0 if shoulder == 0 else -1.0
        reach = horizontal * side
        cos3 = (reach * reach + height * height - l2**2 - l3**2) / (2.0 * l2 * l3)
        if not abs(cos3) <= 1.0 + REACH_TOL:
            row += 4
            continue
        cos3 = min(1.0, max(-1.0, cos3))
        base = phi1 + (0.0 if shoulder == 0 else math.pi)
        t00 = (cos1 * m[0, 0] + sin1 * m[1, 0]) * side
        t01 = (cos1 * m[0, 1] + sin1 * m[1, 1]) * side
        t02 = (cos1 * m[0, 2] + sin1 * m[1, 2]) * side
        t10 = (cos1 * m[1, 0] - sin1 * m[0, 0]) * side
        t11 = (cos1 * m[1, 1] - sin1 * m[0, 1]) * side
        t12 = (cos1 * m[1, 2] - sin1 * m[0, 2]) * side
        for elbow in range(2):
            # Elbow up is φ3 < 0 when reaching forward and φ3 > 0 when reaching back.
            sign = -side if elbow == 0 else side
            sin3 = math.sqrt(1.0 - cos3 * cos3) * sign
            phi3 = math.atan2(sin3, cos3)
            along, across = l2 + l3 * cos3, l3 * sin3
            upper_x = reach * along + height * across
            upper_y = height * along - reach * across
            phi2 = math.atan2(upper_y, upper_x)
            norm = math.sqrt(upper_x * upper_x + upper_y * upper_y)
            if norm == 0.0:
                cos2, sin2 = 1.0, upper_y
            else:
                cos2, sin2 = upper_x / norm, upper_y / norm
            cos23, sin23 = cos2 * cos3 - sin2 * sin3, sin2 * cos3 + cos2 * sin3
            put_wrist_rows(
                out, row, base, phi2, phi3,
                t00, t01, t02,
                cos23 * t11 + sin23 * m[2, 1],
                cos23 * m[2, 0] - sin23 * t10,
                cos23 * m[2, 1] - sin23 * t11,
                cos23 * m[2, 2] - sin23 * t12,
            )
            row += 2


AnthropomorphicArm._kernel = staticmethod(anthropomorphic_kernel)
