"""Ortho-parallel-base arms with a spherical wrist (Brandstötter, Angerer, Hofbaur 2014).

Parameters exactly as the opw_kinematics library defines them (Jmeyer1292/opw_kinematics,
``opw_kinematics_impl.h``), so a ROS-Industrial ``opw_parameters_*.yaml`` carries over:
seven lengths a1, a2, b, c1, c2, c3, c4 (m) and per joint an ``offset`` (rad) and a
``sign_correction`` (±1). The joint values the controller shows are

    joint_i = (θ_i + offset_i) · sign_i,        θ_i = joint_i · sign_i − offset_i,

where θ are the paper's angles: at θ = 0 the arm stands straight up. Forward kinematics,
as opw_kinematics' ``forward()`` computes it (the flange frame):

    ψ3 = atan2(a2, c3),  k = √(a2² + c3²)
    C  = Rz(θ1)·(a1 + c2 sin θ2 + k sin(θ2 + θ3 + ψ3),  b,  c2 cos θ2 + k cos(θ2 + θ3 + ψ3))
         + (0, 0, c1)                                             (wrist centre)
    R  = Rz(θ1)·Ry(θ2 + θ3)·Rz(θ4)·Ry(θ5)·Rz(θ6)
    flange = C + c4·R·e_z

i.e. the product Rz(θ1)·T(a1, b, c1)·Ry(θ2)·T(0, 0, c2)·Ry(θ3)·T(a2, 0, c3)·Rz(θ4)·Ry(θ5)·
Rz(θ6)·T(0, 0, c4) (tests check both forms and hand-computed KR6 R700 values).

Inverse kinematics (8 branches, in this order; ``docs/kinematics_opw_ur.md`` derives it):
shoulder ``front`` / ``back`` × ``elbow-up`` / ``elbow-down`` × ``wrist+`` / ``wrist-``.

* front: in the j1 frame (base rotated by θ1) the wrist centre lies in front of the j1
  axis, x ≥ 0 (the side the shoulder offset a1 points to); back: x ≤ 0, reaching over.
* elbow-up: in the arm plane, with the reach measured away from the j1 axis, the elbow
  lies above the line from the shoulder (j2 axis) to the wrist centre. With
  β = θ3 + ψ3 the bend of the forearm against the upper arm: front & β > 0, back & β < 0.
* wrist+: sin θ5 ≥ 0 (the kinematic θ5; the joint j5 = (θ5 + offset5)·sign5).

Singular poses give finite, FK-exact rows: θ5 = 0 or π (the shared wrist solver splits the
free θ4 ± θ6 evenly; both wrist branches coincide), wrist centre on the j1 axis (b = 0:
θ1 = 0 front and π back), wrist centre on the j2 axis (c2 = k: θ2 = 0), stretched or
folded elbow (|cos β| ≤ 1 + 1e-9: both elbow branches coincide and stay valid).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike

from .arm import REVOLUTE, Arm, array_default
from .wrist import wrist_branches

#: |cos β| up to 1 + this is reachable (stretched / folded elbow: both branches coincide).
REACH_TOL = 1e-9
#: The wrist centre may lie this far (m) inside the cylinder of radius |b| about the j1
#: axis and still count as on it (rounding of an FK pose on the cylinder).
OFFSET_TOL = 1e-9
#: Below this distance (m) from the j1 axis the wrist centre is on it (b = 0 only).
ON_AXIS_TOL = 1e-12

_JOINTS = ("j1", "j2", "j3", "j4", "j5", "j6")
_LABELS = tuple(
    f"{shoulder}/elbow-{elbow}/wrist{wrist}"
    for shoulder in ("front", "back")
    for elbow in ("up", "down")
    for wrist in ("+", "-")
)
_SIDE = np.array([1.0, -1.0])  # front, back: sign of the wrist centre's x in the j1 frame
#: Sign of sin β for (shoulder, elbow): elbow up is β > 0 in front and β < 0 behind.
_ELBOW_SIGN = np.array([[1.0, -1.0], [-1.0, 1.0]])


def _limits_deg(*pairs: tuple[float, float]) -> tuple[tuple[float, float], ...]:
    """Joint limits typed in degrees (data sheets) -> radians, as immutable defaults."""
    return tuple((float(np.deg2rad(low)), float(np.deg2rad(high))) for low, high in pairs)


def _deg(*values: float) -> tuple[float, ...]:
    return tuple(float(np.deg2rad(value)) for value in values)


# Limits and home positions as typed on the data sheets (degrees), in radians
# (np.deg2rad) as the arms' defaults.
_FULL_CIRCLE = _limits_deg(*[(-180.0, 180.0)] * 6)
#: KUKA KR 6 R700 sixx data sheet: A1 ±170°, A2 −190°/+45°, A3 −120°/+156°, A4 ±185°,
#: A5 ±120°, A6 ±350°.
_KR6_R700_LIMITS = _limits_deg(
    (-170.0, 170.0), (-190.0, 45.0), (-120.0, 156.0), (-185.0, 185.0), (-120.0, 120.0),
    (-350.0, 350.0),
)
#: ABB IRB 2400 product specification: axes 1 ±180°, 2 −100°/+110°, 3 −60°/+65°, 4 ±200°,
#: 5 ±120°, 6 ±400°.
_IRB2400_LIMITS = _limits_deg(
    (-180.0, 180.0), (-100.0, 110.0), (-60.0, 65.0), (-200.0, 200.0), (-120.0, 120.0),
    (-400.0, 400.0),
)
#: ABB IRB 2600: axes 1 ±180°, 2 −155°/+95°, 3 −155°/+75°, 4 ±400°, 5 ±120°, 6 ±400°.
_IRB2600_LIMITS = _limits_deg(
    (-180.0, 180.0), (-155.0, 95.0), (-155.0, 75.0), (-400.0, 400.0), (-120.0, 120.0),
    (-400.0, 400.0),
)
#: ABB IRB 4600: axes 1 ±180°, 2 −90°/+150°, 3 −180°/+75°, 4 ±400°, 5 −125°/+120°, 6 ±400°.
_IRB4600_LIMITS = _limits_deg(
    (-180.0, 180.0), (-90.0, 150.0), (-180.0, 75.0), (-400.0, 400.0), (-125.0, 120.0),
    (-400.0, 400.0),
)
#: KUKA's HOME (A2 −90°, A3 +90°), A5 at 45° instead of 0° so it is not wrist-singular.
_KUKA_HOME = _deg(0.0, -90.0, 90.0, 0.0, 45.0, 0.0)
#: ABB's calibration position (all axes 0), axis 5 at 30° instead of 0° (not singular).
_ABB_HOME = _deg(0.0, 0.0, 0.0, 0.0, 30.0, 0.0)


def six_floats(arm: Arm, label: str, values: ArrayLike) -> tuple[float, ...]:
    """``values`` as six finite floats; ``ValueError`` naming ``label`` otherwise."""
    try:
        array = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{arm.name}: {label} must be six numbers, got {values!r}") from None
    if array.shape != (6,):
        raise ValueError(f"{arm.name}: {label} must have 6 entries, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{arm.name}: {label} must be finite, got {array.tolist()}")
    return tuple(float(value) for value in array)


def six_signs(arm: Arm, label: str, values: ArrayLike) -> tuple[int, ...]:
    """``values`` as six signs ±1; ``ValueError`` naming ``label`` otherwise."""
    signs = six_floats(arm, label, values)
    if any(sign not in (1.0, -1.0) for sign in signs):
        raise ValueError(f"{arm.name}: every entry of {label} must be +1 or -1, got {signs}")
    return tuple(int(sign) for sign in signs)


@dataclass(frozen=True, eq=False)
class OpwArm(Arm):
    """Any OPW arm: enter the data sheet's (or ROS-Industrial's) parameters and limits.

    Defaults: the KUKA KR 6 R700 sixx geometry, offsets and signs (see ``KukaKr6R700``)
    with every joint limited to ±180°, so the default arm has the 8 closed-form branches
    and no turns, like opw_kinematics itself, which "has no concept of limits"."""

    name: ClassVar[str] = "opw"
    joint_names: ClassVar[tuple[str, ...]] = _JOINTS
    joint_types: ClassVar[tuple[str, ...]] = (REVOLUTE,) * 6
    closed_form_labels: ClassVar[tuple[str, ...]] = _LABELS

    #: Shoulder (j2 axis) offset from the j1 axis along the arm, m (opw_kinematics a1).
    a1: float = 0.025
    #: Elbow-to-wrist offset across the forearm, m (a2; negative: the forearm axis is
    #: below the elbow axis when the forearm is horizontal).
    a2: float = -0.035
    #: Lateral shoulder offset along the j2 axis, m (b).
    b: float = 0.0
    #: Shoulder height above the base frame, m (c1, ≥ 0).
    c1: float = 0.400
    #: Upper arm, j2 axis to j3 axis, m (c2, > 0).
    c2: float = 0.315
    #: Forearm, j3 axis to the wrist centre along the forearm, m (c3, > 0).
    c3: float = 0.365
    #: Wrist centre to the flange, m (c4, ≥ 0).
    c4: float = 0.080
    #: θ = joint·sign − offset (rad), opw_kinematics' ``offsets``.
    offsets: tuple[float, ...] = (0.0, -np.pi / 2, 0.0, 0.0, 0.0, 0.0)
    #: opw_kinematics' ``sign_corrections`` (±1).
    sign_corrections: tuple[int, ...] = (-1, 1, 1, -1, 1, -1)
    #: ±180° on every joint: no turn branches.
    joint_limits: np.ndarray = field(default_factory=array_default(_FULL_CIRCLE))
    #: Upper arm vertical, forearm horizontal (KUKA's HOME), wrist bent 45° (not singular).
    home: np.ndarray = field(default_factory=array_default(_KUKA_HOME))

    def __post_init__(self) -> None:
        object.__setattr__(self, "offsets", six_floats(self, "offsets", self.offsets))
        object.__setattr__(
            self, "sign_corrections", six_signs(self, "sign_corrections", self.sign_corrections)
        )
        super().__post_init__()

    def _check_parameters(self) -> None:
        for label in ("c2", "c3"):
            value = getattr(self, label)
            if not value > 0.0:
                raise ValueError(f"{self.name}: {label} must be positive, got {value}")
        for label in ("c1", "c4"):
            if not getattr(self, label) >= 0.0:
                raise ValueError(
                    f"{self.name}: {label} must be non-negative, got {getattr(self, label)}"
                )

    # ------------------------------------------------------------------------- geometry
    @property
    def _signs(self) -> np.ndarray:
        return np.array(self.sign_corrections, dtype=np.float64)

    @property
    def _offsets(self) -> np.ndarray:
        return np.array(self.offsets)

    def angles_from_joints(self, q: ArrayLike) -> np.ndarray:
        """The paper's θ (…, 6) for joint values ``q``: θ = q·sign − offset."""
        return np.asarray(q, dtype=np.float64) * self._signs - self._offsets

    def joints_from_angles(self, theta: ArrayLike) -> np.ndarray:
        """Joint values (…, 6) for the paper's θ: q = (θ + offset)·sign."""
        return (np.asarray(theta, dtype=np.float64) + self._offsets) * self._signs

    def wrist_centre(self, q: ArrayLike) -> np.ndarray:
        """(…, 3) wrist centre C for joint values ``q`` (…, 6)."""
        pose = self.fk(q)
        return pose[..., :3, 3] - self.c4 * pose[..., :3, 2]

    def _fk(self, q: np.ndarray) -> np.ndarray:
        t = self.angles_from_joints(q)
        # Every sine and cosine in one call each, the matrices written in place: the
        # values of opw_kinematics' forward(), term for term, with half the numpy calls.
        s, c = np.sin(t), np.cos(t)
        s1, s2, s3, s4, s5, s6 = (s[..., j] for j in range(6))
        c1, c2, c3, c4, c5, c6 = (c[..., j] for j in range(6))
        t2, t3 = t[..., 1], t[..., 2]
        psi3 = math.atan2(self.a2, self.c3)
        k = math.sqrt(self.a2 * self.a2 + self.c3 * self.c3)
        cx1 = self.c2 * s2 + k * np.sin(t2 + t3 + psi3) + self.a1
        cy1 = self.b
        cz1 = self.c2 * c2 + k * np.cos(t2 + t3 + psi3)
        shape = t.shape[:-1]
        r_0c, r_ce = np.empty((*shape, 3, 3)), np.empty((*shape, 3, 3))
        r_0c[..., 0, 0] = c1 * c2 * c3 - c1 * s2 * s3
        r_0c[..., 0, 1] = -s1
        r_0c[..., 0, 2] = c1 * c2 * s3 + c1 * s2 * c3
        r_0c[..., 1, 0] = s1 * c2 * c3 - s1 * s2 * s3
        r_0c[..., 1, 1] = c1
        r_0c[..., 1, 2] = s1 * c2 * s3 + s1 * s2 * c3
        r_0c[..., 2, 0] = -s2 * c3 - c2 * s3
        r_0c[..., 2, 1] = 0.0
        r_0c[..., 2, 2] = -s2 * s3 + c2 * c3
        r_ce[..., 0, 0] = c4 * c5 * c6 - s4 * s6
        r_ce[..., 0, 1] = -c4 * c5 * s6 - s4 * c6
        r_ce[..., 0, 2] = c4 * s5
        r_ce[..., 1, 0] = s4 * c5 * c6 + c4 * s6
        r_ce[..., 1, 1] = -s4 * c5 * s6 + c4 * c6
        r_ce[..., 1, 2] = s4 * s5
        r_ce[..., 2, 0] = -s5 * c6
        r_ce[..., 2, 1] = s5 * s6
        r_ce[..., 2, 2] = c5
        out = np.zeros((*shape, 4, 4))
        rotation = out[..., :3, :3]
        np.matmul(r_0c, r_ce, out=rotation)
        out[..., 0, 3] = (cx1 * c1 - cy1 * s1) + self.c4 * rotation[..., 0, 2]
        out[..., 1, 3] = (cx1 * s1 + cy1 * c1) + self.c4 * rotation[..., 1, 2]
        out[..., 2, 3] = (cz1 + self.c1) + self.c4 * rotation[..., 2, 2]
        out[..., 3, 3] = 1.0
        return out

    def _kernel_parameters(self) -> np.ndarray:
        return np.array(
            [self.a1, self.a2, self.b, self.c1, self.c2, self.c3, self.c4,
             *self.offsets, *self.sign_corrections], dtype=np.float64
        )


def opw_kernel(m: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """The OPW closed form for one pose (``Arm._kernel``): the 8 rows front/back ×
    elbow up/down × wrist +/−, before offsets and signs are applied, then
    joint = (θ + offset) · sign. ``p`` is ``_kernel_parameters()``."""
    a1, a2, b, c1, c2, c3, c4 = p[0], p[1], p[2], p[3], p[4], p[5], p[6]
    k = math.sqrt(a2 * a2 + c3 * c3)
    psi3 = math.atan2(a2, c3)
    cos_psi, sin_psi = c3 / k, a2 / k
    cx = m[0, 3] - c4 * m[0, 2]
    cy = m[1, 3] - c4 * m[1, 2]
    cz = m[2, 3] - c4 * m[2, 2]
    # θ1: Rz(θ1)·(x, b) = (cx, cy) with x = ±√(r² − b²) (front, back); no solution inside
    # the cylinder of radius |b| about the j1 axis.
    r2 = cx * cx + cy * cy
    radius = math.sqrt(r2)
    if not radius >= abs(b) - OFFSET_TOL:
        return
    along = math.sqrt(max(r2 - b * b, 0.0))
    on_axis = radius < ON_AXIS_TOL and b == 0.0
    row = 0
    for shoulder in range(2):
        side = 1.0 if shoulder == 0 else -1.0
        x = along * side
        if on_axis:
            theta1, cos1, sin1 = (0.0 if shoulder == 0 else math.pi), side, 0.0
        else:
            num_s, num_c = cy * x - cx * b, cx * x + cy * b
            theta1 = math.atan2(num_s, num_c)
            norm1 = math.sqrt(num_s * num_s + num_c * num_c)
            if norm1 == 0.0:
                norm1 = 1.0
            cos1, sin1 = num_c / norm1, num_s / norm1
        # θ2, θ3: the planar two-link chain from the shoulder (a1, c1) to (x, cz).
        dx, dz = x - a1, cz - c1
        cos_b = (dx * dx + dz * dz - c2 * c2 - k * k) / (2.0 * c2 * k)
        if not abs(cos_b) <= 1.0 + REACH_TOL:
            row += 4
            continue
        cos_b = min(1.0, max(-1.0, cos_b))
        t00 = cos1 * m[0, 0] + sin1 * m[1, 0]
        t01 = cos1 * m[0, 1] + sin1 * m[1, 1]
        t02 = cos1 * m[0, 2] + sin1 * m[1, 2]
        t10 = cos1 * m[1, 0] - sin1 * m[0, 0]
        t11 = cos1 * m[1, 1] - sin1 * m[0, 1]
        t12 = cos1 * m[1, 2] - sin1 * m[0, 2]
        t20, t21, t22 = m[2, 0], m[2, 1], m[2, 2]
        for elbow in range(2):
            sign = side if elbow == 0 else -side  # elbow up: β > 0 in front, β < 0 behind
            bend = math.sqrt(1.0 - cos_b * cos_b)
            sin_b = bend * sign
            # β = ±atan2(|sin β|, cos β): atan2 is odd in its first argument.
            theta3 = math.atan2(bend, cos_b) * sign - psi3
            along_arm, across = c2 + k * cos_b, k * sin_b
            s2 = along_arm * dx - across * dz
            c2_ = across * dx + along_arm * dz
            theta2 = math.atan2(s2, c2_)
            norm2 = math.sqrt(s2 * s2 + c2_ * c2_)
            if norm2 == 0.0:  # wrist centre on the j2 axis (c2 = k): θ2 is free, atan2 gives 0
                cos2, sin2 = 1.0, s2
            else:
                cos2, sin2 = c2_ / norm2, s2 / norm2
            cos2b, sin2b = cos2 * cos_b - sin2 * sin_b, sin2 * cos_b + cos2 * sin_b
            cos23 = cos2b * cos_psi + sin2b * sin_psi  # θ2 + θ3 = θ2 + β − ψ3
            sin23 = sin2b * cos_psi - cos2b * sin_psi
            # Wrist: R_w = Ry(θ23)ᵀ·Rz(θ1)ᵀ·R = Rz(θ4)Ry(θ5)Rz(θ6), solved as the Y–X–Y
            # wrist of M = PᵀR_wP with P the cyclic permutation x→y→z→x
            # (M_ij = R_w[π(i)][π(j)], π = (1, 2, 0)). Only the entries it reads are formed.
            w00 = cos23 * t00 - sin23 * t20
            w01 = cos23 * t01 - sin23 * t21
            w02 = cos23 * t02 - sin23 * t22
            w22 = sin23 * t02 + cos23 * t22
            plus, minus = wrist_branches(t11, t12, t10, w22, w01, w02, w00)
            for wrist in range(2):
                angles = (theta1, theta2, theta3) + (plus if wrist == 0 else minus)
                for joint in range(6):
                    out[row, joint] = (angles[joint] + p[7 + joint]) * p[13 + joint]
                row += 1


OpwArm._kernel = staticmethod(opw_kernel)


# --------------------------------------------------------------------------- named arms
@dataclass(frozen=True, eq=False)
class KukaKr6R700(OpwArm):
    """KUKA KR 6 R700 sixx (KR AGILUS). Geometry, offsets and signs: opw_kinematics'
    ``makeKukaKR6_R700_sixx()`` (also moveit_opw_kinematics_plugin's example); limits: the
    KR 6 R700 sixx data sheet."""

    name: ClassVar[str] = "kuka_kr6_r700"

    a1: float = 0.025
    a2: float = -0.035
    b: float = 0.0
    c1: float = 0.400
    c2: float = 0.315
    c3: float = 0.365
    c4: float = 0.080
    offsets: tuple[float, ...] = (0.0, -np.pi / 2, 0.0, 0.0, 0.0, 0.0)
    sign_corrections: tuple[int, ...] = (-1, 1, 1, -1, 1, -1)
    #: A1 ±170°, A2 −190°/+45°, A3 −120°/+156°, A4 ±185°, A5 ±120°, A6 ±350°.
    joint_limits: np.ndarray = field(default_factory=array_default(_KR6_R700_LIMITS))
    #: KUKA's HOME (A2 −90°, A3 +90°) with A5 at 45° instead of 0° (not wrist-singular).
    home: np.ndarray = field(default_factory=array_default(_KUKA_HOME))


@dataclass(frozen=True, eq=False)
class AbbIrb2400(OpwArm):
    """ABB IRB 2400/10. Geometry and offsets: opw_kinematics' ``makeIrb2400_10()`` (its
    README's example; signs all +1); limits: the IRB 2400 product specification."""

    name: ClassVar[str] = "abb_irb2400"

    a1: float = 0.100
    a2: float = -0.135
    b: float = 0.0
    c1: float = 0.615
    c2: float = 0.705
    c3: float = 0.755
    c4: float = 0.085
    offsets: tuple[float, ...] = (0.0, 0.0, -np.pi / 2, 0.0, 0.0, 0.0)
    sign_corrections: tuple[int, ...] = (1, 1, 1, 1, 1, 1)
    #: Axis 1 ±180°, 2 −100°/+110°, 3 −60°/+65°, 4 ±200°, 5 ±120°, 6 ±400° (degrees).
    joint_limits: np.ndarray = field(default_factory=array_default(_IRB2400_LIMITS))
    #: ABB's calibration position (all axes 0) with axis 5 at 30° (not wrist-singular).
    home: np.ndarray = field(default_factory=array_default(_ABB_HOME))


@dataclass(frozen=True, eq=False)
class AbbIrb2600(OpwArm):
    """ABB IRB 2600-12/1.65. Geometry and offsets: ROS-Industrial's
    ``abb_irb2600_support`` opw parameters (as in rs-opw-kinematics' ``irb2600_12_165``);
    limits: the IRB 2600 product specification."""

    name: ClassVar[str] = "abb_irb2600"

    a1: float = 0.150
    a2: float = -0.115
    b: float = 0.0
    c1: float = 0.445
    c2: float = 0.700
    c3: float = 0.795
    c4: float = 0.085
    offsets: tuple[float, ...] = (0.0, 0.0, -np.pi / 2, 0.0, 0.0, 0.0)
    sign_corrections: tuple[int, ...] = (1, 1, 1, 1, 1, 1)
    #: Axis 1 ±180°, 2 −155°/+95°, 3 −155°/+75°, 4 ±400°, 5 ±120°, 6 ±400° (degrees).
    joint_limits: np.ndarray = field(default_factory=array_default(_IRB2600_LIMITS))
    #: Calibration position with axis 5 at 30°.
    home: np.ndarray = field(default_factory=array_default(_ABB_HOME))


@dataclass(frozen=True, eq=False)
class AbbIrb4600(OpwArm):
    """ABB IRB 4600-60/2.05. Geometry and offsets: ROS-Industrial's
    ``abb_irb4600_support`` opw parameters (as in rs-opw-kinematics' ``irb4600_60_205``);
    limits: the IRB 4600 product specification."""

    name: ClassVar[str] = "abb_irb4600"

    a1: float = 0.175
    a2: float = -0.175
    b: float = 0.0
    c1: float = 0.495
    c2: float = 0.900
    c3: float = 0.960
    c4: float = 0.135
    offsets: tuple[float, ...] = (0.0, 0.0, -np.pi / 2, 0.0, 0.0, 0.0)
    sign_corrections: tuple[int, ...] = (1, 1, 1, 1, 1, 1)
    #: Axis 1 ±180°, 2 −90°/+150°, 3 −180°/+75°, 4 ±400°, 5 −125°/+120°, 6 ±400° (degrees).
    joint_limits: np.ndarray = field(default_factory=array_default(_IRB4600_LIMITS))
    #: Calibration position with axis 5 at 30°.
    home: np.ndarray = field(default_factory=array_default(_ABB_HOME))

