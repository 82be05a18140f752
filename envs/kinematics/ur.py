"""Universal Robots arms (non-spherical wrist): UR's DH chain, 8 closed-form branches.

Forward kinematics is UR's standard Denavit–Hartenberg chain to the tool0 frame,

    T = A1·A2·…·A6,   A_i = Rz(θ_i)·Tz(d_i)·Tx(a_i)·Rx(α_i),
    α = (π/2, 0, 0, π/2, −π/2, 0),  a = (0, a2, a3, 0, 0, 0),  d = (d1, 0, 0, d4, d5, d6),

with UR's published values (a2, a3 < 0 by UR's convention) and the joint values the
controller shows: no offsets, no sign changes.

Inverse kinematics after Hawkins (2013), "Analytic inverse kinematics for the Universal
Robots UR-5/UR-10 arms", re-derived in ``docs/kinematics_opw_ur.md``. With u = (sin θ1,
−cos θ1, 0) the common axis direction of joints 2, 3, 4 and p5 = p − d6·z6 the wrist point
(where the joint 5 and 6 axes meet):

    p5·u = d4                                  -> θ1 (two: shoulder front / back)
    z6·u = cos θ5,  (x6·u, y6·u) = sin θ5·(cos θ6, −sin θ6)
                                               -> θ5 (two: wrist + / −), θ6
    p4 = p5 + d5·(sin θ6·x6 + cos θ6·y6)       -> planar 2R in frame 1: θ2, θ3 (elbow up / down)
    x4 = R·(cos θ5 cos θ6, −cos θ5 sin θ6, −sin θ5)  -> θ2 + θ3 + θ4

Branches (8, in this order): ``front`` / ``back`` × ``elbow-up`` / ``elbow-down`` ×
``wrist+`` / ``wrist-``.

* front: the wrist point lies on the side of the base axis the upper arm points to at
  θ2 = 0, i.e. sign(a2)·(p5·x1) ≥ 0 with x1 = (cos θ1, sin θ1, 0) (for UR's a2 < 0: p5 on
  the −x1 side); back: the other θ1.
* elbow-up: in the arm plane (reach measured from the base axis towards p5, height up),
  the elbow (frame 2 origin) lies above the line from the shoulder (frame 1 origin) to the
  end of the forearm (frame 3 origin).
* wrist+: sin θ5 ≥ 0.

Singular cases give finite, FK-exact rows: sin θ5 = 0 (joints 2, 3, 4 and 6 parallel:
θ6 is free and chosen so that the elbow reaches best, ``singular_wrist_turn``; both wrist
branches coincide), the shoulder singularity (p5 on the
cylinder p5·u = d4 with no in-plane reach, |d4| = ρ: both shoulder branches coincide),
stretched or folded elbow (both elbow branches coincide).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike

from .arm import REVOLUTE, Arm, array_default
from .opw import _LABELS, _deg, _limits_deg
from .wrist import WRIST_SINGULAR_TOL

#: |cos θ3| up to 1 + this is reachable; the wrist point may lie this far (m) inside the
#: cylinder of radius d4 about the base axis (rounding of an FK pose on its boundary).
REACH_TOL = 1e-9

# α of UR's DH table as exact cosines and sines (the chain is the same as with π/2 in
# floating point, without the 6e-17 cross terms).
_COS_ALPHA = (0.0, 1.0, 1.0, 0.0, 0.0, 1.0)
_SIN_ALPHA = (1.0, 0.0, 0.0, 1.0, -1.0, 0.0)

#: ±180° everywhere (the generic ``ur``: no turns); UR's own limits (``ur_description``
#: joint_limits.yaml, degrees): ±360° on every joint but the elbow, ±180°.
_FULL_CIRCLE = _limits_deg(*[(-180.0, 180.0)] * 6)
_UR_LIMITS = _limits_deg(
    (-360.0, 360.0), (-360.0, 360.0), (-180.0, 180.0), (-360.0, 360.0), (-360.0, 360.0),
    (-360.0, 360.0),
)
#: The upright "ready" pose of UR's examples, tool pointing down.
_READY = _deg(0.0, -90.0, 90.0, -90.0, -90.0, 0.0)

_SHOULDER = np.array([1.0, -1.0])  # front, back: the sign of sign(a2)·(p5·x1)
_WRIST = np.array([1.0, -1.0])  # wrist+, wrist−: the sign of sin θ5


def dh_transform(
    theta: ArrayLike, d: ArrayLike, a: ArrayLike, cos_alpha: ArrayLike, sin_alpha: ArrayLike
) -> np.ndarray:
    """Rz(θ)·Tz(d)·Tx(a)·Rx(α), batched over θ (…,) -> (…, 4, 4); the DH values are
    floats or arrays that broadcast against θ (several joints at once)."""
    theta = np.asarray(theta, dtype=np.float64)
    c, s = np.cos(theta), np.sin(theta)
    out = np.zeros((*theta.shape, 4, 4))
    out[..., 0, 0], out[..., 0, 1], out[..., 0, 2], out[..., 0, 3] = (
        c, -s * cos_alpha, s * sin_alpha, a * c)
    out[..., 1, 0], out[..., 1, 1], out[..., 1, 2], out[..., 1, 3] = (
        s, c * cos_alpha, -c * sin_alpha, a * s)
    out[..., 2, 1], out[..., 2, 2], out[..., 2, 3] = sin_alpha, cos_alpha, d
    out[..., 3, 3] = 1.0
    return out


@dataclass(frozen=True, eq=False)
class UrArm(Arm):
    """Any Universal Robots arm: enter its DH d1, a2, a3, d4, d5, d6 and limits.

    Defaults: the UR5e's DH values with every joint limited to ±180° (8 branches, no turns);
    ``ur5e`` and ``ur10e`` carry UR's real limits."""

    name: ClassVar[str] = "ur"
    joint_names: ClassVar[tuple[str, ...]] = (
        "base", "shoulder", "elbow", "wrist1", "wrist2", "wrist3",
    )
    joint_types: ClassVar[tuple[str, ...]] = (REVOLUTE,) * 6
    closed_form_labels: ClassVar[tuple[str, ...]] = _LABELS

    #: Base to shoulder axis, m (DH d1, > 0).
    d1: float = 0.1625
    #: Upper arm, m (DH a2; UR's tables give it negative; non-zero).
    a2: float = -0.425
    #: Forearm, m (DH a3; negative in UR's tables; non-zero).
    a3: float = -0.3922
    #: Shoulder offset along the joint 2–4 axes, m (DH d4, > 0).
    d4: float = 0.1333
    #: Wrist 1 to wrist 2, m (DH d5, > 0).
    d5: float = 0.0997
    #: Wrist 2 to the tool flange (tool0), m (DH d6, > 0).
    d6: float = 0.0996
    joint_limits: np.ndarray = field(default_factory=array_default(_FULL_CIRCLE))
    #: The upright "ready" pose of UR's examples, tool pointing down: (0, −90°, 90°, −90°,
    #: −90°, 0); clear of the wrist (sin θ5 = −1) and shoulder singularities.
    home: np.ndarray = field(default_factory=array_default(_READY))

    def _check_parameters(self) -> None:
        for label in ("d1", "d4", "d5", "d6"):
            value = getattr(self, label)
            if not value > 0.0:
                raise ValueError(f"{self.name}: {label} must be positive, got {value}")
        for label in ("a2", "a3"):
            if getattr(self, label) == 0.0:
                raise ValueError(f"{self.name}: {label} must be non-zero (UR's tables: negative)")

    @property
    def dh(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """(d, a) of the six DH rows."""
        d = (self.d1, 0.0, 0.0, self.d4, self.d5, self.d6)
        return d, (0.0, self.a2, self.a3, 0.0, 0.0, 0.0)

    def frames(self, q: ArrayLike) -> np.ndarray:
        """(…, 7, 4, 4): the base frame and frames 1–6 (tool0) of UR's DH chain."""
        q = np.asarray(q, dtype=np.float64)
        d, a = self.dh
        pose = np.broadcast_to(np.eye(4), (*q.shape[:-1], 4, 4))
        out = [pose]
        for joint in range(6):
            pose = pose @ dh_transform(q[..., joint], d[joint], a[joint],
                                       _COS_ALPHA[joint], _SIN_ALPHA[joint])
            out.append(pose)
        return np.stack(out, axis=-3)

    def _fk(self, q: np.ndarray) -> np.ndarray:
        # The six dh_transform matrices in one call (joint first, so that each is one
        # contiguous stack), then their product in joint order: dh_transform's values,
        # with a sixth of its numpy calls.
        d, a = self.dh
        theta = np.moveaxis(q, -1, 0)
        rows = (slice(None),) + (None,) * (theta.ndim - 1)
        t = dh_transform(theta, np.array(d)[rows], np.array(a)[rows],
                         np.array(_COS_ALPHA)[rows], np.array(_SIN_ALPHA)[rows])
        pose = t[0]
        for joint in range(1, 6):
            pose = pose @ t[joint]
        return pose

    def _kernel_parameters(self) -> np.ndarray:
        return np.array([self.d1, self.a2, self.a3, self.d4, self.d5, self.d6])


#: ``singular_wrist_turn`` takes and returns floats (the compiled kernel) or arrays.


def singular_wrist_turn(
    reach: float,
    height: float,
    x6_reach: float,
    x6_height: float,
    y6_reach: float,
    y6_height: float,
    a2: float,
    a3: float,
    d5: float,
) -> tuple[float, float]:
    """(cos θ6, sin θ6) at sin θ5 = 0, where θ6 is free.

    With the tool axis along the joint 2–4 axes, frame 4's origin p4 = p5 − d5·z4 can be any
    point of the circle of radius d5 about the wrist point p5 in the arm plane (z4 ⟂ u).
    The elbow reaches distances [| |a2| − |a3| |, |a2| + |a3|] from the shoulder; p4 is put
    at the distance r* closest to the middle of that range, max(|a2|, |a3|), among those the
    circle offers ([ρ − d5, ρ + d5], ρ = |p5 − shoulder|), on the side z4 = (cos φ, sin φ)
    with φ = atan2(height, reach) + arccos(…) (in frame 1: reach along x1, height up). So a
    reachable singular pose always has solutions, and θ6 follows from z4 = −(sin θ6·x6 +
    cos θ6·y6). The arguments are p5 and the in-plane components of x6, y6 in frame 1.
    """
    rho = math.sqrt(reach * reach + height * height)
    middle = max(abs(a2), abs(a3))
    target = min(max(middle, rho - d5), rho + d5)
    ratio = (rho * rho + d5 * d5 - target * target) / (2.0 * d5 * (rho if rho > 0.0 else 1.0))
    phi = math.atan2(height, reach) + math.acos(min(max(ratio, -1.0), 1.0))
    z_reach, z_height = math.cos(phi), math.sin(phi)
    sin6 = -(z_reach * x6_reach + z_height * x6_height)
    cos6 = -(z_reach * y6_reach + z_height * y6_height)
    norm = math.sqrt(sin6 * sin6 + cos6 * cos6)
    return cos6 / norm, sin6 / norm


def ur_kernel(m: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """The UR closed form (Hawkins 2013) for one pose (``Arm._kernel``): the 8 rows
    shoulder front/back × elbow up/down × wrist +/−. ``p`` is ``_kernel_parameters()``."""
    d1, a2, a3, d4, d5, d6 = p[0], p[1], p[2], p[3], p[4], p[5]
    p5x = m[0, 3] - d6 * m[0, 2]
    p5y = m[1, 3] - d6 * m[1, 2]
    p5z = m[2, 3] - d6 * m[2, 2]
    # θ1: p5 = X·x1 + d4·u with X = ±√(ρ² − d4²) the in-plane reach.
    rho2 = p5x * p5x + p5y * p5y
    if not math.sqrt(rho2) >= d4 - REACH_TOL:
        return
    reach = math.sqrt(max(rho2 - d4 * d4, 0.0))
    s_a2, s_a3 = math.copysign(1.0, a2), math.copysign(1.0, a3)
    for shoulder in range(2):
        side = 1.0 if shoulder == 0 else -1.0
        x = reach * (s_a2 * side)
        num_s, num_c = x * p5y + d4 * p5x, x * p5x - d4 * p5y
        theta1 = math.atan2(num_s, num_c)
        norm1 = math.sqrt(num_s * num_s + num_c * num_c)
        cos1, sin1 = num_c / norm1, num_s / norm1  # norm1 ≥ d4 ρ > 0 when reachable
        # θ5, θ6 from the components of u = (sin θ1, −cos θ1, 0) in frame 6.
        xu = m[0, 0] * sin1 - m[1, 0] * cos1
        yu = m[0, 1] * sin1 - m[1, 1] * cos1
        zu = m[0, 2] * sin1 - m[1, 2] * cos1
        sin5_abs = math.sqrt(xu * xu + yu * yu)
        singular = sin5_abs < WRIST_SINGULAR_TOL
        for wrist in range(2):
            w = 1.0 if wrist == 0 else -1.0
            sin5, cos5 = sin5_abs * w, zu
            theta5 = math.atan2(sin5, cos5)
            if singular:
                # Joints 2, 3, 4, 6 parallel: θ6 is free. It is chosen so that the elbow can
                # reach frame 4 best (``singular_wrist_turn``); both wrist rows coincide.
                cos6, sin6 = singular_wrist_turn(
                    cos1 * p5x + sin1 * p5y, p5z - d1,
                    cos1 * m[0, 0] + sin1 * m[1, 0], m[2, 0],
                    cos1 * m[0, 1] + sin1 * m[1, 1], m[2, 1],
                    a2, a3, d5,
                )
            else:
                cos6, sin6 = xu * w / sin5_abs, -yu * w / sin5_abs
            theta6 = math.atan2(sin6, cos6)
            # Frame 4's origin and x axis.
            p4x = p5x + d5 * (sin6 * m[0, 0] + cos6 * m[0, 1])
            p4y = p5y + d5 * (sin6 * m[1, 0] + cos6 * m[1, 1])
            p4z = p5z + d5 * (sin6 * m[2, 0] + cos6 * m[2, 1])
            x4x = cos5 * cos6 * m[0, 0] - cos5 * sin6 * m[0, 1] - sin5 * m[0, 2]
            x4y = cos5 * cos6 * m[1, 0] - cos5 * sin6 * m[1, 1] - sin5 * m[1, 2]
            x4z = cos5 * cos6 * m[2, 0] - cos5 * sin6 * m[2, 1] - sin5 * m[2, 2]
            # In frame 1 (x1 horizontal, y1 = up, z1 = u): the planar chain of a2, a3.
            px = cos1 * p4x + sin1 * p4y
            py = p4z - d1
            theta234 = math.atan2(x4z, cos1 * x4x + sin1 * x4y)
            cos3 = (px * px + py * py - a2 * a2 - a3 * a3) / (2.0 * a2 * a3)
            if not abs(cos3) <= 1.0 + REACH_TOL:
                continue
            cos3 = min(1.0, max(-1.0, cos3))
            for elbow in range(2):
                # Elbow up is sin θ3 = −sign(a3) in front and +sign(a3) behind.
                sign = (-s_a3 if elbow == 0 else s_a3) * side
                sin3 = math.sqrt(1.0 - cos3 * cos3) * sign
                theta3 = math.atan2(sin3, cos3)
                along, across = a2 + a3 * cos3, a3 * sin3
                theta2 = math.atan2(along * py - across * px, along * px + across * py)
                row = 4 * shoulder + 2 * elbow + wrist
                out[row, 0], out[row, 1], out[row, 2] = theta1, theta2, theta3
                out[row, 3], out[row, 4], out[row, 5] = theta234 - theta2 - theta3, theta5, theta6


UrArm._kernel = staticmethod(ur_kernel)


@dataclass(frozen=True, eq=False)
class Ur5e(UrArm):
    """UR5e: DH values from Universal Robots' "DH parameters for calculations of kinematics
    and dynamics" table (UR e-Series); limits as UR's ROS description
    (``ur_description/config/ur5e/joint_limits.yaml``): ±360° on every joint, the elbow
    ±180°."""

    name: ClassVar[str] = "ur5e"

    d1: float = 0.1625
    a2: float = -0.425
    a3: float = -0.3922
    d4: float = 0.1333
    d5: float = 0.0997
    d6: float = 0.0996
    #: ±360°, the elbow ±180° (degrees from UR's description, converted with np.deg2rad).
    joint_limits: np.ndarray = field(default_factory=array_default(_UR_LIMITS))
    home: np.ndarray = field(default_factory=array_default(_READY))


@dataclass(frozen=True, eq=False)
class Ur10e(UrArm):
    """UR10e: DH values from Universal Robots' DH table (UR e-Series); limits as
    ``ur_description/config/ur10e/joint_limits.yaml``: ±360°, the elbow ±180°."""

    name: ClassVar[str] = "ur10e"

    d1: float = 0.1807
    a2: float = -0.6127
    a3: float = -0.57155
    d4: float = 0.17415
    d5: float = 0.11985
    d6: float = 0.11655
    #: ±360°, the elbow ±180° (degrees from UR's description, converted with np.deg2rad).
    joint_limits: np.ndarray = field(default_factory=array_default(_UR_LIMITS))
    home: np.ndarray = field(default_factory=array_default(_READY))
