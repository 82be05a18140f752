"""Two-arm relative-manipulation systems (Vorob'ev 2020, figs. 1–3), six joints each.

Arm 1 (links 1–3) and arm 2 (links 4–6) stand on a common base frame Oxyz. The task is the
pose of arm 2's output link 4 *relative to* arm 1's output link 3; ``fk(q)`` returns it as
the 4 × 4 pose of frame 4 expressed in frame 3 (the paper's M34 of eq. 11; its M43 of
eq. 1 is the inverse). Joints are ordered arm 1's three, then arm 2's three, each arm from
its base to its output link (the order a MuJoCo tree lays out qpos). That is the order
the paper lists its generalised coordinates, except for RRP–RPP's arm 2, which the paper
lists tip first (s4, s5, φ6). Frames follow the paper's text and its
(corrected) equations; ``docs/seed003.md`` derives the solutions and lists the misprints.

RRP–RPP (``dual_rrp_rpp``, fig. 1, eqs. 2–7), q = (φ1, φ2, s3, φ6, s5, s4):

    arm 1: A = (a0, 0, 0);  φ1 about Ox at A;  B = A + Rx(φ1)·(0, 0, l1);
           φ2 about z2 at B;  link 3 slides s3 along x2:
           R3 = Rx(φ1)·Rz(φ2),   C3 = B + R3·(s3, 0, 0)
    arm 2: φ6 about Oz at O;  link 5 slides s5 along z6;  link 4 slides s4 along x6 at the
           lateral offset b0 = OD:
           R4 = Rz(φ6),           C4 = Rz(φ6)·(s4, b0, s5)

RRR–PPP (``dual_rrr_ppp``, fig. 2, eqs. 8–10), q = (φ1, φ2, φ3, s4, s5, s6):

    arm 1: A = (0, 0, h);  φ1 about z1 (Oz);  B = A + Rz(φ1)·(l1, 0, 0) on the axis x1 of
           pair B;  φ2 about x2;  C = B + Rz(φ1)·Rx(φ2)·(0, 0, l2) on the axis z2 of pair C;
           φ3 about z3;  C3 at l3 along the link axis x3:
           R3 = Rz(φ1)·Rx(φ2)·Rz(φ3),   C3 = C + R3·(l3, 0, 0)
    arm 2: a gantry, slides s6 along Ox, s5 along Oz, s4 along Oy (eq. 10 reuses h and
           adds the offset b0 = b1 − b):
           R4 = I,                C4 = (s6, b0 + s4, h + s5)

PPR–PRR (``dual_ppr_prr``, fig. 3, eqs. 12–17), q = (s1, s2, φ3, s4, φ5, φ6):

    arm 1: s1 along Ox, s2 along Oy;  φ3 about the vertical axis of pair C at height l1;
           link 3 of length l3 along x3:
           R3 = Rz(φ3),           C3 = (s1, s2, l1) + Rz(φ3)·(l3, 0, 0)
    arm 2: link 6 slides along Oz (joint s4, the equations' s6); φ5 about x6 at E = (0, 0, s4);
           D = E + Rx(φ5)·(0, 0, l5) on the axis z5 of pair D; φ6 (the equations' φ4) about
           z5; C4 at l4 along the link axis x4:
           R4 = Rx(φ5)·Rz(φ6),    C4 = D + R4·(l4, 0, 0)

The paper's list of coordinates for fig. 3 (s4, φ5, φ6) disagrees with its own text and
eqs. 15–17 (s6, φ5, φ4: the prismatic pair is link 6's, at arm 2's base). The joint names
keep the list; the mechanism is the text's.

Every relative orientation is a Z–X–Z product, R = Rz(α)·Rx(β)·Rz(γ), so each system has
two branches, β = ±arccos R[2, 2] (the paper's arccos α33), and the positions then follow
from linear equations. Where β = 0 or π only α ± γ is defined (a continuum of solutions):
see each class for the convention that picks one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from .arm import PRISMATIC, REVOLUTE, Arm, array_default
from .rotations import homogeneous, rot_x, rot_z
from .wrist import WRIST_SINGULAR_TOL, wrist_branches

_DEG = np.pi / 180.0

#: RRP–RPP: below this |x3 · y4| the slide s3 cannot move C4 across the plane of s4 and s5,
#: so s3 is either impossible or free.
SLIDE_PARALLEL_TOL = 1e-12
#: RRP–RPP: in that case the lateral offset must already match to this distance (m).
COINCIDENT_TOL = 1e-9


def solve_zxz(rotation: np.ndarray) -> np.ndarray:
    """All (α, β, γ) with Rz(α)·Rx(β)·Rz(γ) = ``rotation`` (3, 3), as a (2, 3) array
    (``zxz_branches`` on its entries)."""
    r = np.asarray(rotation, dtype=np.float64)
    if r.shape != (3, 3):
        raise ValueError(f"rotation must have shape (3, 3), got {r.shape}")
    return np.array(zxz_branches(*(float(value) for value in r.ravel())))


_Y_TO_Z = rot_x(np.pi / 2)
#: Its entries cos(π/2) (6e-17, not 0) and sin(π/2), for ``zxz_branches``.
_PC, _PS = float(_Y_TO_Z[1, 1]), float(_Y_TO_Z[2, 1])


def zxz_branches(
    a00: float, a01: float, a02: float, a10: float, a11: float, a12: float, a20: float,
    a21: float, a22: float,
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """Both (α, β, γ) with Rz(α)·Rx(β)·Rz(γ) = A, for A given entry by entry as floats:
    ((α, β, γ), (α', β', γ')), for the IK kernels.

    The shared Y–X–Y wrist solver in another basis: with P = Rx(90°) (``_Y_TO_Z``), which
    takes y to z and keeps x, Rz(α)Rx(β)Rz(γ) = P·Ry(α)Rx(β)Ry(γ)·Pᵀ. So the rows, the flip
    and the singular convention are the wrist's: row 0 has β ≥ 0, row 1 is
    (α + π, −β, γ + π); at β = 0 or π the free angle is split evenly and both rows describe
    the same rotation. M = Pᵀ·A·P is formed entry by entry (P's 6e-17 entries kept)."""
    pc, ps = _PC, _PS
    # B = A·P, then M = Pᵀ·B.
    b01, b02 = a01 * pc + a02 * ps, a02 * pc - a01 * ps
    b11, b12 = a11 * pc + a12 * ps, a12 * pc - a11 * ps
    b21, b22 = a21 * pc + a22 * ps, a22 * pc - a21 * ps
    m00, m01, m02 = a00, b01, b02
    m11 = pc * b11 + ps * b21
    m20, m21, m22 = pc * a20 - ps * a10, pc * b21 - ps * b11, pc * b22 - ps * b12
    return wrist_branches(m00, m01, m02, m11, m20, m21, m22)


def _relative_pose(
    r3: np.ndarray, p3: np.ndarray, r4: np.ndarray, p4: np.ndarray
) -> np.ndarray:
    """Pose of frame 4 in frame 3 from both frames' world rotations and origins."""
    r3t = np.swapaxes(r3, -1, -2)
    return homogeneous(r3t @ r4, (r3t @ (p4 - p3)[..., None])[..., 0])


def _apply(rotation: np.ndarray, vector: np.ndarray) -> np.ndarray:
    return (rotation @ vector[..., None])[..., 0]


def _require_positive(arm: Arm, *names: str) -> None:
    for label in names:
        if getattr(arm, label) <= 0.0:
            raise ValueError(f"{arm.name}: {label} must be positive")


@dataclass(frozen=True, eq=False)
class DualRrpRppArm(Arm):
    """RRP–RPP (fig. 1): a tilting telescopic arm 1 and a turning two-slide arm 2.

    The paper gives no dimensions; the defaults are a plausible compact cell (arm 1's roll
    axis meets arm 2's column axis 0.3 m from arm 1's base) with the strokes of mid-size
    telescopic and column robots.

    Branches (2): ``phi1+`` / ``phi1-``, the sign of φ1 = ±arccos R34[2, 2]; the other has
    φ2 + π and φ6 + π. s3, s4, s5 then follow linearly: s3 from the lateral (y4) offset,
    which x3 must cross (R34[0, 1] ≠ 0).

    Conventions (measure-zero sets, documented in ``docs/seed003.md``):

    * φ1 = 0 or π (z3 ∥ z4): only φ6 ∓ φ2 is defined and one position equation is lost, so
      the solutions form a continuum. s3 is put at the middle of its stroke and φ6 solved
      from the lateral offset: its two values φ6 and π − φ6 are the two branches. If no φ6
      allows mid-stroke, φ6 = ±90° (the one that brings s3 closest to it) for both.
    * x3 ⟂ y4 (R34[0, 1] = 0) elsewhere: s3 is free if the lateral offset already matches
      (then s3 is at mid-stroke), impossible otherwise (NaN).
    """

    name: ClassVar[str] = "dual_rrp_rpp"
    relative: ClassVar[bool] = True
    #: Arm 2 base to tip: the turn φ6 carries the lift s5, which carries the slide s4.
    joint_names: ClassVar[tuple[str, ...]] = ("phi1", "phi2", "s3", "phi6", "s5", "s4")
    joint_types: ClassVar[tuple[str, ...]] = (
        (REVOLUTE,) * 2 + (PRISMATIC, REVOLUTE) + (PRISMATIC,) * 2
    )
    closed_form_labels: ClassVar[tuple[str, ...]] = ("phi1+", "phi1-")

    #: OA, arm 1's base on Ox (the paper's a0 in eq. 6; no value given): 0.3 m. The flipped
    #: branch is the pair turned half a turn about Oz with arm 1's base moved by 2·a0, so a
    #: close placement keeps both branches within the strokes for a fair share of poses.
    a0: float = 0.3
    #: AB along z1 (the paper's l1 in eq. 6; no value given): 0.5 m shoulder link.
    l1: float = 0.5
    #: OD, lateral offset of arm 2's slide from its turning axis (the paper's b0 in eq. 3,
    #: b1 = b0 + b; no value given): 0.2 m.
    b0: float = 0.2
    #: Roll φ1 and turn φ6 full circle; φ2 ±170° as on common column/waist joints; telescope
    #: s3 0.2–1.2 m, arm 2's radial slide s4 0.2–1.2 m and lift s5 0–1 m (mid-size
    #: cylindrical-robot strokes). The paper gives no limits.
    joint_limits: np.ndarray = field(default_factory=array_default((
        (-np.pi, np.pi),
        (-170 * _DEG, 170 * _DEG),
        (0.2, 1.2),
        (-np.pi, np.pi),
        (0.0, 1.0),
        (0.2, 1.2),
    )))
    #: Arm 1 tilted 20° and turned back towards arm 2's column: clear of every singularity.
    home: np.ndarray = field(
        default_factory=array_default((20 * _DEG, 160 * _DEG, 0.6, 10 * _DEG, 0.5, 0.5))
    )

    def _check_parameters(self) -> None:
        # a0 > 0 is what turns φ6 into a position constraint when φ1 = 0 or π (see above).
        _require_positive(self, "a0", "l1")

    def _arm1(
        self, phi1: np.ndarray, phi2: np.ndarray, s3: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        r3 = rot_x(phi1) @ rot_z(phi2)
        shoulder = np.stack(
            [np.full_like(phi1, self.a0), -self.l1 * np.sin(phi1), self.l1 * np.cos(phi1)], -1
        )
        return r3, shoulder + s3[..., None] * r3[..., :, 0]

    def _fk(self, q: np.ndarray) -> np.ndarray:
        r3, p3 = self._arm1(q[..., 0], q[..., 1], q[..., 2])
        phi6 = q[..., 3]
        r4 = rot_z(phi6)
        p4 = _apply(r4, np.stack([q[..., 5], np.full_like(phi6, self.b0), q[..., 4]], -1))
        return _relative_pose(r3, p3, r4, p4)

    def _kernel_parameters(self) -> np.ndarray:
        s3_mid = 0.5 * (self.joint_limits[2, 0] + self.joint_limits[2, 1])
        return np.array([self.a0, self.l1, self.b0, s3_mid])

    def _singular_angles(
        self,
        rotation: np.ndarray,
        t: np.ndarray,
        s3_mid: float,
        phi1: np.ndarray,
        phi2: np.ndarray,
        phi6: np.ndarray,
        singular: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """φ1 = 0 or π: R34 = Rx(φ1)·Rz(θ) with θ = φ6 − ε·φ2 (ε = cos φ1).

        In frame 4 the lateral equation reads −a0·sin φ6 + s3·R34[0, 1] + (R34ᵀt)_y = b0.
        """
        eps = np.where(rotation[..., 2, 2] >= 0.0, 1.0, -1.0)
        theta = np.arctan2(eps * rotation[..., 1, 0], rotation[..., 0, 0])
        lateral = np.einsum("...ji,...j->...i", rotation, t)[..., 1]
        sine = (lateral - self.b0 + s3_mid * rotation[..., 0, 1]) / self.a0
        base = np.arcsin(np.clip(sine, -1.0, 1.0))
        sing_phi6 = np.stack([base, np.pi - base], -1)
        sing_phi2 = eps[..., None] * (sing_phi6 - theta[..., None])
        sing_phi1 = np.broadcast_to(np.where(eps > 0.0, 0.0, np.pi)[..., None], sing_phi6.shape)
        mask = singular[..., None]
        return (
            np.where(mask, sing_phi1, phi1),
            np.where(mask, sing_phi2, phi2),
            np.where(mask, sing_phi6, phi6),
        )


@dataclass(frozen=True, eq=False)
class DualRrrPppArm(Arm):
    """RRR–PPP (fig. 2): a three-revolute Z–X–Z arm 1 and a Cartesian gantry arm 2.

    The paper gives no dimensions; the defaults are a compact revolute arm (0.8 m column)
    beside a gantry whose strokes cover arm 1's whole reach.

    Branches (2): ``phi2+`` / ``phi2-``, the sign of φ2 = ±arccos R34[2, 2]; the other has
    φ1 + π and φ3 + π. The gantry strokes then follow directly (R4 = I).

    Convention: at φ2 = 0 or π only φ1 ± φ3 is defined and the gantry absorbs any choice (a
    continuum); the free angle is split evenly, φ1 = ±φ3, and both branches coincide.
    """

    name: ClassVar[str] = "dual_rrr_ppp"
    relative: ClassVar[bool] = True
    joint_names: ClassVar[tuple[str, ...]] = ("phi1", "phi2", "phi3", "s4", "s5", "s6")
    joint_types: ClassVar[tuple[str, ...]] = (REVOLUTE,) * 3 + (PRISMATIC,) * 3
    closed_form_labels: ClassVar[tuple[str, ...]] = ("phi2+", "phi2-")

    #: AO, height of arm 1's first pair (the paper's h in eq. 8; no value given): 0.8 m.
    h: float = 0.8
    #: AB along x1 (the paper's l1; no value given): 0.25 m.
    l1: float = 0.25
    #: BC along z2 (the paper's l2; no value given): 0.35 m.
    l2: float = 0.35
    #: CC3 along x3 (the paper's l3; no value given): 0.3 m.
    l3: float = 0.3
    #: y of the gantry's zero stroke (the paper's b0 in b1 = b0 + b, eq. 10; no value
    #: given): 1.2 m, i.e. the gantry's home stands beside arm 1.
    b0: float = 1.2
    #: φ1 and φ3 full circle, φ2 ±170°; gantry strokes reach 0.8 m past arm 1's axis in
    #: y, ±1 m in x and 0–1.2 m in height (the paper gives no limits).
    joint_limits: np.ndarray = field(default_factory=array_default((
        (-np.pi, np.pi),
        (-170 * _DEG, 170 * _DEG),
        (-np.pi, np.pi),
        (-2.0, 0.0),
        (-0.8, 0.4),
        (-1.0, 1.0),
    )))
    #: Arm 1 turned 30°, tilted 45°: clear of the φ2 = 0 singularity.
    home: np.ndarray = field(
        default_factory=array_default((30 * _DEG, 45 * _DEG, -30 * _DEG, -1.0, -0.3, 0.3))
    )

    def _check_parameters(self) -> None:
        _require_positive(self, "l1", "l2", "l3")

    def _arm1(
        self, phi1: np.ndarray, phi2: np.ndarray, phi3: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        r2 = rot_z(phi1) @ rot_x(phi2)
        r3 = r2 @ rot_z(phi3)
        base = np.stack(
            [self.l1 * np.cos(phi1), self.l1 * np.sin(phi1), np.full_like(phi1, self.h)], -1
        )
        return r3, base + self.l2 * r2[..., :, 2] + self.l3 * r3[..., :, 0]

    def _kernel_parameters(self) -> np.ndarray:
        return np.array([self.h, self.l1, self.l2, self.l3, self.b0])

    def _fk(self, q: np.ndarray) -> np.ndarray:
        r3, p3 = self._arm1(q[..., 0], q[..., 1], q[..., 2])
        p4 = np.stack([q[..., 5], self.b0 + q[..., 3], self.h + q[..., 4]], -1)
        return _relative_pose(r3, p3, np.broadcast_to(np.eye(3), r3.shape), p4)

@dataclass(frozen=True, eq=False)
class DualPprPrrArm(Arm):
    """PPR–PRR (fig. 3): an XY carriage with a turning link and a lift with a two-axis head.

    The paper gives no dimensions; the defaults are an overhead XY carriage 1.5 m high
    above a lift column with a tilting, turning head.

    Branches (2): ``phi5+`` / ``phi5-``, the sign of φ5 = ±arccos R34[2, 2]; the other has
    φ3 + π and φ6 + π. s1, s2 and the lift s4 then follow directly.

    Convention: at φ5 = 0 or π only φ6 ∓ φ3 is defined and the carriage absorbs any choice
    (a continuum); the free angle is split evenly, φ6 = ∓φ3, and both branches coincide.
    """

    name: ClassVar[str] = "dual_ppr_prr"
    relative: ClassVar[bool] = True
    joint_names: ClassVar[tuple[str, ...]] = ("s1", "s2", "phi3", "s4", "phi5", "phi6")
    joint_types: ClassVar[tuple[str, ...]] = (
        (PRISMATIC,) * 2 + (REVOLUTE, PRISMATIC) + (REVOLUTE,) * 2
    )
    closed_form_labels: ClassVar[tuple[str, ...]] = ("phi5+", "phi5-")

    #: Height of link 3's frame, the length of link 1 (the paper's l1 in eq. 13; no value
    #: given): 1.5 m, an overhead carriage.
    l1: float = 1.5
    #: Link 3 (the paper's l3 in eq. 13; no value given): 0.4 m.
    l3: float = 0.4
    #: Link 4 along x4 (the paper's l4 in eq. 16; no value given): 0.3 m.
    l4: float = 0.3
    #: ED along z5 (the paper's l5 in eq. 16; no value given): 0.5 m.
    l5: float = 0.5
    #: Carriage strokes ±1 m in x and y, lift 0–1 m, the head's tilt φ5 ±135° (a typical
    #: industrial wrist bend), the turns full circle (the paper gives no limits).
    joint_limits: np.ndarray = field(default_factory=array_default((
        (-1.0, 1.0),
        (-1.0, 1.0),
        (-np.pi, np.pi),
        (0.0, 1.0),
        (-135 * _DEG, 135 * _DEG),
        (-np.pi, np.pi),
    )))
    #: Head tilted 45°: clear of the φ5 = 0 singularity.
    home: np.ndarray = field(
        default_factory=array_default((0.2, 0.0, 30 * _DEG, 0.5, 45 * _DEG, 20 * _DEG))
    )

    def _check_parameters(self) -> None:
        _require_positive(self, "l1", "l3", "l4", "l5")

    def _kernel_parameters(self) -> np.ndarray:
        return np.array([self.l1, self.l3, self.l4, self.l5])

    def _arm2_offset(
        self, phi5: np.ndarray, phi6: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """C4 − E and R4 of arm 2 (E = (0, 0, s4))."""
        r4 = rot_x(phi5) @ rot_z(phi6)
        return r4, self.l5 * r4[..., :, 2] + self.l4 * r4[..., :, 0]

    def _fk(self, q: np.ndarray) -> np.ndarray:
        phi3 = q[..., 2]
        r3 = rot_z(phi3)
        p3 = np.stack(
            [
                q[..., 0] + self.l3 * np.cos(phi3),
                q[..., 1] + self.l3 * np.sin(phi3),
                np.full_like(phi3, self.l1),
            ],
            -1,
        )
        r4, offset = self._arm2_offset(q[..., 4], q[..., 5])
        p4 = offset + np.stack([np.zeros_like(phi3), np.zeros_like(phi3), q[..., 3]], -1)
        return _relative_pose(r3, p3, r4, p4)

# ------------------------------------------------------------------ single-pose kernels
def rrp_rpp_kernel(m: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """``DualRrpRppArm``'s closed form for one pose (``Arm._kernel``)."""
    a0, l1, b0, s3_mid = p[0], p[1], p[2], p[3]
    t0, t1, t2 = m[0, 3], m[1, 3], m[2, 3]
    # R34ᵀ = Rz(−φ6)·Rx(φ1)·Rz(φ2)
    rows = zxz_branches(m[0, 0], m[1, 0], m[2, 0], m[0, 1], m[1, 1], m[2, 1],
                      m[0, 2], m[1, 2], m[2, 2])
    singular = math.sqrt(m[0, 2] * m[0, 2] + m[1, 2] * m[1, 2]) < WRIST_SINGULAR_TOL
    if singular:
        eps = 1.0 if m[2, 2] >= 0.0 else -1.0
        theta = math.atan2(eps * m[1, 0], m[0, 0])
        lateral = m[0, 1] * t0 + m[1, 1] * t1 + m[2, 1] * t2
        sine = (lateral - b0 + s3_mid * m[0, 1]) / a0
        base = math.asin(min(1.0, max(-1.0, sine)))
    for branch in range(2):
        alpha, beta, gamma = rows[branch]
        phi1, phi2, phi6 = beta, gamma, -alpha
        if singular:
            phi6 = base if branch == 0 else math.pi - base
            phi2 = eps * (phi6 - theta)
            phi1 = 0.0 if eps > 0.0 else math.pi
        c1, s1, c2, s2 = math.cos(phi1), math.sin(phi1), math.cos(phi2), math.sin(phi2)
        c6, s6 = math.cos(phi6), math.sin(phi6)
        # R3 = Rx(φ1)·Rz(φ2); C3 without the slide; then both in arm 2's joint frame.
        r00, r01, r02 = c2, -s2, 0.0
        r10, r11, r12 = c1 * s2, c1 * c2, -s1
        r20, r21, r22 = s1 * s2, s1 * c2, c1
        v0 = a0 + (r00 * t0 + r01 * t1 + r02 * t2)
        v1 = -l1 * s1 + (r10 * t0 + r11 * t1 + r12 * t2)
        v2 = l1 * c1 + (r20 * t0 + r21 * t1 + r22 * t2)
        w0, w1, w2 = c6 * v0 + s6 * v1, c6 * v1 - s6 * v0, v2
        d0, d1, d2 = c6 * r00 + s6 * r10, c6 * r10 - s6 * r00, r20
        gap = b0 - w1
        if abs(d1) < SLIDE_PARALLEL_TOL:
            if abs(gap) > COINCIDENT_TOL:
                continue
            s3 = s3_mid
        else:
            s3 = gap / d1
        out[branch, 0], out[branch, 1], out[branch, 2] = phi1, phi2, s3
        out[branch, 3], out[branch, 4], out[branch, 5] = phi6, w2 + s3 * d2, w0 + s3 * d0


def rrr_ppp_kernel(m: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """``DualRrrPppArm``'s closed form for one pose (``Arm._kernel``)."""
    h, l1, l2, l3, b0 = p[0], p[1], p[2], p[3], p[4]
    t0, t1, t2 = m[0, 3], m[1, 3], m[2, 3]
    # R3 = R34ᵀ because the gantry never turns.
    rows = zxz_branches(m[0, 0], m[1, 0], m[2, 0], m[0, 1], m[1, 1], m[2, 1],
                      m[0, 2], m[1, 2], m[2, 2])
    for branch in range(2):
        phi1, phi2, phi3 = rows[branch]
        c1, s1, c2, s2 = math.cos(phi1), math.sin(phi1), math.cos(phi2), math.sin(phi2)
        c3, s3 = math.cos(phi3), math.sin(phi3)
        # R2 = Rz(φ1)·Rx(φ2), R3 = R2·Rz(φ3).
        a00, a01, a02 = c1, -s1 * c2, s1 * s2
        a10, a11, a12 = s1, c1 * c2, -c1 * s2
        a20, a21, a22 = 0.0, s2, c2
        r00, r10, r20 = a00 * c3 + a01 * s3, a10 * c3 + a11 * s3, a20 * c3 + a21 * s3
        r01, r11, r21 = a01 * c3 - a00 * s3, a11 * c3 - a10 * s3, a21 * c3 - a20 * s3
        x = l1 * c1 + l2 * a02 + l3 * r00 + (r00 * t0 + r01 * t1 + a02 * t2)
        y = l1 * s1 + l2 * a12 + l3 * r10 + (r10 * t0 + r11 * t1 + a12 * t2)
        z = h + l2 * a22 + l3 * r20 + (r20 * t0 + r21 * t1 + a22 * t2)
        out[branch, 0], out[branch, 1], out[branch, 2] = phi1, phi2, phi3
        out[branch, 3], out[branch, 4], out[branch, 5] = y - b0, z - h, x


def ppr_prr_kernel(m: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """``DualPprPrrArm``'s closed form for one pose (``Arm._kernel``)."""
    l1, l3, l4, l5 = p[0], p[1], p[2], p[3]
    t0, t1, t2 = m[0, 3], m[1, 3], m[2, 3]
    # R34 = Rz(−φ3)·Rx(φ5)·Rz(φ6)
    rows = zxz_branches(m[0, 0], m[0, 1], m[0, 2], m[1, 0], m[1, 1], m[1, 2],
                      m[2, 0], m[2, 1], m[2, 2])
    for branch in range(2):
        alpha, phi5, phi6 = rows[branch]
        phi3 = -alpha
        c3, s3 = math.cos(phi3), math.sin(phi3)
        c5, s5, c6, s6 = math.cos(phi5), math.sin(phi5), math.cos(phi6), math.sin(phi6)
        # offset = l5·z4 + l4·x4 with R4 = Rx(φ5)·Rz(φ6); arm1 = Rz(φ3)·(l3 + a, b, c).
        o0 = l4 * c6
        o1 = l5 * -s5 + l4 * (c5 * s6)
        o2 = l5 * c5 + l4 * (s5 * s6)
        r0 = l3 + t0
        u0, u1, u2 = c3 * r0 - s3 * t1, s3 * r0 + c3 * t1, t2
        out[branch, 0], out[branch, 1], out[branch, 2] = o0 - u0, o1 - u1, phi3
        out[branch, 3], out[branch, 4], out[branch, 5] = l1 + u2 - o2, phi5, phi6


DualRrpRppArm._kernel = staticmethod(rrp_rpp_kernel)
DualRrrPppArm._kernel = staticmethod(rrr_ppp_kernel)
DualPprPrrArm._kernel = staticmethod(ppr_prr_kernel)
