"""Rod mechanism: the three-DOF "original part" of a six-axis manipulator (Balakin &
Shamutdinov 2013, seed 004). Position-only.

A turntable (q3, about the vertical axis) carries two supports a apart, symmetric about the
axis. Linear rods turn a block about O1 (q1) and, within it, the working table about O4
(q2); P is the working point on the table. In the vertical plane of the turntable, with r
the signed horizontal distance from the axis, the mechanism is a two-link chain
O1 → O4 → P with |O1O4| = b and |O4P| = l'p, and the paper's eq. (1) reads

    r   = −l'p·cos(q2 + ψ − q1 − γ) + b·cos(q1 + γ) − a/2
    z_p =  l'p·sin(q2 + ψ − q1 − γ) + b·sin(q1 + γ)
    x_p = r·sin q3,   y_p = r·cos q3

Joint order is base to tip, (q3, q1, q2), as for every other arm and as MuJoCo lays out
qpos for the tree turntable → block → table. Names and signs are the paper's: q1 turns the
block counter-clockwise in the (r, z) plane, q2 turns the table clockwise relative to it,
and q3 turns from +Y towards +X, i.e. about −Z (the opposite sense to the seed-000 arms'
base joints).

Frame returned by ``fk``: translation P; rotation the working table's frame,
R = Rz(−q3)·Rx(q1 − q2). The table rides on link O4P, which turns by q1 about O1 and by −q2
about O4 about axes parallel to the turntable's x axis; at q = 0 the frame is the world
frame. A MuJoCo model reproduces it with hinges about −z (q3), +x at O1 (q1), −x at O4 (q2)
and an identity-oriented site at P.

Branches (4), in this order: the sign of r (``r+``: q3 = atan2(x_p, y_p); ``r-``: q3 + π
with r = −√(x_p² + y_p²)) × the elbow at O4 (``elbow+``: sin(q2 + ψ) ≥ 0, the side the
mechanism is built on, since q = 0 gives sin ψ > 0; ``elbow-``: the mirror image about
line O1P). On the turntable axis q3 is free: it is set to 0 (r+) and π (r−).
Derivation and the paper's misprints: ``docs/seed004.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from .arm import REVOLUTE, Arm, array_default
from .rotations import homogeneous, rot_x, rot_z

_DEG = np.pi / 180.0

#: Reach tolerance: |cos β| up to 1 + this still counts as reachable (both elbow branches
#: then coincide at the workspace boundary and stay valid).
REACH_TOL = 1e-9
#: Below this horizontal distance (m) P is on the turntable axis and q3 is free.
ON_AXIS_TOL = 1e-12


def psi_from_sides(b: float, lp: float, lp_prime: float) -> float:
    """ψ, the angle at O4 of the triangle O1O4P at q2 = 0, from its three sides.

    The paper's law of cosines with its misprint corrected (it prints l'p for both lp and
    l'p): lp² = l'p² + b² − 2·b·l'p·cos ψ.
    """
    return float(np.arccos((b**2 + lp_prime**2 - lp**2) / (2.0 * b * lp_prime)))


@dataclass(frozen=True, eq=False)
class RodMechanism(Arm):
    """Turntable plus rod-driven two-link chain. The paper prints no dimensions or
    ranges: the defaults are a bench-top size chosen so that, as in the paper's fig. 1,
    P starts on the far side of the axis from O4 (its initial y = −l3·cos β < 0) and the
    rotated section overlaps the axis (the paper's fig. 6a case)."""

    name: ClassVar[str] = "rod_mechanism"
    joint_names: ClassVar[tuple[str, ...]] = ("q3", "q1", "q2")  # base to tip
    joint_types: ClassVar[tuple[str, ...]] = (REVOLUTE,) * 3
    closed_form_labels: ClassVar[tuple[str, ...]] = tuple(
        f"{side}/{elbow}" for side in ("r+", "r-") for elbow in ("elbow+", "elbow-")
    )
    target: ClassVar[str] = "position"

    #: O4P = l'p, the table link from the upper pivot O4 to the working point (not given in
    #: the paper; chosen).
    lp_prime: float = 0.25
    #: O1O4 = b, the block link from the lower pivot O1 to O4 (not given; chosen).
    b: float = 0.50
    #: The supports are a apart, so O1 sits a/2 from the turntable axis on the −r side (the
    #: paper's shift "to the left by a/2"; a not given, chosen).
    a: float = 0.30
    #: γ, the inclination of O1O4 to the horizontal at q1 = 0 (not given; chosen 60°).
    gamma: float = 60 * _DEG
    #: ψ, the angle at O4 between O4O1 and O4P at q2 = 0 (the paper derives it from
    #: lp = O1P, see ``psi_from_sides``; not given, chosen 90°, so lp = √(b² + l'p²)).
    psi: float = 90 * _DEG
    #: The paper's conclusions stress that the joints' angular ranges set the workspace
    #: size, but print none: ±30° is a plausible rod-driven tilt; the turntable turns fully.
    joint_limits: np.ndarray = field(default_factory=array_default((
        (-np.pi, np.pi),
        (-30 * _DEG, 30 * _DEG),
        (-30 * _DEG, 30 * _DEG),
    )))
    #: The paper's initial position: both rods at their reference, table level.
    home: np.ndarray = field(default_factory=array_default((0.0, 0.0, 0.0)))

    def _check_parameters(self) -> None:
        for label in ("lp_prime", "b"):
            if getattr(self, label) <= 0.0:
                raise ValueError(f"rod_mechanism: {label} must be positive")
        if self.a < 0.0:
            raise ValueError("rod_mechanism: the support spacing a must be non-negative")
        if not 0.0 < self.psi < np.pi:
            # ψ is a triangle's angle; outside (0, π) 'elbow+' would not be the built side.
            raise ValueError("rod_mechanism: psi must lie in (0, pi)")

    @property
    def lp(self) -> float:
        """O1P at q2 = 0 (the paper's lp), from the corrected law of cosines."""
        return float(
            np.sqrt(self.b**2 + self.lp_prime**2 - 2 * self.b * self.lp_prime * np.cos(self.psi))
        )

    def _fk(self, q: np.ndarray) -> np.ndarray:
        q3, q1, q2 = q[..., 0], q[..., 1], q[..., 2]
        table = q2 + self.psi - q1 - self.gamma
        block = q1 + self.gamma
        r = -self.lp_prime * np.cos(table) + self.b * np.cos(block) - self.a / 2
        z = self.lp_prime * np.sin(table) + self.b * np.sin(block)
        position = np.stack([r * np.sin(q3), r * np.cos(q3), z], -1)
        return homogeneous(rot_z(-q3) @ rot_x(q1 - q2), position)

    def _kernel_parameters(self) -> np.ndarray:
        return np.array([self.lp_prime, self.b, self.a, self.gamma, self.psi])


def rod_kernel(m: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """The mechanism's closed form for one target (``Arm._kernel``)."""
    lpp, b, a, gamma, psi = p[0], p[1], p[2], p[3], p[4]
    x, y, z = m[0, 3], m[1, 3], m[2, 3]
    horizontal = math.sqrt(x * x + y * y)
    q3_plus = 0.0 if horizontal < ON_AXIS_TOL else math.atan2(x, y)
    # In-plane target relative to O1, for r = +ρ and r = −ρ.
    for side in range(2):
        u = (horizontal if side == 0 else -horizontal) + a / 2
        q3 = q3_plus if side == 0 else q3_plus + math.pi
        # β = π − q2 − ψ is the turn from O1O4 to O4P: |O1P|² = b² + l'p² + 2·b·l'p·cos β.
        cos_beta = (u**2 + z**2 - b**2 - lpp**2) / (2.0 * b * lpp)
        if not abs(cos_beta) <= 1.0 + REACH_TOL:
            continue
        bend = math.acos(min(1.0, max(-1.0, cos_beta)))
        for elbow in range(2):
            beta = bend if elbow == 0 else -bend
            block = math.atan2(z, u) - math.atan2(lpp * math.sin(beta), b + lpp * math.cos(beta))
            row = 2 * side + elbow
            out[row, 0], out[row, 1], out[row, 2] = q3, block - gamma, math.pi - psi - beta


RodMechanism._kernel = staticmethod(rod_kernel)
