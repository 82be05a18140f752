"""How far a configuration lies from the arm's singular configurations.

The three singularities of the six-axis families, each where two of the closed-form
branches meet (``opw.py`` and ``ur.py`` list them):

- **wrist**: θ5 = 0 or π, the axes of joints 4 and 6 aligned (OPW: the spherical wrist;
  UR: joints 2, 3, 4 and 6 parallel). Margin: the angle from θ5 to the nearer of 0 and π.
- **elbow**: the forearm stretched or folded against the upper arm. OPW: the bend
  β = θ3 + ψ3, ψ3 = atan2(a2, c3), at 0 or π; UR: θ3 at 0 or π. Margin: the angle from
  the nearer of the two.
- **shoulder**: the wrist point on the surface where the two shoulder solutions meet.
  OPW: the wrist centre C at distance |b| from the j1 axis; UR: the wrist point
  p5 = p − d6·z6 at distance d4 from it. Margin (m): √(max(ρ² − offset², 0)), ρ the
  point's distance from the j1 axis: the in-plane reach the shoulder solves for.

θ are the kinematic angles (for OPW arms θ = joint·sign − offset). Pure numpy; no state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from .arm import Arm
from .opw import OpwArm
from .ur import UrArm

#: The families with these rules.
FAMILIES = (OpwArm, UrArm)


@dataclass(frozen=True)
class SingularityMargins:
    """Per configuration (…,): the wrist and elbow margins (rad, 0 … π/2) and the shoulder
    margin (m)."""

    wrist: np.ndarray
    elbow: np.ndarray
    shoulder: np.ndarray


def has_singularity_rules(arm: Arm) -> bool:
    """``arm`` (or the arm it wraps, ``base_arm``) is of a family whose singular
    configurations this module knows."""
    return isinstance(getattr(arm, "base_arm", arm), FAMILIES)


def _from_zero_or_pi(angle: np.ndarray) -> np.ndarray:
    """The angle from ``angle`` to the nearer multiple of π (0 … π/2)."""
    folded = np.mod(angle, np.pi)
    return np.minimum(folded, np.pi - folded)


def singularity_margins(arm: Arm, q: ArrayLike) -> SingularityMargins:
    """How far configurations ``q`` (…, 6) lie from ``arm``'s singular configurations
    (module docstring); ``ValueError`` for an arm of another family. NaN rows give NaN."""
    arm = getattr(arm, "base_arm", arm)  # an arm wrapped with a free tool axis: its own
    q = np.asarray(q, dtype=np.float64)
    finite = np.isfinite(q).all(axis=-1)
    if not finite.all():  # NaN rows (branches that do not exist): NaN margins
        inner = singularity_margins(arm, q[finite])
        out = [np.full(finite.shape, np.nan) for _ in range(3)]
        for array, values in zip(out, (inner.wrist, inner.elbow, inner.shoulder), strict=True):
            array[finite] = values
        return SingularityMargins(*out)
    if isinstance(arm, OpwArm):
        theta = arm.angles_from_joints(q)
        centre = arm.wrist_centre(q)
        bend = theta[..., 2] + math.atan2(arm.a2, arm.c3)
        offset = arm.b
    elif isinstance(arm, UrArm):
        theta = q
        pose = arm.fk(q)
        centre = pose[..., :3, 3] - arm.d6 * pose[..., :3, 2]
        bend = theta[..., 2]
        offset = arm.d4
    else:
        raise ValueError(f"{arm.name}: no singularity rules for this arm (OPW and UR arms "
                         "have them)")
    radius2 = centre[..., 0] ** 2 + centre[..., 1] ** 2
    reach = np.sqrt(np.maximum(radius2 - offset * offset, 0.0))
    return SingularityMargins(wrist=_from_zero_or_pi(theta[..., 4]),
                              elbow=_from_zero_or_pi(bend), shoulder=reach)
